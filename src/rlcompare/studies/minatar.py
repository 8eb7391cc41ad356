"""``rlcompare reproduce minatar``: the paper's question on MinAtar's games (Young and Tian 2019), with networks.

The pair is the paper's, in one PQN-style engine whose only switch is the bootstrap: Q(λ) (off-policy, the max) and
SARSA(λ) (on-policy, the action taken), with MinAtar's convolutional network and purejaxql's MinAtar settings,
trained on paired seeds under one protocol (``docs/minatar.md``); ``--methods`` adds DQN, Double DQN, PPO or
Expected SARSA(λ) with their MinAtar presets. The report draws greedy learning curves against environment steps,
tabulates each game's final return (greedy, and at ε = 0.05 as DQN's protocol; mean and IQM with 95% intervals)
beside a uniformly random policy's, gives the across-game IQM of scores normalised between random and the best
method here, performance profiles and the probability of improvement, judges "on-policy against off-policy target"
per game, Holm-corrected over the games, sets those verdicts beside the ones the paper's tabular study and the deep
study wrote for the same question (:mod:`rlcompare.studies.same_question`), and shows each method's agent at three
stages of learning in every game.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.deep import float64
from rlcompare.deep.config import DeepConfig
from rlcompare.deep.methods import DEEP_METHODS, deep_method
from rlcompare.deep.playback import MAX_STEPS, play_stages, stage_titles
from rlcompare.deep.results import DeepResults, merge_seeds
from rlcompare.deep.rollout import evaluate
from rlcompare.deep.train import params_template
from rlcompare.envs import minatar
from rlcompare.experiment import engines, rundir, store
from rlcompare.experiment.backends import make_backend
from rlcompare.experiment.runner import run_or_load
from rlcompare.experiment.sweep import Trial
from rlcompare.report import plots
from rlcompare.report.aggregate_plots import draw_aggregates
from rlcompare.report.findings import gap_and_interval
from rlcompare.report.page import Section, plain_number, save_figure, write_report, write_table
from rlcompare.report.stage_video import render_stages
from rlcompare.stats import intervals as stats
from rlcompare.stats.aggregates import by_method, score_scales
from rlcompare.stats.compare import Judged, compare_paired, judge_family
from rlcompare.studies import deep, same_question
from rlcompare.studies.interface import UI, Report, listed
from rlcompare.studies.margins import margin
from rlcompare.studies.registry import MinAtarOptions

STUDY = "minatar"
PAIR = ("pqn_sarsa_lambda", "pqn_q_lambda")
"""The on-policy and the off-policy target in one engine: the only switch is the bootstrap."""
BUDGETS = {
    "short": (("breakout", "space_invaders", "asterix"), 250_000),
    "paper": (tuple(minatar.GAMES), 5_000_000),
    "pqn": (tuple(minatar.GAMES), 10_000_000),
}
"""Budget -> (default games, environment steps per training). ``short``: under 20 minutes on 2 CPU cores with the
default 8 seeds, a short look that says so in its report (at 5 seeds and 400,000 steps every game was already far
above random, and no verdict could be reached: see :func:`smallest_p`); ``paper``: the MinAtar paper's 5 M
frames (a frame is a step: MinAtar skips none); ``pqn``: purejaxql's 10 M steps."""
MARGIN = margin("minatar", "a game (final greedy return)")
"""Differences of mean return smaller than one reward (one brick, alien, treasure or crossing per episode) count
as no difference (:data:`rlcompare.studies.margins.MARGINS`), declared before any run."""
OVERALL_MARGIN = margin("minatar", "over the games (normalised score)")
"""Across games, differences of mean normalised score smaller than a twentieth of the gap between the random
policy and the best method count as no difference."""
EVAL_EPSILON = 0.05
"""DQN's evaluation protocol (Mnih et al. 2015): ε-greedy with ε = 0.05, beside the greedy evaluation (ε = 0)."""
EPSILON_EPISODES = 8
"""Episodes per seed of the final network at :data:`EVAL_EPSILON`, played when the report is drawn."""
EPSILON_KEY = 20_000
"""Seed ``s``'s episodes at ε = 0.05 play from ``jax.random.key(EPSILON_KEY + s)``, apart from training's keys."""
DEFAULT_WORKERS = max(1, min(2, os.cpu_count() or 1))
VMAP_WIDTH = 10
"""Seeds trained side by side in one program, at most."""


