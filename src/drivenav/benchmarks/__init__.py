"""Benchmarks and episode generation: the embedded world's episodes (:mod:`~drivenav.benchmarks.generate`), the
HM3D-OVON-style episodes of benchmark v2 (:mod:`~drivenav.benchmarks.ovon_episodes`), the frozen benchmarks v1 and
v2 (:mod:`~drivenav.benchmarks.benchmark`), the world statistics (``drivenav episodes stats``), and the benches that
run generated episodes (``bench agent``, ``bench episodes``)."""
