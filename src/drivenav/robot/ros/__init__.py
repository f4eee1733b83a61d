"""The ROS 2 side of the real robot (paper Sec. V-E): message conversions, time synchronisation, a bag source and
the ``cmd_vel`` motion logic.

The paper's robot, a Unitree G1, carries an RGB-D camera and a LiDAR whose returns are fused with the IMU by
FAST-LIO2. This package turns its ROS 2 messages into frames (:class:`drivenav.robot.parts.SensorFrame`) and one
discrete action into velocity commands closed on odometry. Nothing here imports ``rclpy`` at module level: the
conversions (:mod:`.convert`) work on duck-typed messages (as deserialised by ``rosbags`` or received by
``rclpy``), :class:`BagSource` (:mod:`.bag`) reads a ROS 2 bag with ``rosbags`` (no ROS install needed, imported
when a bag is opened), and only :class:`RosSensorSource` and :class:`RosMotionExecutor` (:mod:`.nodes`) need a
sourced ROS 2 environment. The topics and the LiDAR's mounting are in :mod:`.topics`, the pairing of messages by
their stamps in :mod:`.sync`, the pure ``cmd_vel`` closed loop in :mod:`.motion`.

The package re-exports the parts the robot server builds from the command line (``drivenav robot serve``).
"""

from drivenav.robot.ros.bag import BagSource
from drivenav.robot.ros.nodes import RosMotionExecutor, RosSensorSource
from drivenav.robot.ros.topics import LidarMount, RosTopics

__all__ = ["BagSource", "LidarMount", "RosMotionExecutor", "RosSensorSource", "RosTopics"]
