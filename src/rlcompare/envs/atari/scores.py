"""Published facts about the 57 Atari 2600 games of the standard suite, for human-normalised scores.

A game's human-normalised score is ``(score - random) / (human - random)``: 0 plays as a uniformly random agent
does, 1 as the professional human games tester of Mnih et al. (2015, "Human-level control through deep
reinforcement learning", Nature 518). Both baselines were measured with up to 30 no-op actions at the start and
episodes cut at 108,000 frames.

Sources:

- Random and human scores: the table of Mnih et al. (2015), extended to the 57 games by later work (Badia et al.
  2020, "Agent57: Outperforming the Atari Human Benchmark", ICML), as DeepMind's DQN Zoo lists it:
  ``dqn_zoo/atari_data.py`` in github.com/deepmind/dqn_zoo, unchanged from commit
  402ba5c8a973149036eb7f94cf2038ae0d7ef2c7 to commit f87bb1f13d0e87c0724bc504e43d43019753cc43. That table
  differs from Agent57's in one game: Video Pinball's random score is 16256.9 there (Mnih et al.'s random agent),
  0.0 in Agent57's table, Atari-5's and rliable's. Space Invaders' random score is 148.0 there, 148.3 in Atari-5's
  ``Atari-Human.csv`` (148.03 in Agent57's table). The other 55 agree to the first decimal.
- Atari-100k: the 26 games of Kaiser et al. (2020, "Model-Based Reinforcement Learning for Atari", ICLR).
- Atari-5 and its estimate of the 57-game median: Aitchison, Sweetser and Hutter (2023, "Atari-5: Distilling the
  Arcade Learning Environment down to Five Games", ICML, PMLR 202:421-438; arXiv 2210.02019). See
  :func:`atari5_median` for the model and where its numbers come from.

Titles are spelt as Gymnasium's ALE environments spell them (``ALE/<title>-v5``); ``rom`` is ale-py's ROM id.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, overload

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Game:
    """One Atari game and its two published baseline scores."""

    title: str
    """Gymnasium's spelling, as in ``ALE/<title>-v5``."""
    rom: str
    """ale-py's ROM id."""
    random: float
    """A uniformly random agent's score."""
    human: float
    """The professional human games tester's score."""


GAMES: dict[str, Game] = {row["title"]: Game(row["title"], row["rom"], float(row["random"]), float(row["human"]))
                          for row in csv.DictReader(Path(__file__).with_name("scores.csv").read_text().splitlines())}
"""The 57 games of the standard suite, by title, in alphabetical order: ``scores.csv`` beside this module, the
sources' table as it stands (Video Pinball's random score is DQN Zoo's, 16256.9; 0.0 in Agent57's table, see
above)."""

ATARI_5 = ("BattleZone", "DoubleDunk", "NameThisGame", "Phoenix", "Qbert")
"""Aitchison et al. (2023)'s five games."""

ATARI_100K = ("Alien", "Amidar", "Assault", "Asterix", "BankHeist", "BattleZone", "Boxing", "Breakout",
              "ChopperCommand", "CrazyClimber", "DemonAttack", "Freeway", "Frostbite", "Gopher", "Hero", "Jamesbond",
              "Kangaroo", "Krull", "KungFuMaster", "MsPacman", "Pong", "PrivateEye", "Qbert", "RoadRunner",
              "Seaquest", "UpNDown")
"""Kaiser et al. (2020)'s 26 games, trained on 100k agent steps (400k frames)."""

SETS: dict[str, tuple[str, ...]] = {
    "atari5": ATARI_5,
    "atari100k": ATARI_100K,
    "breakout-pong": ("Breakout", "Pong"),
    "atari57": tuple(GAMES),
    "breakout": ("Breakout",),
}
"""Named sets of games, each a tuple of titles."""


def chosen_games(spec: str) -> tuple[str, ...]:
    """A set's games (:data:`SETS`), or titles given one by one, comma-separated; anything else a
    :class:`~rlcompare.validation.ConfigError` naming ``games``."""
    from rlcompare.validation import ConfigError

    if spec.strip() in SETS:
        return SETS[spec.strip()]
    chosen = tuple(name.strip() for name in spec.split(",") if name.strip())
    if not chosen or any(name not in GAMES for name in chosen):
        raise ConfigError("games", spec, f"one of the sets {', '.join(SETS)}, or a comma-separated list of "
                                         f"{', '.join(GAMES)}")
    return chosen


