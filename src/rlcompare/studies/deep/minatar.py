"""``rlcompare reproduce minatar``: the paper's question on MinAtar's games (Young and Tian 2019), with networks.

A configuration of the paired study (:mod:`rlcompare.studies.paired`). The pair is the paper's, in one PQN-style
engine whose only switch is the bootstrap: Q(λ) (off-policy, the max) and SARSA(λ) (on-policy, the action taken),
with MinAtar's convolutional network and purejaxql's MinAtar settings, trained on paired seeds under one protocol
(``docs/minatar.md``) and budget, on this machine or on a Ray cluster; ``--methods`` adds DQN, Double DQN, PPO or
Expected SARSA(λ) with their MinAtar presets. Beside what every configuration reports, each game's final return
at ε = 0.05 (DQN's protocol) beside the greedy one and a uniformly random policy's, the answer in words and
seed by seed, the verdicts the paper's tabular study and the deep study wrote for the same question
(:mod:`rlcompare.studies.deep.same_question`), and each method's agent at three stages of learning in every game.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from rlcompare.deep import float64
from rlcompare.deep.methods import DEEP_METHODS, deep_method
from rlcompare.deep.playback import MAX_STEPS, play_stages, stage_titles
from rlcompare.deep.results import DeepResults
from rlcompare.deep.rollout import evaluate
from rlcompare.deep.train import params_template
from rlcompare.envs import minatar
from rlcompare.experiment import store
from rlcompare.formatting import number
from rlcompare.report.aggregate_plots import across_section
from rlcompare.report.page import Section, write_report, write_table
from rlcompare.report.stage_video import render_stages
from rlcompare.stats import intervals as stats
from rlcompare.stats.compare import Judged
from rlcompare.stats.design import SIGNED_RANK, smallest_p
from rlcompare.studies import paired_report
from rlcompare.studies.deep import same_question
from rlcompare.studies.deep.minatar_plan import (
    ABLATIONS,
    BUDGETS,
    LEARNT,
    MARGIN,
    MINATAR,
    OVERALL_MARGIN,
    STUDY,
    plan_of,
    title,
)
from rlcompare.studies.deep.minatar_plan import study_plan as study_plan
from rlcompare.studies.interface import UI, Report
from rlcompare.studies.paired import cluster, final_returns, train
from rlcompare.studies.paired_plan import OVERALL, RANDOM_EPISODES, Key, random_floor
from rlcompare.studies.registry import MinAtarOptions

PAIR_DIFFERS_IN = (
    "What the pair differs in: Q(λ) here is Peng's (purejaxql's), whose return G = r + γ[(1 − λ) max Q(s′) + λ G′] "
    "never cuts its trace on an exploratory action, so at λ = {lam:g} it differs from SARSA(λ) only in the "
    "{share:g}-weighted bootstrap (max against the action taken): it is not off-policy learning of Q* in full. "
    "Watkins's Q(λ) (the trace cut after an exploratory action, Sutton and Barto 12.10) and the pair at λ = 0 (the "
    "one-step targets alone) separate the target from the traces: {ablations}.")
PAIR_LAMBDA = 0.65
"""λ of the pair's MinAtar preset (purejaxql's)."""
SCHEDULES = (
    "Schedules: ε and the learning rate decay over the share of each training their preset gives (PQN: ε over "
    "its first tenth; DQN: ε over 2%), so a shorter budget decays them sooner; purejaxql and MinAtar's own DQN fix "
    "them in steps instead (TOTAL_TIMESTEPS_DECAY; 100,000 steps). At the short budget ε reaches its end after "
    "25,000 steps, not 1 M: the methods are compared under the same rescaled schedules, which docs/minatar.md "
    "states.")
EVAL_EPSILON = 0.05
"""DQN's evaluation protocol (Mnih et al. 2015): ε-greedy with ε = 0.05, beside the greedy evaluation (ε = 0)."""
EPSILON_EPISODES = 8
"""Episodes per seed of the final network at :data:`EVAL_EPSILON`, played when the report is drawn."""
EPSILON_KEY = 20_000
"""Seed ``s``'s episodes at ε = 0.05 play from ``jax.random.key(EPSILON_KEY + s)``, apart from training's keys."""


