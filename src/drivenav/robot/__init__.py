"""The real-robot deployment of the paper (Sec. V-E): the brain (agent, models) on a workstation, the robot's
sensors and motion behind a ZMQ protocol (:mod:`drivenav.wire.protocol`), a ROS 2 side and LiDAR occupancy.

See docs/robot.md. Nothing here is imported by the algorithmic core; the brain reaches a robot through
:class:`drivenav.envs.robot.RobotEnv`.
"""
