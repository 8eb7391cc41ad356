"""On- or off-policy in chess endgames, measured against the exact optimum (the paper's future work, "Chess").

Q-Learning (Algorithm 1) against SARSA (Algorithm 2) play White in KRK and KQK against a defender that resists
longest or plays at random (:mod:`rlcompare.envs.chess.endgame`), ε decaying from 1 and constant at 0.5 as in the
paper, on paired seeds. Each seed's final greedy policy plays a fixed set of won starts, and the solver's depth to
mate says how far each game was from perfect play:

- mate rate: the share of starts it mates from; optimal share: the share it mates in no more moves than perfect play
  takes against the longest resistance (a random defender may be mated sooner);
- excess moves: moves beyond that optimum, over the games it mates (below 0 against a random defender);
  behaviour return: what it collected while
  learning; episodes to hold: when the greedy mate rate rose to :data:`HOLD_LEVEL` and stayed there.

Every comparison is one family under Holm's correction, each with a margin declared in
:mod:`rlcompare.studies.margins`. Why: with decaying ε, the order of choosing A' and updating is swapped in both
learners, which splits SARSA - Q-Learning into order, target and their interaction as the ``why`` study does.
"""

from __future__ import annotations

import functools
from collections.abc import Collection, Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from rlcompare.algorithms.registry import AFTER_UPDATE, BEFORE_UPDATE
from rlcompare.envs.chess.endgames import ENDGAMES, MOVE_LIMIT, parse
from rlcompare.stats.design import GATE, SIGNED_RANK
from rlcompare.studies.interface import UI, run_each
from rlcompare.studies.plans import Question, StudyPlan, episodic
from rlcompare.studies.registry import ChessEndgameOptions
from rlcompare.tabular.config import ExperimentConfig

if TYPE_CHECKING:  # a plan reads no table nor run: pandas loads where one is made
    import pandas as pd

    from rlcompare.tabular.results import Results

STUDY = "chess-endgames"
DEFENDERS = ("optimal", "random")
LEARNERS = ("q_learning", "sarsa")
BUDGETS = {("KRK", "optimal"): 150_000, ("KQK", "optimal"): 100_000, ("KRK", "random"): 30_000,
           ("KQK", "random"): 30_000}
"""Training episodes per seed: where the better learner mates from most starts (measured: docs/chess.md)."""
ALPHA, GAMMA, EPSILON = 0.5, 0.9, 0.5
"""The paper's γ and constant ε; α ten times the paper's (docs/chess.md)."""
SCHEDULES = ("decay", "constant")
ORDER_ABLATION = (("q_learning", BEFORE_UPDATE), ("sarsa", AFTER_UPDATE))
EVAL_STARTS = 200
EVAL_SEED = 41
"""The evaluation starts: :data:`EVAL_STARTS` won positions drawn uniformly with this seed, the same for every
learner and seed; the defender's ties in those games are drawn from a stream of this seed plus the run's."""
HOLD_LEVEL = 0.9
"""The greedy mate rate a learner must reach and keep to the end of training (declared before any run)."""
EVALUATIONS = 20
"""Greedy evaluation rounds over training, of :data:`ROUND_EPISODES` random won starts each."""
ROUND_EPISODES = 50
MEASURES = {"mate_rate": ("mate rate", +1), "optimal_share": ("optimal share", +1),
            "excess_moves": ("excess moves", -1), "behaviour_return": ("behaviour return", +1),
            "episodes_to_hold": ("episodes to hold", -1)}
"""Each measure's name in tables and whether more (+1) or less (-1) is better."""
SIDES = ("SARSA", "Q-Learning")


def env_name(endgame: str, defender: str) -> str:
    return endgame if defender == "optimal" else f"{endgame}:defender={defender}"