def game_of(results: DeepResults) -> str:
    return minatar.NAMES[results.config.env][0].module_name


def run(out: Path, options: MinAtarOptions, ui: UI, *, study: str = STUDY, force: bool = False) -> dict[str, Any]:
    """Every training of the plan on this machine, or on the Ray cluster at ``options.address`` (each training's
    blocks of seeds a task: :mod:`rlcompare.studies.seed_blocks`)."""
    plan = plan_of(options)
    backend = cluster(options.address)
    where = f"on Ray at {options.address}" if backend else "on this machine"
    ui.say(f"MinAtar, {minatar.PROTOCOLS[options.protocol].summary}: {len(plan.configs())} trainings x "
           f"{len(plan.seeds)} seeds x {plan.steps_text()} (budget '{options.budget}') {where}; each compiles its "
           "program first.")
    return train(out, STUDY, plan, ui, force=force, backend=backend)


# --- what the report adds to the paired study's --------------------------------------------------------------

def by_game(judged: dict[Key, Judged]) -> dict[str, Judged]:
    """The verdicts by game title (and :data:`~rlcompare.studies.paired_plan.OVERALL`)."""
    return {title(key.env): j for key, j in judged.items()}


@float64
def epsilon_returns(results: DeepResults, epsilon: float = EVAL_EPSILON, episodes: int = EPSILON_EPISODES
                    ) -> np.ndarray:
    """Each seed's mean return of its final network acting ε-greedily (DQN's evaluation protocol)."""
    config = results.config
    act = deep_method(config.algorithm).module.act(config.method_config(), config.environment)
    params = results.stacked_params(params_template(config))
    keys = jnp.stack([jax.random.key(EPSILON_KEY + seed) for seed in results.seeds])
    play = jax.vmap(lambda p, key: evaluate(config.environment, act, p, key, episodes, epsilon)[0])
    returns: np.ndarray = np.asarray(jax.jit(play)(params, keys)).mean(axis=1)
    return returns


def summary_table(runs: dict[str, DeepResults], floors: dict[str, float]) -> pd.DataFrame:
    """Per game and method: the final greedy return (mean and IQM, 95% intervals), at ε = 0.05, and the random
    policy's."""
    rows = []
    for results in runs.values():
        final = final_returns(results)
        rows.append({"game": minatar.GAMES[game_of(results)].title, "env": results.config.env,
                     "method": DEEP_METHODS[results.config.algorithm].label,
                     "final greedy (ε = 0), mean": stats.interval(final).format(2),
                     "final greedy (ε = 0), IQM": stats.interval(final, "iqm").format(2),
                     f"final at ε = {EVAL_EPSILON:g}, mean": stats.interval(epsilon_returns(results)).format(2),
                     "random policy": round(floors[results.config.env], 2), "seeds": len(final),
                     "steps/s": round(results.meta["timings"]["steps_per_second"])})
    return pd.DataFrame(rows)


def same_question_rows(compared: dict[str, Judged]) -> pd.DataFrame:
    """The verdicts by game (:func:`by_game`) in the columns of the table set beside the other studies' verdicts
    (:mod:`rlcompare.studies.deep.same_question`)."""
    return pd.DataFrame([{
        "study": "minatar (this study)", "environment": f"MinAtar, {'over the games' if game == OVERALL else game}",
        "engine: on- vs off-policy": "network (CNN): SARSA(λ) vs Q(λ), PQN-style",
        "metric": "normalised final greedy return" if game == OVERALL else "final greedy return",
        "claim": same_question.TWO_SIDED, "estimate": j.paired.difference.format(2),
        "estimate of": "on - off, mean [95% CI]", "p (Holm)": j.p, "verdict": j.label,
    } for game, j in compared.items()], columns=same_question.COLUMNS)


