"""drivenav: DRIVE-Nav zero-shot open-vocabulary object navigation.

Packages follow the paper: ``mapping`` (depth to maps, frontiers), ``directions`` (persistent directions,
Sec. IV-A a-b), ``inspection`` (representative views, Sec. IV-A c), ``semantics`` (reasoner and grounding,
Sec. IV-B/C), ``agent`` (the decision loop), ``envs`` (embedded world and adapters), ``eval`` (episodes,
metrics, runner), ``viz`` (pictures).
"""

__version__ = "0.1.0"