def study_configs(options: ChessEndgameOptions) -> dict[str, ExperimentConfig]:
    """Every configuration, by run directory ``{endgame}-{defender}-{algorithm}-{schedule}[-{order}]``."""
    endgames, defenders, learners = options.chosen
    defenders = tuple(d for d in DEFENDERS if d in defenders)
    configs = {}
    for endgame in endgames:
        for defender in defenders:
            episodes = options.episodes or BUDGETS[endgame, defender]
            base = ExperimentConfig(env=env_name(endgame, defender), seeds=options.seed_range, episodes=episodes,
                                    eval_every=max(1, episodes // EVALUATIONS), eval_episodes=ROUND_EPISODES,
                                    stages=(("final", 1.0),), alpha=ALPHA, gamma=GAMMA, epsilon=EPSILON)
            prefix = f"{endgame}-{defender}"
            for algorithm in learners:
                for schedule in SCHEDULES:
                    configs[f"{prefix}-{algorithm}-{schedule}"] = replace(base, algorithm=algorithm, schedule=schedule)
            if set(LEARNERS) <= set(learners):
                for algorithm, order in ORDER_ABLATION:
                    configs[f"{prefix}-{algorithm}-decay-{order}"] = replace(base, algorithm=algorithm,
                                                                             next_action=order)
    return configs


def settings(runs: Collection[str]) -> list[tuple[str, str, str]]:
    """(endgame, defender, schedule) of every pair of SARSA and Q-Learning runs, in the study's order."""
    return [(e, d, s) for e in ENDGAMES for d in DEFENDERS for s in SCHEDULES
            if f"{e}-{d}-sarsa-{s}" in runs and f"{e}-{d}-q_learning-{s}" in runs]


def study_plan(options: ChessEndgameOptions) -> StudyPlan:
    """What the study trains and can decide: every measure of every setting, one family (:func:`verdicts`), and
    the learning gate."""
    configs = study_configs(options)
    comparisons = len(settings(configs)) * len(MEASURES)
    questions = (Question(f"SARSA against Q-Learning ({comparisons} comparisons, each a direction and an "
                          "equivalence test)", SIGNED_RANK, options.seeds, 2 * comparisons),
                 Question("whether each learner has learnt (a mate rate above 0, one-sided)", GATE, options.seeds))
    return StudyPlan(episodic(configs), questions if comparisons else ())


def run(out: Path, options: ChessEndgameOptions, ui: UI, *, study: str = STUDY, force: bool = False
        ) -> dict[str, Results]:
    """Each configuration into ``out / name``, or loaded where it is complete there."""
    runs = run_each(out, study_configs(options), ui, study=study, force=force)
    ui.table(*summary(measured(runs, played(runs))))
    return runs



# --- measures -----------------------------------------------------------------------------------------------


@functools.cache
def evaluation_starts(env: str) -> np.ndarray:
    """The fixed evaluation set of an endgame: :data:`EVAL_STARTS` won positions, uniformly, seed :data:`EVAL_SEED`
    (read-only)."""
    from rlcompare.envs.chess.endgame import make_endgame

    starts = make_endgame(parse(env)).starts
    chosen = np.sort(np.random.default_rng(EVAL_SEED).choice(starts, size=min(EVAL_STARTS, starts.size),
                                                             replace=False))
    chosen.flags.writeable = False
    return chosen


def optimum_moves(env: str, positions: np.ndarray) -> np.ndarray:
    """White's moves to mate with best play from each White-to-move position (the solver's half-moves, halved)."""
    from rlcompare.envs.chess.solver import solve

    return np.asarray(solve(ENDGAMES[parse(env).endgame].piece).white[positions].astype(np.int64) + 1) // 2


class Games(NamedTuple):
    """A seed's final greedy policy from every evaluation start, game by game."""

    won: np.ndarray  # bool: mated
    moves: np.ndarray  # White's moves played
    failed: np.ndarray  # bool: the piece lost, or stalemate
    last: np.ndarray  # the last state and action, as ``state * actions + action``


def greedy_play(results: Results, seed: int) -> Games:
    """The seed's games from every evaluation start (:func:`~rlcompare.tabular.games.greedy_games`), the
    defender's ties drawn from a stream of :data:`EVAL_SEED` plus the seed."""
    from rlcompare.envs.chess.endgame import make_endgame
    from rlcompare.rng import stream_state
    from rlcompare.studies.measures import solved
    from rlcompare.tabular.games import greedy_games

    config = results.config
    tables = make_endgame(parse(config.env))
    starts = tables.state_of[evaluation_starts(config.env)].astype(np.int64)
    returns, moves, ended, last = greedy_games(tables, results.q_table(seed), starts, MOVE_LIMIT,
                                               stream_state(EVAL_SEED + seed))
    won = solved(config.environment.success, returns, moves, ended, MOVE_LIMIT)
    return Games(won, moves, ended & ~won, last)


def played(runs: Mapping[str, Results]) -> dict[str, list[Games]]:
    """:func:`greedy_play` of every seed of every run, by name."""
    return {name: [greedy_play(results, seed) for seed in results.seeds] for name, results in runs.items()}


def episodes_to_hold(rates: np.ndarray, every: int) -> float:
    """The episodes after which the greedy mate rate of every evaluation round stayed at or above
    :data:`HOLD_LEVEL`; NaN where the last round is below it."""
    below = np.flatnonzero(rates < HOLD_LEVEL)
    if below.size and below[-1] == rates.size - 1:
        return np.nan
    return float(((below[-1] + 2) if below.size else 1) * every)


def per_seed(results: Results, games: list[Games]) -> pd.DataFrame:
    """One row per seed: every measure of :data:`MEASURES` and the failure rate (the piece lost or stalemate)."""
    import pandas as pd

    from rlcompare.studies.measures import solved

    config, records = results.config, results.records
    optimum = optimum_moves(config.env, evaluation_starts(config.env))
    rounds = solved(config.environment.success, records.eval_returns, records.eval_lengths, records.eval_terminated,
                    config.step_limit).mean(axis=2)
    return pd.DataFrame([
        {"seed": seed, "mate_rate": g.won.mean(), "optimal_share": (g.won & (g.moves <= optimum)).mean(),
         "excess_moves": (g.moves - optimum)[g.won].mean() if g.won.any() else np.nan,
         "failure_rate": g.failed.mean(), "behaviour_return": records.returns[run].mean(),
         "episodes_to_hold": episodes_to_hold(rounds[run], config.eval_every)}
        for run, (seed, g) in enumerate(zip(results.seeds, games, strict=True))])


def measured(runs: Mapping[str, Results], games: Mapping[str, list[Games]]) -> dict[str, pd.DataFrame]:
    """:func:`per_seed` of every run, by name."""
    return {name: per_seed(results, games[name]) for name, results in runs.items()}


def _title(measure: str) -> str:
    return MEASURES[measure][0] if measure in MEASURES else measure.replace("_", " ")


def summary(metrics: Mapping[str, pd.DataFrame]) -> tuple[pd.DataFrame, str, str]:
    """Each configuration's mean of every measure over seeds: the table, its title and its caption."""
    import pandas as pd

    frame = pd.DataFrame([{"configuration": name, "seeds": len(m),
                           **{_title(str(c)): round(float(m[c].mean()), 3) for c in m.columns if c != "seed"}}
                          for name, m in metrics.items()])
    return (frame, "Chess endgames: mean over seeds",
            f"greedy play from {EVAL_STARTS} fixed won starts; optimal share: mated in no more moves than perfect play "
            "takes against the longest resistance; episodes to hold: when the greedy mate rate reached "
            f"{HOLD_LEVEL:g} and stayed (mean over the seeds that held; the verdicts count the others at the budget)")