def smallest_p(seeds: int) -> float:
    """The smallest two-sided p-value the signed-rank test can give on ``seeds`` pairs, every pair on one side:
    ``2 / 2**seeds``. Below 0.05 divided by the number of games, no verdict can be reached at all."""
    return 2.0 / 2**seeds


@dataclass(frozen=True)
class Plan:
    """What the study trains: games, protocol, seeds and steps."""

    games: tuple[str, ...]
    protocol: str
    seeds: tuple[int, ...]
    steps: int
    budget: str
    workers: int = DEFAULT_WORKERS
    methods: tuple[str, ...] = PAIR

    def env(self, game: str) -> str:
        return minatar.GAMES[game].name(self.protocol)

    def configs(self) -> dict[str, DeepConfig]:
        return {f"{method}-{game}": DeepConfig(algorithm=method, env=self.env(game), seeds=self.seeds,
                                               hyperparameters={"total_steps": self.steps},
                                               vmap_width=min(len(self.seeds), VMAP_WIDTH), eval_rounds=10,
                                               eval_episodes=8)
                for game in self.games for method in self.methods}


def plan_of(options: MinAtarOptions) -> Plan:
    """The plan from the options; an unknown game, protocol or method, or steps a method cannot train in, is a
    :class:`ConfigError` naming the option."""
    default_games, default_steps = BUDGETS[options.budget]
    games = listed("games", options.games, tuple(minatar.GAMES)) if options.games else default_games
    methods = listed("methods", options.methods, tuple(DEEP_METHODS), every="all")
    plan = Plan(games, options.protocol, options.seed_range, options.steps or default_steps, options.budget,
                options.workers or DEFAULT_WORKERS, methods)
    deep.built_with_steps_option(plan.configs)
    return plan


def reproduce(out: Path, plan: Plan, *, progress: Callable[[str, int], None] | None = None, force: bool = False,
              backend: Any = None) -> Iterator[tuple[str, DeepResults, bool]]:
    """Train (or load, where finished) every configuration into ``out``: on this machine, or with ``backend``
    (a connected :class:`~rlcompare.experiment.backends.RayBackend`) as tasks on a cluster."""
    advance = None if progress is None else (lambda n: progress("deep", n))
    if backend is None:
        yield from run_or_load(Path(out), plan.configs(), study=STUDY, progress=advance, force=force,
                               workers=plan.workers)
        return
    with store.output_directory(Path(out), store.Owner("study", STUDY), force=force):
        yield from _trained_on(backend, Path(out), plan.configs(), advance)


def seed_blocks(config: DeepConfig) -> list[DeepConfig]:
    """``config`` cut into blocks of ``vmap_width`` seeds: each trains as it would in one program of the whole (a
    seed's numbers depend on the width, not on the seeds beside it), so the merged blocks equal the whole."""
    width = config.vmap_width
    return [dataclasses.replace(config, seeds=config.seeds[first:first + width])
            for first in range(0, len(config.seeds), width)]


def _trained_on(backend: Any, out: Path, configs: dict[str, DeepConfig], progress: Callable[[int], None] | None
                ) -> Iterator[tuple[str, DeepResults, bool]]:
    """Every configuration ``out`` lacks as tasks of ``backend``, a block of seeds each; a configuration is saved
    when its last block is back, so an interrupted study loses only the configurations it had not finished."""
    trials, blocks, finished = [], {}, []
    for name, config in configs.items():
        stored = engines.load_if_complete(out / name, config)
        if stored is not None:
            if progress is not None:
                progress(config.progress_total)
            yield name, stored, True
            continue
        parts = seed_blocks(config)
        blocks[name] = [None] * len(parts)
        trials += [Trial(part, name, index) for index, part in enumerate(parts)]

    def save(trial: Trial, results: DeepResults) -> None:
        parts = blocks[trial.config_hash]
        parts[trial.seed_index] = results
        if progress is not None:
            progress(len(results.seeds))
        if all(part is not None for part in parts):
            merged = merge_seeds(parts)
            with store.output_directory(out / trial.config_hash, store.RUN):
                rundir.write_results(out / trial.config_hash, merged)
            finished.append((trial.config_hash, merged))

    backend.run(trials, save)
    for name, results in finished:
        yield name, results, False


