"""DRIVE-Nav's explorer (paper Sec. IV-A): persistent directions, representative views, inspection events and
reasoner decisions. Its modes, one module each, in the order an episode meets them:

- :mod:`~drivenav.agent.explorers.drive_nav.scan`: the 360 deg start scan, then a reasoner decision;
- :mod:`~drivenav.agent.explorers.drive_nav.follow`: drive toward the farthest frontier point of the selected
  direction;
- :mod:`~drivenav.agent.explorers.drive_nav.sweep`: an inspection event -- rotate over the forward-240 deg
  directions lacking views, then decide (Sec. IV-A c);
- :mod:`~drivenav.agent.explorers.drive_nav.enrich`: the reasoner sees the target but the grounder does not --
  face it and enrich the detector's prompt (Sec. IV-B).

Each exposes ``act(directions, loop, observation, ctx)``; :mod:`~drivenav.agent.explorers.drive_nav.explorer`
dispatches on the mode. Its settings section and registration are in
:mod:`~drivenav.agent.explorers.drive_nav.config`.
"""
