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


def returns_from_tables(episodes: pd.DataFrame, evaluations: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """:func:`returns_per_seed`'s three numbers, by the same definitions, from the long tables a run directory
    holds (``return`` per training episode; ``round`` and ``return`` per evaluation episode), one row per group of
    ``by`` (a sweep's configuration and seed): thousands of trials at once, without loading each run."""
    behaviour = episodes.groupby(by)["return"].mean().rename("behaviour_return")
    if evaluations.empty:
        return behaviour.reset_index().assign(greedy_return=np.nan, greedy_auc=np.nan)
    per_round = evaluations.groupby([*by, "round"])["return"].mean()  # rounds in ascending order in each group
    greedy = per_round.groupby(level=by).last().rename("greedy_return")
    auc = per_round.groupby(level=by).mean().rename("greedy_auc")
    return pd.concat([behaviour, greedy, auc], axis=1).reset_index()