@overload
def human_normalised(title: str, score: float) -> float: ...
@overload
def human_normalised(title: str, score: npt.NDArray[Any]) -> FloatArray: ...
def human_normalised(title: str, score: float | npt.NDArray[Any]) -> float | FloatArray:
    """``(score - random) / (human - random)`` for the game titled ``title``: 0 at random play, 1 at human."""
    game = GAMES[title]
    normalised = (np.asarray(score, dtype=np.float64) - game.random) / (game.human - game.random)
    return float(normalised) if normalised.ndim == 0 else normalised


ATARI5_WEIGHTS: dict[str, float] = {
    "BattleZone": 0.3819751237831753,
    "DoubleDunk": 0.0679099488887574,
    "NameThisGame": 0.310804148620847,
    "Phoenix": 0.12412619402774641,
    "Qbert": 0.08048518286466755,
}
"""The Atari-5 model's weight per game (it has no intercept): see :func:`atari5_median`."""


@overload
def atari5_median(scores_by_title: Mapping[str, float]) -> float: ...
@overload
def atari5_median(scores_by_title: Mapping[str, npt.NDArray[Any]]) -> FloatArray: ...
@overload
def atari5_median(scores_by_title: Mapping[str, float | npt.NDArray[Any]]) -> float | FloatArray: ...
def atari5_median(scores_by_title: Mapping[str, float | npt.NDArray[Any]]) -> float | FloatArray:
    """Aitchison et al. (2023)'s Atari-5 estimate of the median human-normalised score over the 57 games.

    ``scores_by_title`` holds human-normalised scores on this module's scale (1 = human, as
    :func:`human_normalised` gives them) for at least the five :data:`ATARI_5` games; other games are ignored.
    Arrays broadcast together. The estimate comes back on the same scale.

    Their model works in percent: with ``p_i = 100 h_i`` a game's human-normalised score in percent,
    ``log10(1 + median%) = sum_i w_i log10(1 + max(p_i, 0))``, a least-squares fit without intercept
    (:data:`ATARI5_WEIGHTS`) over published results of 44 algorithms. Scores below random count as random;
    the +1 acts on percent, so passing fractions straight to the formula would be wrong.

    Sources: the transform, the percent scale and the absent intercept are those of ``atari5.py`` (``transform``,
    ``USE_INTERCEPT = False``, ``Normalized``) in github.com/maitchison/Atari-5 at commit
    118cad542c94bc6e57181bb259a17d020e0a330f. That repository does not print the weights; they are the
    author's own, ``AtariScoreNormalizer.SUBSETS["Atari_5"]`` in ``tools/plot_util.py`` of
    github.com/maitchison/PPO at commit d3e3228252b87bb9b0e5ea6f29329db01287439e (``plot_util.py`` since
    d59190ea5b7f6fb5c8edc838fdc2544242c4769b), with 10.4% as its error (10-fold cross-validated mean absolute
    error of the log10 estimate, times ln 10: about a relative error).
    Refitting ``atari5.py``'s model to the Atari-5 repository's ``dataset.csv`` reproduces them to every digit.
    Their model normalised with Atari-5's ``Atari-Human.csv``, whose baselines for these five games match
    :data:`GAMES` to within 0.05 points.
    """
    missing = [title for title in ATARI_5 if title not in scores_by_title]
    if missing:
        raise KeyError(f"Atari-5 needs scores for {', '.join(missing)}")
    log_estimate: float | FloatArray = 0.0
    for title, weight in ATARI5_WEIGHTS.items():
        percent = 100.0 * np.asarray(scores_by_title[title], dtype=np.float64)
        log_estimate = log_estimate + weight * np.log10(1.0 + np.maximum(percent, 0.0))
    estimate = (10.0 ** np.asarray(log_estimate) - 1.0) / 100.0
    return float(estimate) if estimate.ndim == 0 else estimate
