"""The analysis of finished runs: the paper's tables over the methods' runs (``bench ablations``:
:mod:`~drivenav.analysis.ablations`, its data and its Markdown / CSV report), the comparison of run directories
(``drivenav compare``, the Table II subset) and the statistics they share (Wilson and bootstrap intervals)."""