SAME_QUESTION = (
    "The verdicts above beside those the paper's tabular study (Mountain Car) and the deep study (classic control, "
    "with a network and in a table) wrote in their own verdict tables, read as written: nothing is recomputed. The "
    "paper's rows are its claims (a direction, a sameness or \"about R times\", labelled supported, contradicted, "
    "not resolved, undecidable here or no data), the others' two-sided comparisons labelled by the better target. "
    "Each study Holm-corrects its own claims (the paper study its claims, the deep study its whole table, this one "
    "its games and the overall row), so each label is read within its own study's family: the rows are not one "
    "family.")


def budget_words(steps: int) -> str:
    """How a training of ``steps`` stands beside the named budgets."""
    if steps >= BUDGETS["pqn"][1]:
        return "PQN's budget"
    return "the MinAtar paper's budget" if steps >= BUDGETS["paper"][1] else "a short budget"


def video_cells(runs: dict[str, DeepResults], videos: Path) -> list[tuple[str, str, str]]:
    """Each training's first seed at its three stages of learning, one video per game and method."""
    cells = []
    for name, results in runs.items():
        seed = results.seeds[0]
        played = play_stages(results, seed)
        colours = minatar.palette(played.observations.shape[-1])
        mp4, gif = render_stages(played, stage_titles(results),
                                 functools.partial(minatar.picture, colours=colours), videos / f"{name}.mp4",
                                 videos / f"{name}.gif")
        cells.append((f"videos/{mp4.name}", f"videos/{gif.name}",
                      f"{minatar.GAMES[game_of(results)].title}, {DEEP_METHODS[results.config.algorithm].label}, "
                      f"seed {seed}: {', '.join(results.stages)}"))
    return cells


def report(out: Path, ui: UI | None = None, *, runs: dict[str, Any] | None = None, videos: bool = True,
           beside: dict[str, Path | str] | None = None) -> Report:
    """Tables, verdicts, figures, videos and ``report.html`` of a MinAtar study directory, from its run
    directories; the paper's and the deep study's verdicts beside its own, read from ``beside`` (by study name:
    ``paper``, ``deep``) or from the study directories of those names beside ``out``."""
    siblings = same_question.sibling_dirs(Path(out), beside)
    with store.rewriting(Path(out), "study"):
        return _build_report(Path(out), videos, siblings)


