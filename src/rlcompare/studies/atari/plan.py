"""What ``rlcompare reproduce atari`` trains and can decide (its ``--plan``): the budgets, sets of games and methods,
each game's margin on its random-to-human range, read by the study (:mod:`rlcompare.studies.atari.study`) and by
``--plan`` without the report's modules.
"""

from __future__ import annotations

from dataclasses import dataclass

from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.envs.atari import games as atari
from rlcompare.envs.atari import scores as atari_scores
from rlcompare.studies.interface import listed
from rlcompare.studies.margins import margin
from rlcompare.studies.paired_plan import OVERALL, PairedStudy, Plan, checked, paired_plan, short_label
from rlcompare.studies.plans import StudyPlan
from rlcompare.studies.registry import AtariOptions
from rlcompare.validation import ConfigError

STUDY = "atari"


@dataclass(frozen=True)
class Budget:
    """A named budget (:data:`rlcompare.studies.registry.ATARI_BUDGETS`): its games (a set of
    :data:`rlcompare.envs.atari.scores.SETS`), agent steps per training, evaluations, and how long it takes, measured
    or not (``docs/atari.md``)."""

    games: str
    steps: int
    eval_rounds: int
    eval_episodes: int
    takes: str


BUDGETS = {
    "smoke": Budget("breakout", 32_768, 4, 8,
                    "about 10 minutes on 2 CPU cores at the default 2 seeds (measured: docs/atari.md)"),
    "100k": Budget("atari100k", 100_000, 10, 8,
                   "about 30 minutes a game on 2 CPU cores at 2 seeds (13 hours for the 26), from the smoke's "
                   "measured pace; not run whole"),
    "10m": Budget("atari5", 10_000_000, 20, 8, "about 12 hours a seed of a method and game on 2 CPU cores, from the "
                  "smoke's measured pace: a GPU's work, not yet measured on one"),
    "200m": Budget("atari5", 50_000_000, 20, 8,
                   "purejaxql's 200 M frames a training: a GPU's work, not yet measured"),
}
"""Budget -> its defaults. A step is 4 frames: ``10m`` is 10 M steps (40 M frames), ``200m`` 200 M frames; Atari
100k's is 100,000 steps (Kaiser et al. 2020)."""
MARGIN = margin("atari", "a game (final return)")
LEARNT = margin("atari", "learnt (final return above random)")
OVERALL_MARGIN = margin("atari", "over the games (human-normalised score)")
EPSILON = atari.PROTOCOL.eval_epsilon


def name_of(title: str) -> str:
    return f"{title}-Atari"


def title(env: str) -> str:
    """``Breakout`` for ``Breakout-Atari`` (and :data:`~rlcompare.studies.paired_plan.OVERALL` for itself)."""
    return env if env == OVERALL else atari.title_of(env)


ENVS = tuple(name_of(t) for t in atari_scores.GAMES)
ATARI = PairedStudy(STUDY, ENVS, dict.fromkeys(ENVS, MARGIN), lambda key: {"game": title(key.env)},
                    label=short_label, method_order=tuple(sorted(DEEP_METHODS)), tasks="games",
                    overall_margin=OVERALL_MARGIN, prefix="across-games-",
                    references={name_of(t): g.human for t, g in atari_scores.GAMES.items()},
                    floors={name_of(t): g.random for t, g in atari_scores.GAMES.items()}, learnt_share=LEARNT,
                    overall_statistic="iqm", frames_per_step=atari.PROTOCOL.frameskip)
"""Every game of the 57, each margin a share of its random-to-human range; over them, each seed's interquartile mean
of its human-normalised scores, which one game's scale cannot own (DoubleDunk and Phoenix make 80% of the mean of
Rainbow's Atari-5 scores)."""


def check_roms(titles: tuple[str, ...]) -> None:
    """Each game's ROM, which ale-py ships; one it lacks a :class:`~rlcompare.validation.ConfigError` naming it."""
    from ale_py import roms

    missing = [t for t in titles if roms.get_rom_path(atari_scores.GAMES[t].rom) is None]
    if missing:
        raise ConfigError("games", ",".join(missing), "games whose ROM ale-py has (pip install -e '.[atari]')")


def plan_of(options: AtariOptions) -> Plan:
    """The plan from the options; an unknown game or method, a missing ROM, or steps a method cannot train in is a
    :class:`~rlcompare.validation.ConfigError` naming the option."""
    budget = BUDGETS[options.budget]
    titles = atari_scores.chosen_games(options.games or budget.games)
    check_roms(titles)
    methods = listed("methods", options.methods, tuple(DEEP_METHODS), every="all")
    return checked(Plan(options.seed_range, methods, {t: name_of(t) for t in titles},
                        options.steps or budget.steps, 1, eval_rounds=budget.eval_rounds,
                        eval_episodes=budget.eval_episodes, vmap_width=1))


def plumbing(steps: int) -> str:
    """Why a training of ``steps`` steps checks the pipeline, not the question (the smoke budget's or fewer); empty
    where it asks the question."""
    if steps > BUDGETS["smoke"].steps:
        return ""
    return f"{steps:,} steps a training, the smoke budget's or fewer: the pipeline checked, not the question"


def study_plan(options: AtariOptions) -> StudyPlan:
    """What the study trains and can decide (``reproduce atari --plan``); the smoke budget is a plumbing check."""
    plan = plan_of(options)
    steps = max(config.steps_trained for config in plan.configs().values())
    return paired_plan(ATARI, plan, "agent steps", plumbing(steps))
