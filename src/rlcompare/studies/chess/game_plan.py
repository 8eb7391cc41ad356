"""What ``rlcompare reproduce chess`` trains and can decide (its ``--plan``): the game, budgets and methods, the
margin on the result against the random player, read by the study (:mod:`rlcompare.studies.chess.game`) and by
``--plan`` without the report's or the ladder's modules.
"""

from __future__ import annotations

import os

from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.envs.chess.games import GAMES
from rlcompare.studies.interface import listed
from rlcompare.studies.margins import margin
from rlcompare.studies.paired_plan import PairedStudy, Plan, checked, paired_plan, short_label
from rlcompare.studies.plans import StudyPlan
from rlcompare.studies.registry import ChessOptions

STUDY = "chess"
BUDGETS = {"cpu": 500_000, "gpu": 10_000_000}
"""Budget -> environment steps per training (``docs/chess-game.md`` gives the time each took)."""
MARGIN = margin("chess", "a game (result against the random player)")
LEARNT = margin("chess", "learnt (result above the random player's)")
WON_EVERY_GAME = 1.0
"""The reference a result is measured against: +1, winning every game against the random player."""
DEFAULT_WORKERS = max(1, min(2, os.cpu_count() or 1))
EVAL_ROUNDS, EVAL_EPISODES = 10, 64
"""Each training's evaluations: rounds over the training, and games of the greedy network against the random player
in each."""


def game_title(env: str) -> str:
    return GAMES[env].label


CHESS = PairedStudy(STUDY, tuple(GAMES), dict.fromkeys(GAMES, MARGIN), lambda key: {"game": game_title(key.env)},
                    label=short_label, method_order=tuple(sorted(DEEP_METHODS)), tasks="games",
                    references=dict.fromkeys(GAMES, WON_EVERY_GAME), learnt_share=LEARNT)
"""The game played, its margin a share of the range from the random player's result against itself (0) to winning
every game (+1)."""


def plan_of(options: ChessOptions) -> Plan:
    """The plan from the options; an unknown game or method is a :class:`~rlcompare.validation.ConfigError`."""
    methods = listed("methods", options.methods, tuple(m for m in DEEP_METHODS if m.startswith("pqn_")))
    return checked(Plan(options.seed_range, methods, {options.game: options.game},
                        options.steps or BUDGETS[options.budget], options.workers or DEFAULT_WORKERS,
                        eval_rounds=EVAL_ROUNDS, eval_episodes=EVAL_EPISODES))


def study_plan(options: ChessOptions) -> StudyPlan:
    """What the study trains and can decide (``reproduce chess --plan``)."""
    return paired_plan(CHESS, plan_of(options), "plies")
