"""The embedded world: a 2.5-D simulator of homes and offices (procedural houses, real floor plans), rendered by
numba, with Habitat's ObjectNav measures. The default world; :class:`~drivenav.envs.embedded.env.EmbeddedEnv` is its
:class:`~drivenav.envs.base.Env`."""
