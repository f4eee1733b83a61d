"""Habitat worlds: the paper's benchmarks (HM3D-OVON, HM3D v1 / v2, MP3D) through habitat-lab's ``Env``.

:mod:`.benchmarks`, :mod:`.spec`, :mod:`.layouts` and :mod:`.observations` are plain Python (the parent process
lists episodes and checks set-ups without habitat-lab); :mod:`.config`, :mod:`.ovon` and :mod:`.env` import
habitat-lab and run in the worker processes that step it. See docs/habitat.md.
"""