def run(out: Path, options: MinAtarOptions, ui: UI, *, study: str = STUDY, force: bool = False) -> dict[str, Any]:
    plan = plan_of(options)
    configs = plan.configs()
    backend = None
    if options.address is not None:
        backend = make_backend("ray", address=options.address)
        backend.connect()  # a cluster that cannot be reached is reported before anything is written
    where = f"on Ray at {options.address}" if backend else "on this machine"
    ui.say(f"MinAtar, {minatar.PROTOCOLS[plan.protocol].summary}: {len(configs)} trainings x {len(plan.seeds)} "
           f"seeds x {plan.steps:,} steps (budget '{plan.budget}') {where}; each compiles its program first.")
    runs = {}
    with ui.tasks({"deep": sum(c.progress_total for c in configs.values())}) as advance:
        for name, results, reused in reproduce(out, plan, force=force, progress=advance, backend=backend):
            runs[name] = results
            ui.done(name, results, reused)
    return runs


# --- what the report computes from the run directories ----------------------------------------------------

def game_of(results: DeepResults) -> str:
    return minatar.NAMES[results.config.env][0].module_name


def final_returns(results: DeepResults) -> np.ndarray:
    """Each seed's mean greedy return in the last evaluation round."""
    return deep.eval_curves(results)[1][:, -1]


@float64
def epsilon_returns(results: DeepResults, epsilon: float = EVAL_EPSILON, episodes: int = EPSILON_EPISODES
                    ) -> np.ndarray:
    """Each seed's mean return of its final network acting ε-greedily (DQN's evaluation protocol)."""
    config = results.config
    act = deep_method(config.algorithm).module.act(config.method_config(), config.environment)
    params = results.stacked_params(params_template(config))
    keys = jnp.stack([jax.random.key(EPSILON_KEY + seed) for seed in results.seeds])
    play = jax.vmap(lambda p, key: evaluate(config.environment, act, p, key, episodes, epsilon)[0])
    return np.asarray(jax.jit(play)(params, keys)).mean(axis=1)


def summary_table(runs: dict[str, DeepResults], floors: dict[str, float]) -> pd.DataFrame:
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


def per_game(runs: dict[str, DeepResults], values: Callable[[DeepResults], np.ndarray]
             ) -> dict[str, dict[str, np.ndarray]]:
    """``values`` of every training, by environment and method."""
    found: dict[str, dict[str, np.ndarray]] = {}
    for results in runs.values():
        found.setdefault(results.config.env, {})[results.config.algorithm] = values(results)
    return found


def normalised(runs: dict[str, DeepResults], floors: dict[str, float]) -> dict[str, np.ndarray]:
    """Per method, ``(games, seeds)`` final returns scaled so that the random policy is 0 and the best method's
    mean here is 1, game by game (:func:`~rlcompare.stats.aggregates.score_scales`)."""
    finals = per_game(runs, final_returns)
    return by_method(finals, score_scales(finals, floors))


def normalised_curves(runs: dict[str, DeepResults], floors: dict[str, float]) -> dict[str, np.ndarray]:
    """Per method, ``(games, seeds, rounds)`` greedy curves on the scales of :func:`normalised`."""
    scales = score_scales(per_game(runs, final_returns), floors)
    return by_method(per_game(runs, lambda results: deep.eval_curves(results)[1]), scales)


def short_label(method: str) -> str:
    """``SARSA(λ)`` for ``SARSA(λ), network``: every method here has a network."""
    return DEEP_METHODS[method].label.removesuffix(", network")


