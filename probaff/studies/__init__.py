"""Inference studies: each module holds a config dataclass and a resumable ``run(config)``.

Modules:
    affordance_map: chapter 3's manipulation loop, information gain against exhaustive pushing
        over generated warehouse maps (Figs. 3.5-3.7).
    push_models: chapters 5 and 4, mixtures of GP experts fitted by EM and VI.
"""

from __future__ import annotations

__all__: list[str] = []
