"""The decision loop's modes, one module each (paper Sec. IV overview), in the order an episode meets them:

- :mod:`~drivenav.agent.modes.scan`: the 360 deg start scan, then a reasoner decision;
- :mod:`~drivenav.agent.modes.follow`: drive toward the farthest frontier point of the selected direction;
- :mod:`~drivenav.agent.modes.sweep`: an inspection event -- rotate over the forward-240 deg directions lacking
  views, then decide (Sec. IV-A c);
- :mod:`~drivenav.agent.modes.enrich`: the reasoner sees the target but the grounder does not -- face it and
  enrich the detector's prompt (Sec. IV-B);
- :mod:`~drivenav.agent.modes.approach`: drive to the target candidate, verifying it (Sec. IV-C), and STOP.

Each exposes ``act(loop, observation, ctx)``; :class:`~drivenav.agent.loop.Loop` dispatches on the mode.
"""