def _build_report(out: Path, videos: bool, siblings: dict[str, Path]) -> Report:
    found = paired_report.findings(out, MINATAR)
    runs, aggregates, files = found.runs, found.aggregates, found.files
    floors = {env: random_floor(env) for env in found.envs}
    summary = summary_table(runs, floors)
    floors_by_game = {title(env): floor for env, floor in floors.items()}
    references_by_game = {title(env): minatar.NAMES[env][0].reference for env in found.envs}
    compared = by_game(found.judged)
    elsewhere = same_question.beside(out, same_question_rows(compared), siblings)
    files |= {name: write_table(frame, out / "tables", f"minatar_{name}")
              for name, frame in (("summary", summary), ("same_question", elsewhere.table))}
    curve_figures = [paired_report.curves_drawn(runs, env, "steps",
                                                out / "figures" / f"curves-{env.replace('/', '_')}.png",
                                                "environment steps") for env in found.envs]
    steps = {r.config.steps_trained for r in runs.values()}
    budget = budget_words(max(steps, default=0))
    protocols = sorted({minatar.NAMES[r.config.env][1].summary for r in runs.values()})
    seeds = min((len(r.seeds) for r in runs.values()), default=0)
    lines = paired_report.answer(compared, seeds, floors=floors_by_game, references=references_by_game)
    unlearnt = paired_report.not_learnt(compared)
    if unlearnt:
        lines.append(f"Not learnt at this budget ({budget}, {max(steps, default=0):,} steps): "
                     f"{', '.join(unlearnt)}. docs/minatar.md expects the 'paper' budget (--budget paper, 5 M "
                     "steps, where the MinAtar paper's DQN reaches its reference) to learn them; not yet measured "
                     "here.")
    sections = [
        paired_report.answer_section(lines, runs, found.envs, title, out / "figures"),
        Section("On-policy or off-policy target, with a convolutional network", [
            f"{paired_report.PQN_PAIR}, final greedy return. Protocol: {'; '.join(protocols)}. Training: "
            f"{', '.join(f'{s:,}' for s in sorted(steps))} environment steps per seed, {budget}: read the verdicts "
            f"as what this budget shows, not what the methods reach. Each game's scale runs from the random "
            f"policy's return to {minatar.REFERENCE_SOURCE}: "
            + ", ".join(f"{title(env)} {number(floors[env])} to {number(minatar.NAMES[env][0].reference)}"
                        for env in found.envs)
            + ". " + paired_report.learnt_rule("the random policy's", LEARNT, MARGIN, [
                f"{title(env)} ±{number(MARGIN * (minatar.NAMES[env][0].reference - floors[env]))}"
                for env in found.envs], " and the game is left out of the overall row; where one has, that is the "
                "answer")
            + f", ±{OVERALL_MARGIN:g} of the normalised score overall (each seed's normalised score averaged over "
            f"the games learnt; random 0, the reference 1). p-values Holm-adjusted over the games and the overall "
            f"row; with {seeds} seeds the signed-rank test cannot give a p below "
            f"{number(smallest_p(SIGNED_RANK, seeds))}.",
            PAIR_DIFFERS_IN.format(lam=PAIR_LAMBDA, share=round(1 - PAIR_LAMBDA, 2), ablations=(
                "they stand beside it in every table" if set(ABLATIONS) <= {r.config.algorithm for r in runs.values()}
                else "'--methods ablations' sets them beside it in every table")),
            SCHEDULES], [("Verdicts", found.verdicts, files["verdicts"])]),
        Section("The same question on tables and on classic control", [SAME_QUESTION, *elsewhere.paragraphs],
                [(same_question.CAPTION, elsewhere.table, files["same_question"])]),
        Section("Every game", [
            f"Final greedy (ε = 0): each seed's mean return in the last evaluation round of training, in the port. "
            f"At ε = {EVAL_EPSILON:g} (DQN's protocol): the same final network acting ε-greedily, {EPSILON_EPISODES} "
            f"episodes a seed played when this report was drawn. Random: the mean of {RANDOM_EPISODES} "
            "episodes of a uniformly random policy under the same protocol."],
            [("Summary", summary, files["summary"])]),
        across_section(
            "Across games",
            "Scores normalised game by game between the random policy (0) and the MinAtar paper's DQN at 5 M frames "
            "(1), as human-normalised scores are on the Atari 2600, pooled over the games as rliable does (Agarwal "
            "et al. 2021): interval estimates, the probability of improvement, performance profiles and "
            "sample-efficiency curves, with 95% stratified bootstrap intervals.",
            aggregates, files, "Interval estimates of normalised final returns",
            "Across games: needs two or more games and methods."),
        Section("Learning curves", figures=curve_figures),
        Section("The agents at three stages of learning", [
            "Each training's first seed, its networks after a tenth and half of the training and at its end, playing "
            "one greedy episode side by side from the same start and with the same draws (the first "
            f"{MAX_STEPS:,} steps), in MinAtar's own colours." if videos else
            "Videos were not rendered (--no-videos)."],
            videos=video_cells(runs, out / "videos") if videos else []),
    ]
    page = write_report(out / "report.html", "MinAtar: on- or off-policy target with a network", sections,
                        found.problems)
    return Report(page, lines, found.problems)
