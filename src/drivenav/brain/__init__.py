"""The brain's side of a real-robot deployment (paper Sec. V-E): one live episode on a robot and the wire's bench.
The world adapter itself is :class:`~drivenav.envs.robot.RobotEnv`."""
