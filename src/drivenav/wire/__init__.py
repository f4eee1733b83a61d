"""The brain-robot wire (docs/robot.md): the protocol's messages, the brain's client and who may connect. Below both
ends: the brain's :class:`~drivenav.envs.robot.RobotEnv` and the robot's server (:mod:`drivenav.robot`)."""
