"""Time to converge, as a settling time with a stated rule.

The paper reports a "time to converge" (its Table I) without a unit or a rule. Here it is the
*settling time* of the learning curve, as in control engineering (e.g. Ogata, *Modern Control
Engineering*, the 2% or 5% settling time of a step response): the first time after which the signal
stays within a band around its final value. For a run of ``episodes`` per-episode returns:

1. Smooth the returns with a trailing moving average of ``window`` episodes (the first ``window - 1``
   episodes average what is available so far). Single episodes are too noisy to settle.
2. Final level = mean of the last ``window`` raw returns; initial level = mean of the first ``window``.
3. Band half-width = ``max(tolerance * |final - initial|, min_band)``: a share of the total
   improvement (5% by default, the classic settling band), but never narrower than ``min_band``
   reward units, so a run that barely moved is not held to a band thinner than its noise.
4. The convergence episode is the first index ``e`` such that the smoothed curve is within
   ``final ± band`` at every episode from ``e`` to the end; it is reported as a count, ``e + 1``
   episodes.
5. A run that does not solve the task by the end has nothing to converge *to*: when fewer than
   ``min_success`` of its last ``window`` episodes were solved (by default: ended before the step limit,
   return ``> -max_steps``, as on Mountain Car; other environments pass which episodes they count as
   solved) it is reported as never converged, NaN. So is a run that has not stayed in the band for the last
   ``settled_share`` of its episodes (10%) and at least ``settled_windows`` windows: the last smoothed
   value *is* the final level, so a curve still climbing would otherwise "converge" shortly before the end.

The trailing average lags the raw curve, so the settling time is late by up to one ``window`` compared
with where the raw (noise-free) curve settles: a step change at episode ``t`` is detected at about
``t + window``. Compare settling times computed with the same ``window``, never with other rules.

The band and the window are choices, so a verdict read from settling times is also read under the other
:data:`RULES` (bands of 5, 10 and 20%, windows of 50, 100 and 200 episodes, and the greedy-evaluation curve);
a verdict that changes with the rule is marked fragile (``docs/why.md``, "Verdicts").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from rlcompare.stats.curves import moving_average


def _runs(returns: np.ndarray, window: int) -> np.ndarray:
    values = np.asarray(returns, dtype=np.float64)
    if values.ndim != 2:
        raise ValueError(f"expected (runs, episodes) returns, got shape {values.shape}")
    if window < 1:
        raise ValueError(f"window must be at least 1, got {window}")
    if values.shape[1] < window:
        raise ValueError(f"{values.shape[1]} episodes is fewer than a window of {window}")
    return values


def convergence_episodes(
    returns: np.ndarray,
    window: int = 100,
    tolerance: float = 0.05,
    min_band: float = 10.0,
    max_steps: int = 1000,
    min_success: float = 0.5,
    settled_windows: int = 2,
    settled_share: float = 0.1,
    solved: np.ndarray | None = None,
) -> np.ndarray:
    """Settling time of each run, in episodes (rule in the module docstring); NaN for never converged.

    ``returns``: ``(runs, episodes)`` per-episode returns; ``solved``: the same shape, whether each episode
    solved the task (default: ``returns > -max_steps``). Returns ``(runs,)`` float: the number of episodes
    until the smoothed curve stays within the band around the final level, in ``1 .. episodes``, or NaN.
    """
    values = _runs(returns, window)
    smooth = moving_average(values, window)
    last = values[:, -window:]
    final = last.mean(axis=1)
    initial = values[:, :window].mean(axis=1)
    band = np.maximum(tolerance * np.abs(final - initial), min_band)
    outside = np.abs(smooth - final[:, None]) > band[:, None]
    episodes = values.shape[1]
    # Index of the last episode outside the band, -1 when the curve never leaves it.
    last_outside = np.where(outside.any(axis=1), episodes - 1 - np.argmax(outside[:, ::-1], axis=1), -1)
    settled = last_outside + 2.0  # first index inside for good is last_outside + 1; as a count, + 1 more
    solved_last = last > -max_steps if solved is None else np.asarray(solved, dtype=bool)[:, -window:]
    solved = solved_last.mean(axis=1) >= min_success
    shortest_stay = max(settled_windows * window, settled_share * episodes)
    never = ~solved | (settled > episodes - shortest_stay + 1)
    return np.where(never, np.nan, settled)


def episodes_to_seconds(convergence: np.ndarray, lengths: np.ndarray, seconds_per_step: float) -> np.ndarray:
    """Wall time to reach each run's convergence episode: steps up to and including it, times the step cost.

    ``convergence``: ``(runs,)`` episode counts from :func:`convergence_episodes` (NaN stays NaN);
    ``lengths``: ``(runs, episodes)`` steps of each episode; ``seconds_per_step``: measured cost of one
    environment step plus update.
    """
    counts = np.asarray(convergence, dtype=np.float64)
    steps = np.asarray(lengths, dtype=np.float64)
    if steps.ndim != 2 or counts.shape != (steps.shape[0],):
        raise ValueError(f"need (runs,) counts and (runs, episodes) lengths, got {counts.shape} and {steps.shape}")
    known = ~np.isnan(counts)
    if np.any((counts[known] < 1) | (counts[known] > steps.shape[1]) | (counts[known] % 1 != 0)):
        raise ValueError(f"convergence counts must be whole numbers of episodes in 1..{steps.shape[1]}")
    index = np.where(known, counts, 1).astype(np.int64) - 1
    cumulative = np.take_along_axis(np.cumsum(steps, axis=1), index[:, None], axis=1)[:, 0]
    return np.where(known, cumulative * seconds_per_step, np.nan)


@dataclass(frozen=True)
class Rule:
    """One reading of "time to converge": the band's share of the improvement, the smoothing window in
    episodes, and the curve: the behaviour (ε-greedy) returns of training, or the greedy-evaluation rounds."""

    tolerance: float = 0.05
    window: int = 100
    curve: Literal["behaviour", "greedy"] = "behaviour"

    @property
    def name(self) -> str:
        prefix = "greedy curve, " if self.curve == "greedy" else ""
        return f"{prefix}band {self.tolerance:.0%}, window {self.window}"


DEFAULT_RULE = Rule()
"""The rule of Table I: behaviour returns, a 5% band, a window of 100 episodes."""
RULES: tuple[Rule, ...] = (
    *(Rule(tolerance, window) for tolerance in (0.05, 0.1, 0.2) for window in (50, 100, 200)),
    Rule(curve="greedy"),
)
"""The reasonable rules a convergence verdict is checked under: bands x windows, and the greedy curve."""


def convergence_on_rounds(curve: np.ndarray, every: int, window: int = 100, **rule: Any) -> np.ndarray:
    """Settling time of a curve sampled once every ``every`` training episodes (greedy-evaluation rounds),
    in training episodes: round ``k`` (counted from 1) comes after ``k * every`` episodes.

    ``curve``: ``(runs, rounds)``, e.g. each round's mean greedy return; ``window``: in training episodes,
    smoothed over ``max(1, round(window / every))`` rounds; ``rule``: the other arguments of
    :func:`convergence_episodes` (``solved`` then has one entry per round).
    """
    if every < 1:
        raise ValueError(f"every must be at least 1 episode, got {every}")
    return convergence_episodes(curve, window=max(1, round(window / every)), **rule) * every
