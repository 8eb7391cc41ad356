"""Exploration schedules: ε for every episode, computed once before training.

The paper keeps ε at 0.5 in one configuration and, in the other, starts it at 1 and lets it "decay over
time as the agent trains" without giving the rule. ``decay`` here is linear from ``start`` to ``end`` over
the first ``fraction`` of the episodes, then flat: the rule of the widely copied tabular Mountain Car
tutorials that use the same 20-bin grid, and the one whose behaviour is easiest to read on a curve.
``docs/departures.md`` gives the defaults and the reasons.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

SCHEDULES = ("constant", "decay")


def constant_epsilon(episodes: int, epsilon: float) -> np.ndarray:
    """ε the same for every episode."""
    import numpy as np

    return np.full(episodes, epsilon, dtype=np.float64)


def linear_decay_epsilon(episodes: int, start: float, end: float, fraction: float) -> np.ndarray:
    """ε from ``start`` at the first episode down to ``end`` after ``fraction`` of the episodes, then ``end``."""
    import numpy as np

    decay_episodes = max(round(fraction * episodes), 1)
    progress = np.minimum(np.arange(episodes, dtype=np.float64) / decay_episodes, 1.0)
    return start + (end - start) * progress
