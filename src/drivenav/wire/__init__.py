"""The wire (docs/robot.md): message framing, the client and server sockets, and who may connect. Below every end
that speaks it: the brain's :class:`~drivenav.envs.robot.RobotEnv` and the robot's server (:mod:`drivenav.robot`),
and the served grounder's client and server (:mod:`drivenav.semantics.served`,
:mod:`drivenav.semantics.grounder_server`)."""
