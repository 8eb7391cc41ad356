"""The returns of each seed, the same for every engine and study: what "behaviour return", "greedy return" and
"area under the greedy curve" mean, in one place.

- behaviour return: the mean return of the ε-greedy (or softmax) behaviour over the training episodes given,
  what an agent collects while it learns (the paper's "mean cumulative reward");
- greedy return: the mean return of the target policy's episodes in the last evaluation round, what it learned;
- greedy AUC: the mean over every evaluation round of its mean return, the area under the greedy curve divided
  by its length (how early it learned).
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def returns_per_seed(seeds: tuple[int, ...], training: np.ndarray | list[np.ndarray], evaluations: np.ndarray
                     ) -> pd.DataFrame:
    """One row per seed: ``seed``, ``behaviour_return``, ``greedy_return``, ``greedy_auc``.

    ``training``: each seed's training returns, ``(seeds, episodes)`` or one array per seed where seeds end
    different numbers of episodes (the deep engine's vectorised environments); ``evaluations``: the greedy
    returns, ``(seeds, rounds)`` or ``(seeds, rounds, episodes per round)``. No evaluation round: NaN greedy
    columns."""
    evaluations = np.asarray(evaluations, dtype=np.float64)
    per_round = evaluations.mean(axis=2) if evaluations.ndim == 3 else evaluations
    behaviour = (training.mean(axis=1) if isinstance(training, np.ndarray) and training.ndim == 2
                 else np.array([np.mean(returns) for returns in training], dtype=np.float64))
    evaluated = per_round.shape[1] > 0
    return pd.DataFrame({
        "seed": np.asarray(seeds),
        "behaviour_return": behaviour,
        "greedy_return": per_round[:, -1] if evaluated else np.nan,
        "greedy_auc": per_round.mean(axis=1) if evaluated else np.nan,
    })
