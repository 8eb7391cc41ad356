"""What ``rlcompare reproduce minatar`` trains and can decide (its ``--plan``): the budgets, games, protocols and
methods, each game's margin, read by the study (:mod:`rlcompare.studies.deep.minatar`) and by ``--plan`` without the
report's modules or gymnax's games.
"""

from __future__ import annotations

import os

from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.envs import minatar
from rlcompare.studies.interface import listed
from rlcompare.studies.margins import margin
from rlcompare.studies.paired_plan import OVERALL, PairedStudy, Plan, checked, paired_plan, short_label
from rlcompare.studies.plans import StudyPlan
from rlcompare.studies.registry import MinAtarOptions

STUDY = "minatar"
BUDGETS = {
    "short": (("breakout", "space_invaders", "asterix"), 250_000),
    "paper": (tuple(minatar.GAMES), 5_000_000),
    "pqn": (tuple(minatar.GAMES), 10_000_000),
}
"""Budget -> (default games, environment steps per training). ``short``: 11 minutes on 2 CPU cores with the pair and
9 seeds, the fewest that can decide (672 s measured; 37 minutes with the ablations at 8), a short look that says so in
its report
(at 5 seeds and 400,000 steps every game was already far above random, and no verdict could be reached: see
:mod:`rlcompare.stats.design`); ``paper``: the MinAtar paper's 5 M frames (a frame is a step: MinAtar skips none);
``pqn``: purejaxql's 10 M steps."""
MARGIN = margin("minatar", "a game (final greedy return)")
"""Differences of mean return smaller than this share of the game's range from the random policy to the MinAtar
paper's DQN count as no difference (:data:`rlcompare.studies.margins.MARGINS`), declared before any run."""
LEARNT = margin("minatar", "learnt (final greedy return above random)")
"""A method has learnt a game when its final return beats the random policy's by this share of the same range."""
OVERALL_MARGIN = margin("minatar", "over the games (normalised score)")
"""Across games, differences of mean normalised score (random 0, the reference 1) smaller than this count as no
difference."""
ABLATIONS = ("pqn_sarsa_lambda", "pqn_q_lambda", "pqn_watkins_q_lambda", "pqn_sarsa", "pqn_q_learning")
"""``--methods ablations``: the pair, Watkins's Q(λ) and the pair at λ = 0."""
DEFAULT_WORKERS = max(1, min(2, os.cpu_count() or 1))


def title(env: str) -> str:
    """``Breakout`` for ``MinAtar/Breakout-v0`` (and for :data:`~rlcompare.studies.paired_plan.OVERALL`, itself)."""
    return env if env == OVERALL else minatar.NAMES[env][0].title


ENVS = tuple(minatar.NAMES)
"""Every game under every protocol, game by game."""
MINATAR = PairedStudy(STUDY, ENVS, dict.fromkeys(ENVS, MARGIN), lambda key: {"game": title(key.env)},
                      label=short_label, method_order=tuple(sorted(DEEP_METHODS)), tasks="games",
                      overall_margin=OVERALL_MARGIN, prefix="across-games-",
                      references={env: game.reference for env, (game, _) in minatar.NAMES.items()},
                      learnt_share=LEARNT)
"""MinAtar's games, each margin a share of the game's random-to-reference range, one margin over them, the methods
by their short names."""


def plan_of(options: MinAtarOptions) -> Plan:
    """The plan from the options; an unknown game, protocol or method, or steps a method cannot train in, is a
    :class:`~rlcompare.validation.ConfigError` naming the option."""
    default_games, default_steps = BUDGETS[options.budget]
    games = listed("games", options.games, tuple(minatar.GAMES)) if options.games else default_games
    methods = listed("methods", options.methods, tuple(DEEP_METHODS), every="all", groups={"ablations": ABLATIONS})
    envs = {game: minatar.GAMES[game].name(options.protocol) for game in games}
    return checked(Plan(options.seed_range, methods, envs, options.steps or default_steps,
                        options.workers or DEFAULT_WORKERS, eval_rounds=10, eval_episodes=8))


def study_plan(options: MinAtarOptions) -> StudyPlan:
    """What the study trains and can decide (``reproduce minatar --plan``)."""
    return paired_plan(MINATAR, plan_of(options))
