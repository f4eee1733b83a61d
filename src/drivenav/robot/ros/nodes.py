"""The live ROS 2 parts of the robot (paper Sec. V-E): ``rclpy`` nodes that read synchronised frames from the
topics and carry out discrete actions on ``cmd_vel``. ``rclpy`` and the message modules are imported when a node is
made, so that the rest of the robot side runs without a sourced ROS 2 environment."""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from types import ModuleType
from typing import Any

from drivenav.robot.parts import MotionResult, SensorFrame
from drivenav.robot.ros.convert import RosMessage, camera_info_to_intrinsics, odometry_to_pose, stamp_seconds
from drivenav.robot.ros.motion import CmdVelConfig, CmdVelController, Outcome
from drivenav.robot.ros.sync import Stream, SyncBuffer, SyncConfig, assemble_frame
from drivenav.robot.ros.topics import LidarMount, RosTopics
from drivenav.types import Action, CameraIntrinsics, Pose


def _ros_module(name: str) -> ModuleType:
    """Import a ROS 2 Python module, which only a sourced ROS 2 environment provides."""
    try:
        return importlib.import_module(name)
    except ImportError as err:
        raise RuntimeError("rclpy is not installed: source your ROS 2 setup") from err


def _ros_node(name: str) -> tuple[ModuleType, Any]:
    """``rclpy`` (initialised once per process) and a new node."""
    rclpy = _ros_module("rclpy")
    if not rclpy.ok():
        rclpy.init()
    return rclpy, rclpy.create_node(name)


class RosSensorSource:
    """Synchronised frames from live ROS 2 topics (an ``rclpy`` node, spun by :meth:`read`).

    :meth:`read` returns the newest synchronised frame whose RGB image was stamped at or after the call (so no
    image taken while the robot was still moving), which assumes the camera stamps with the node's clock (the
    RealSense driver's default system time); ``TimeoutError`` if none comes within ``timeout`` seconds.
    """

    def __init__(
        self,
        topics: RosTopics | None = None,
        *,
        mount: LidarMount | None = None,
        gimbal_yaw: float = 0.0,
        sync: SyncConfig | None = None,
        timeout: float = 2.0,
        node_name: str = "drivenav_sensors",
    ) -> None:
        self.topics = topics or RosTopics()
        self.mount = mount or LidarMount()
        self.gimbal_yaw = gimbal_yaw
        self.timeout = timeout
        self._buffer = SyncBuffer(sync)
        self._intrinsics: CameraIntrinsics | None = None
        self._rclpy, self._node = _ros_node(node_name)
        sensor_msgs, nav_msgs = _ros_module("sensor_msgs.msg"), _ros_module("nav_msgs.msg")
        qos = _ros_module("rclpy.qos").qos_profile_sensor_data
        subscriptions = [
            (sensor_msgs.Image, self.topics.rgb, Stream.RGB),
            (sensor_msgs.Image, self.topics.depth, Stream.DEPTH),
            (nav_msgs.Odometry, self.topics.odometry, Stream.ODOMETRY),
        ]
        if self.topics.scan:
            subscriptions.append((sensor_msgs.PointCloud2, self.topics.scan, Stream.SCAN))
        for msg_type, topic, stream in subscriptions:
            self._node.create_subscription(msg_type, topic, self._keeper(stream), qos)
        self._node.create_subscription(sensor_msgs.CameraInfo, self.topics.camera_info, self._on_camera_info, qos)

    def read(self) -> SensorFrame:
        """The newest synchronised frame taken after the call (see the class docstring)."""
        since = self._node.get_clock().now().nanoseconds * 1e-9
        deadline = time.monotonic() + self.timeout
        while True:
            messages = self._buffer.latest(after=since)
            if messages is not None and self._intrinsics is not None:
                return assemble_frame(messages, self._intrinsics, self.mount, self.gimbal_yaw)
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise TimeoutError(f"no synchronised frame on {self.topics} within {self.timeout} s")
            self._rclpy.spin_once(self._node, timeout_sec=min(remaining, 0.05))

    def close(self) -> None:
        """Destroy the node."""
        self._node.destroy_node()

    def _keeper(self, stream: Stream) -> Callable[[RosMessage], None]:
        """The subscription callback that keeps a stream's messages."""

        def keep(msg: RosMessage) -> None:
            self._buffer.add(stream, stamp_seconds(msg.header), msg)

        return keep

    def _on_camera_info(self, msg: RosMessage) -> None:
        self._intrinsics = camera_info_to_intrinsics(msg)


class RosMotionExecutor:
    """Discrete actions as ``geometry_msgs/Twist`` on ``cmd_vel``, closed on odometry by :class:`CmdVelController`
    (an ``rclpy`` node, spun by :meth:`execute`; commands at ``rate_hz``)."""

    def __init__(
        self,
        odometry_topic: str = "/odom",
        cmd_vel_topic: str = "cmd_vel",
        *,
        config: CmdVelConfig | None = None,
        rate_hz: float = 20.0,
        node_name: str = "drivenav_motion",
    ) -> None:
        self.config = config or CmdVelConfig()
        self.period = 1.0 / rate_hz
        self._rclpy, self._node = _ros_node(node_name)
        self._twist = _ros_module("geometry_msgs.msg").Twist
        self._publisher = self._node.create_publisher(self._twist, cmd_vel_topic, 10)
        self._node.create_subscription(_ros_module("nav_msgs.msg").Odometry, odometry_topic, self._on_odometry, 10)
        self._pose: Pose | None = None

    def execute(self, action: Action) -> MotionResult:
        """Carry out ``action`` (STOP: stop at once); ``TimeoutError`` if no odometry comes within the action's
        timeout."""
        if action == Action.STOP:
            self.stop()
            return MotionResult(collided=False)
        start = time.monotonic()
        self._spin_for(self.period)  # the newest odometry, not one queued while idle
        while self._pose is None:
            if time.monotonic() - start >= self.config.timeout:
                raise TimeoutError("no odometry received")
            self._spin_for(self.period)
        controller = CmdVelController(action, self._pose, self.config)
        start = time.monotonic()
        while True:
            command = controller.step(self._pose, time.monotonic() - start)
            if isinstance(command, Outcome):
                self.stop()
                return command.result()
            self._publish(command.linear, command.angular)
            self._spin_for(self.period)

    def stop(self) -> None:
        """Command zero velocity."""
        self._publish(0.0, 0.0)

    def close(self) -> None:
        """Stop and destroy the node."""
        self.stop()
        self._node.destroy_node()

    def _publish(self, linear: float, angular: float) -> None:
        twist = self._twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        self._publisher.publish(twist)

    def _spin_for(self, seconds: float) -> None:
        """Handle odometry callbacks for ``seconds``."""
        deadline = time.monotonic() + seconds
        while (remaining := deadline - time.monotonic()) > 0.0:
            self._rclpy.spin_once(self._node, timeout_sec=remaining)

    def _on_odometry(self, msg: RosMessage) -> None:
        self._pose = odometry_to_pose(msg)