def labelled(scores: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {short_label(method): values for method, values in scores.items()}


OVERALL = "overall (normalised)"


def paired_finals(runs: dict[str, DeepResults], games: list[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per game title, the final greedy returns of SARSA(λ) and of Q(λ) on the same seeds."""
    found = {}
    for game in games:
        pair = [next((r for r in runs.values() if game_of(r) == game and r.config.algorithm == m), None)
                for m in PAIR]
        if None not in pair and pair[0].seeds == pair[1].seeds:
            found[minatar.GAMES[game].title] = (final_returns(pair[0]), final_returns(pair[1]))
    return found


def comparisons(runs: dict[str, DeepResults], games: list[str], scores: dict[str, np.ndarray]
                ) -> dict[str, Judged]:
    """SARSA(λ) against Q(λ) per game on paired seeds (final greedy return) and, over two or more games, overall
    (each seed's normalised score averaged over the games), judged as one family (:func:`judge_family`: the games'
    and the overall row's directions and equivalences Holm-adjusted together)."""
    found = {game: compare_paired(on, off, MARGIN) for game, (on, off) in paired_finals(runs, games).items()}
    on, off = (scores.get(method) for method in PAIR)
    if len(found) > 1 and on is not None and off is not None and on.shape == off.shape:
        found[OVERALL] = compare_paired(on.mean(axis=0), off.mean(axis=0), OVERALL_MARGIN)
    return judge_family(found, ("on-policy", "off-policy"))


def verdict_table(compared: dict[str, Judged]) -> pd.DataFrame:
    """:func:`comparisons` as a table, with the difference each row's seeds could detect."""
    return pd.DataFrame([{
        "game": game, "on - off (mean, 95% CI)": j.paired.difference.format(2),
        "P(on > off)": j.paired.improvement.format(2), "p (Holm)": j.p, "p equivalent (Holm)": j.p_equivalence,
        "detectable (80% power)": plain_number(j.detectable), "verdict": j.label,
    } for game, j in compared.items()])


def same_question_rows(compared: dict[str, Judged]) -> pd.DataFrame:
    """:func:`comparisons` in the columns of the table set beside the other studies' verdicts
    (:mod:`rlcompare.studies.same_question`)."""
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


def answer(compared: dict[str, Judged], seeds: int) -> list[str]:
    """The answer in plain words: a sentence for the games, one for the overall comparison."""
    on, off = (short_label(m) for m in PAIR)
    games = []
    for game, j in compared.items():
        if game != OVERALL:
            gap, interval = gap_and_interval(j.paired.difference)
            games.append(f"on {game} {gap} ({interval}; {j.label})")
    sentences = [f"On-policy {on} against off-policy {off}, final greedy return per episode, {seeds} paired seeds: "
                 f"{on} scores {'; '.join(games)}."] if games else []
    if OVERALL in compared:
        paired, label = compared[OVERALL].paired, compared[OVERALL].label
        gap, interval = gap_and_interval(paired.difference)
        sentences.append(f"Over the games, in scores normalised between the random policy (0) and the best method "
                         f"here (1), {on} scores {gap} ({interval}; {label}).")
    return sentences


def difference_figure(runs: dict[str, DeepResults], games: list[str]) -> Figure | None:
    """The answer in one picture: per game, SARSA(λ) minus Q(λ) seed by seed with the mean and its interval."""
    found = paired_finals(runs, games)
    if not found:
        return None
    figure = Figure(figsize=(3.4 * len(found) + 1, 4), layout="constrained")
    axes = figure.subplots(1, len(found), squeeze=False)[0]
    for ax, (game, (on, off)) in zip(axes, found.items(), strict=True):
        plots.plot_paired_differences(ax, {game: on - off}, {game: f"{game}\n{len(on)} seeds"})
        ax.set_ylabel("SARSA(λ) - Q(λ), final greedy return")
    figure.suptitle("SARSA(λ) minus Q(λ) on the same seeds:\neach dot one seed, the bar the mean with its 95% "
                    "BCa interval")
    return figure


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
        mp4, gif = render_stages(played, stage_titles(results), functools.partial(minatar.picture, colours=colours),
                                 videos / f"{name}.mp4", videos / f"{name}.gif")
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
    runs, _, problems = deep.load_runs(out)
    tables, figures = out / "tables", out / "figures"
    envs = sorted({r.config.env for r in runs.values()})
    floors = {env: float(deep.random_returns(env).mean()) for env in envs}
    games = [g for g in minatar.GAMES if any(game_of(r) == g for r in runs.values())]
    summary = summary_table(runs, floors)
    scores = normalised(runs, floors)
    compared = comparisons(runs, games, scores)
    verdicts = verdict_table(compared)
    elsewhere = same_question.beside(out, same_question_rows(compared), siblings)
    aggregates = draw_aggregates(
        labelled(scores), figures, tasks="games", curves=labelled(normalised_curves(runs, floors)),
        x=next(iter(runs.values())).evaluations["after_step"].unique(), curve_xlabel="environment steps",
        prefix="across-games-") if len(games) > 1 and len(scores) > 1 else None
    files = {name: write_table(frame, tables, name) for name, frame in (
        ("minatar_summary", summary), ("minatar_verdicts", verdicts), ("minatar_same_question", elsewhere.table),
        *((("minatar_aggregates", aggregates.intervals), ("minatar_improvement", aggregates.improvements))
          if aggregates else ()))}
    curve_figures = []
    for env in envs:
        path = figures / f"curves-{env.replace('/', '_')}.png"
        curve_figures.append((save_figure(deep.curves_figure(runs, env, "steps"), path),
                              f"{env}: greedy return against environment steps (mean over seeds, 95% band)"))
    steps = {r.config.method_config().total_steps for r in runs.values()}
    budget = budget_words(max(steps, default=0))
    protocols = sorted({minatar.NAMES[r.config.env][1].summary for r in runs.values()})
    seeds = min((len(r.seeds) for r in runs.values()), default=0)
    lines = answer(compared, seeds)
    pictured = difference_figure(runs, games)
    answer_figure = [(save_figure(pictured, figures / "paired-differences.png"),
                      "SARSA(λ) minus Q(λ), seed by seed, per game")] if pictured is not None else []
    sections = [
        Section("The answer", lines, figures=answer_figure),
        Section("On-policy or off-policy target, with a convolutional network", [
            f"SARSA(λ) against Q(λ) in one PQN-style engine (the bootstrap is the only switch), paired seeds, final "
            f"greedy return. Protocol: {'; '.join(protocols)}. Training: {', '.join(f'{s:,}' for s in sorted(steps))}"
            f" environment steps per seed, {budget}: read the verdicts as what this budget shows, not what the "
            f"methods reach. Margins of no difference, declared before the runs: ±{MARGIN:g} per episode in a "
            f"game, ±{OVERALL_MARGIN:g} of the normalised score overall (each seed's normalised score averaged over "
            f"the games; random 0, the best method here 1). p-values Holm-adjusted over the games and the overall "
            f"row; with {seeds} seeds the signed-rank test cannot give a p below "
            f"{smallest_p(seeds):.3g}."], [("Verdicts", verdicts, files["minatar_verdicts"])]),
        Section("The same question on tables and on classic control", [SAME_QUESTION, *elsewhere.paragraphs],
                [(same_question.CAPTION, elsewhere.table, files["minatar_same_question"])]),
        Section("Every game", [
            f"Final greedy (ε = 0): each seed's mean return in the last evaluation round of training, in the port. "
            f"At ε = {EVAL_EPSILON:g} (DQN's protocol): the same final network acting ε-greedily, {EPSILON_EPISODES} "
            f"episodes a seed played when this report was drawn. Random: the mean of {deep.RANDOM_EPISODES} "
            "episodes of a uniformly random policy under the same protocol."],
            [("Summary", summary, files["minatar_summary"])]),
        Section("Across games", [
            "Scores normalised game by game between the random policy (0) and the best method's mean here (1), "
            "pooled over the games as rliable does (Agarwal et al. 2021): interval estimates, the probability of "
            "improvement, performance profiles and sample-efficiency curves, with 95% stratified bootstrap "
            "intervals. The MinAtar paper's DQN scores are not used as the upper anchor: rlcompare has no citable "
            "table of them." if aggregates else "Across games: needs two or more games and methods."],
            [("Interval estimates of normalised final returns", aggregates.intervals, files["minatar_aggregates"]),
             ("Probability of improvement", aggregates.improvements, files["minatar_improvement"])]
            if aggregates else [], aggregates.figures if aggregates else []),
        Section("Learning curves", figures=curve_figures),
        Section("The agents at three stages of learning", [
            "Each training's first seed, its networks after a tenth and half of the training and at its end, playing "
            "one greedy episode side by side from the same start and with the same draws (the first "
            f"{MAX_STEPS:,} steps), in MinAtar's own colours." if videos else
            "Videos were not rendered (--no-videos)."],
            videos=video_cells(runs, out / "videos") if videos else []),
    ]
    page = write_report(out / "report.html", "MinAtar: on- or off-policy target with a network", sections, problems)
    return Report(page, lines, problems)
