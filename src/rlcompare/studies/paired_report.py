"""What every configuration of the paired study (:mod:`rlcompare.studies.paired`) reports, computed once.

Every paired comparison judged as one family (:func:`~rlcompare.stats.compare.judge_family`: directions and
equivalences Holm-adjusted together), the verdict table, the answer in words; the deep methods' final returns
normalised per environment between a uniformly random policy (0) and the best method here (1), as rliable's
aggregates take them (Agarwal et al. 2021, "Deep Reinforcement Learning at the Edge of the Statistical
Precipice"); the learning curves and the seed-by-seed differences of the pair.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.deep.methods import DEEP_METHODS
from rlcompare.deep.results import DeepResults
from rlcompare.experiment import rundir
from rlcompare.formatting import number
from rlcompare.report.aggregate_plots import Aggregates, draw_aggregates
from rlcompare.report.findings import gap_and_interval
from rlcompare.report.page import Section, save_figure, write_table
from rlcompare.report.plots import plot_paired_differences, plot_return_curves
from rlcompare.stats.aggregates import by_method, score_scales
from rlcompare.stats.compare import NEITHER_LEARNT, Judged, Paired, compare_paired, gated_label, judge_family
from rlcompare.stats.design import SIGNED_RANK, smallest_p
from rlcompare.studies.paired import (
    eval_curves,
    final_returns,
    load_runs,
    over_environments,
    pair_of,
    per_seed,
    run_of,
    seconds_per_step,
)
from rlcompare.studies.paired_plan import OVERALL, PAIR, Key, PairedStudy, short_label
from rlcompare.studies.plans import ESTIMATE, SPREAD
from rlcompare.tabular.results import Results

TARGETS = ("on-policy", "off-policy")
"""How the verdicts name the better side of the pair."""


@dataclass(frozen=True)
class Across:
    """The deep methods over the environments, as rliable's aggregates take them: per method, ``scores``
    ``(envs, seeds)`` final greedy returns and ``curves`` ``(envs, seeds, rounds)`` greedy returns at each
    evaluation round, normalised per environment between ``floors`` (0) and the best method's mean final return
    (1), with the curves' ``x`` and what it is."""

    envs: list[str]
    floors: dict[str, float]
    scores: dict[str, np.ndarray]
    curves: dict[str, np.ndarray]
    x: np.ndarray
    xlabel: str


def across(runs: Mapping[str, DeepResults], envs: Sequence[str], floors: dict[str, float], methods: Sequence[str],
           references: Mapping[str, float] | None = None) -> Across:
    """Each of ``methods``' runs on every one of ``envs`` that two or more methods ran (a method missing one is
    left out), normalised between ``floors`` (the random policy's mean return) and each environment's reference
    score where ``references`` has one (else the best mean final greedy return of the methods kept). The curves are
    drawn against environment steps where every training evaluated at the same steps, else against the share of
    each training's own steps (budgets may differ by method)."""
    references = references or {}
    finals: dict[str, dict[str, np.ndarray]] = {}
    rounds: dict[str, dict[str, np.ndarray]] = {}
    steps: dict[tuple[str, str], np.ndarray] = {}
    for env in envs:
        for method in methods:
            results = run_of(runs, env, method)
            if results is not None:
                steps[env, method], curves = eval_curves(results)
                finals.setdefault(env, {})[method] = curves[:, -1]
                rounds.setdefault(env, {})[method] = curves
    kept = by_method(finals)
    kept_envs = [env for env, ran in finals.items() if len(ran) > 1]
    finals = {env: {method: finals[env][method] for method in kept} for env in kept_envs}  # 1: the best of these
    scales = score_scales(finals, floors)
    scales |= {env: (floors[env], references[env] - floors[env]) for env in kept_envs if env in references}
    scores = by_method(finals, scales)
    drawn_curves = {method: values for method, values in by_method(rounds, scales).items() if method in scores}
    drawn = [steps[env, method] for env in kept_envs for method in drawn_curves]
    x, xlabel = (drawn[0], "environment steps") if drawn else (np.zeros(0), "")
    if any(not np.array_equal(s, x) for s in drawn):
        x, xlabel = x / x[-1], "share of each training's environment steps"
        if any(s.shape != x.shape or not np.allclose(s / s[-1], x) for s in drawn):
            drawn_curves, x, xlabel = {}, np.zeros(0), ""
    return Across(kept_envs, floors, scores, drawn_curves, x, xlabel)


def judged(study: PairedStudy, runs: Mapping[str, DeepResults], beside: Mapping[str, Results],
           floors: Mapping[str, float], spread: Across | None = None) -> dict[Key, Judged]:
    """Per environment, :data:`PAIR` on paired seeds (each of the study's metrics, the margin in the environment's
    units: :meth:`PairedStudy.margin_of`), then the study's ``others`` (of the runs ``beside`` the networks); over
    two or more environments, where the study declares a margin for it, the pair overall (each seed's normalised
    scores in ``spread`` taken over the environments where a method learnt, by the study's
    :attr:`~PairedStudy.overall_statistic`). All one family
    (:func:`~rlcompare.stats.compare.judge_family`: directions and equivalences Holm-adjusted together); then each
    network comparison behind the learning gate (:func:`~rlcompare.stats.compare.gated_label`) and the divergence
    check."""
    found: dict[Key, Paired] = {}
    learnt: dict[str, tuple[bool, bool]] = {}
    for env in study.envs:
        pair = pair_of(runs, env)
        if pair is not None:
            on, off = (per_seed(results) for results in pair)
            margin = study.margin_of(env, floors.get(env))
            found |= {Key(env, metric=m): compare_paired(on[m].to_numpy(), off[m].to_numpy(), margin)
                      for m in study.metrics}
            if env in study.references:
                learnt[env] = (study.learnt(env, on["greedy_return"].to_numpy(), floors[env]),
                               study.learnt(env, off["greedy_return"].to_numpy(), floors[env]))
        found |= study.others(env, beside)
    counted = [i for i, env in enumerate(spread.envs if spread else []) if any(learnt.get(env, (True, True)))]
    on_scores, off_scores = (spread.scores.get(method) if spread else None for method in PAIR)
    if (study.overall_margin is not None and len(counted) > 1 and on_scores is not None and off_scores is not None
            and on_scores.shape == off_scores.shape):
        found[Key(OVERALL)] = compare_paired(over_environments(on_scores[counted], study.overall_statistic),
                                             over_environments(off_scores[counted], study.overall_statistic),
                                             study.overall_margin)
    family: dict[Hashable, Paired] = {key: paired for key, paired in found.items()}
    judgements = judge_family(family, TARGETS)
    diverged = {env for env in study.envs if any(r.diverged for r in pair_of(runs, env) or ())}

    def label(key: Key) -> str:
        if key.engine != "network":
            return judgements[key].label
        if key.env in diverged or (key.env == OVERALL and diverged):
            return DIVERGED
        return gated_label(judgements[key].label, learnt.get(key.env, (True, True)), TARGETS)

    return {key: judgements[key]._replace(label=label(key)) for key in found}


DIVERGED = "not decided: a training diverged"
"""The label of a comparison of the networks where a seed's parameters became non-finite: its returns are a network
of NaNs' (:attr:`~rlcompare.deep.results.DeepResults.diverged`), so no test on them is a verdict."""


def verdict_table(study: PairedStudy, compared: Mapping[Key, Judged]) -> pd.DataFrame:
    """One row per comparison, with the power its seeds gave it: the smallest p their signed-rank test can give
    (:mod:`rlcompare.stats.design`) and the difference they could detect."""
    return pd.DataFrame([{
        **study.columns(key), ESTIMATE: j.paired.difference.format(study.digits),
        "P(on > off)": j.paired.improvement.format(2), "p (Holm)": j.p, "p equivalent (Holm)": j.p_equivalence,
        "smallest p": number(smallest_p(SIGNED_RANK, j.paired.seeds), 2),
        "detectable (80% power)": number(j.detectable), "verdict": j.label, SPREAD: j.paired.spread,
        "seeds": j.paired.seeds,
    } for key, j in compared.items()])


def answer(compared: Mapping[str, Judged], seeds: int, over: str = "the games",
           floors: Mapping[str, float] | None = None, references: Mapping[str, float] | None = None,
           measure: str = "final greedy return", reference: str = "the reference") -> list[str]:
    """The answer in plain words, from :func:`judged` by each row's name: a sentence for the environments (one
    neither method learnt says so, with the random policy's return and the reference where given), one for the
    comparison :data:`OVERALL`; ``measure`` names what is compared, ``reference`` the top of the scale."""
    on, off = (short_label(method) for method in PAIR)
    each = []
    for name, j in compared.items():
        if name == OVERALL:
            continue
        if j.label == NEITHER_LEARNT:
            scale = (f", against the random policy's {number(floors[name])} and {reference}'s "
                     f"{number(references[name])}" if floors and references and name in references else "")
            each.append(f"on {name} neither has learnt at this budget ({on} {number(j.paired.a_mean)}, {off} "
                        f"{number(j.paired.b_mean)}{scale}): no verdict")
            continue
        gap, interval = gap_and_interval(j.paired.difference)
        each.append(f"on {name} {gap} ({interval}; {j.label})")
    sentences = [f"On-policy {on} against off-policy {off}, {measure} per episode, {seeds} paired seeds: "
                 f"{on} scores {'; '.join(each)}."] if each else []
    if OVERALL in compared:
        paired, label = compared[OVERALL].paired, compared[OVERALL].label
        gap, interval = gap_and_interval(paired.difference)
        top = f"{reference} (1)" if references else "the best method here (1)"
        sentences.append(f"Over {over}, in scores normalised between the random policy (0) and {top}, {on} scores "
                         f"{gap} ({interval}; {label}).")
    return sentences


@dataclass(frozen=True)
class Findings:
    """What every configuration's report shows, from its run directories: the runs (and those beside the
    networks), what could not be read, the environments run in the study's order, the comparisons judged, the
    aggregates over the environments (two or more run) and the tables written, by name."""

    runs: dict[str, DeepResults]
    beside: dict[str, Results]
    problems: list[str]
    envs: list[str]
    judged: dict[Key, Judged]
    verdicts: pd.DataFrame
    across: Across | None
    aggregates: Aggregates | None
    files: dict[str, str]


def labelled(study: PairedStudy, scores: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {study.label(method): values for method, values in scores.items()}


def findings(out: Path, study: PairedStudy) -> Findings:
    """``out``'s runs loaded, the comparisons judged (:func:`judged`) and rliable's aggregates drawn
    (:func:`draw_across`); the verdicts written into ``out / "tables"`` as ``{study.name}_verdicts``."""
    runs, beside, problems = load_runs(out)
    problems += [note for results in runs.values() if (note := results.divergence())]
    envs = [env for env in study.envs if any(r.config.env == env for r in runs.values())]
    floors = {env: study.floor_of(env) for env in envs} if len(envs) > 1 or study.references else {}
    spread = across(runs, envs, floors, study.method_order, study.references) if len(envs) > 1 else None
    compared = judged(study, runs, beside, floors, spread)
    verdicts = verdict_table(study, compared)
    written = write_table(verdicts, out / "tables", f"{study.name}_verdicts")
    rundir.enter_members(out, [], {written: (out / written).read_bytes()})  # read again by the next --plan
    aggregates, files = draw_across(study, spread, out / "tables", out / "figures") if spread else (None, {})
    return Findings(runs, beside, problems, envs, compared, verdicts, spread, aggregates,
                    {"verdicts": written, **files})


def draw_across(study: PairedStudy, spread: Across, tables: Path, figures: Path
                ) -> tuple[Aggregates | None, dict[str, str]]:
    """rliable's aggregates of ``spread`` drawn into ``figures`` and written into ``tables``
    (``{study.name}_aggregates``, ``_improvement``), with those files by name; none unless two or more methods
    ran on two or more environments alike."""
    if len(spread.envs) < 2 or len(spread.scores) < 2:
        return None, {}
    x, xlabel = spread.x, spread.xlabel
    if study.frames_per_step and xlabel == "environment steps":
        x, xlabel = x * study.frames_per_step, "frames"
    aggregates = draw_aggregates(labelled(study, spread.scores), figures, tasks=study.tasks,
                                 curves=labelled(study, spread.curves), x=x, curve_xlabel=xlabel, prefix=study.prefix)
    return aggregates, {name: write_table(frame, tables, f"{study.name}_{name}") for name, frame in (
        ("aggregates", aggregates.intervals), ("improvement", aggregates.improvements))}


PQN_PAIR = "SARSA(λ) against Q(λ) in one PQN-style engine (the bootstrap is the only switch), paired seeds"
"""What the networks' studies compare, in a report's words."""


def not_learnt(compared: Mapping[str, Judged]) -> list[str]:
    """The environments whose verdict is that neither method learnt them."""
    return [env for env, judged in compared.items() if judged.label == NEITHER_LEARNT]


def learnt_rule(floor: str, learnt: float, margin: float, margins: Sequence[str], after_neither: str = "") -> str:
    """The rule a game's verdict follows, for a report: when a method has learnt it (beating ``floor`` by ``learnt``
    of its range), what neither learning it reads, and the margins declared before the runs (``margin`` of the
    range: ``margins``, each game's)."""
    return (f"A method has learnt a game when its final return beats {floor} by {learnt:g} of that range (one-sided "
            f"signed-rank test, α = 0.05); where neither has, the verdict is \"{NEITHER_LEARNT}\"{after_neither}. "
            f"Margins of no difference, declared before the runs: {margin:g} of the game's range "
            f"({', '.join(margins)})")


AGAINST = {"steps": "environment steps", "frames": "frames", "seconds": "seconds of training"}
"""What a curve may be drawn against, and its axis's label."""


def curves_figure(runs: Mapping[str, DeepResults], env: str, against: str, frames_per_step: int = 0) -> Figure:
    """Greedy return against environment steps (``steps``), frames (``frames``: ``frames_per_step`` a step) or
    wall-clock seconds (``seconds``), mean over seeds with a 95% bootstrap band, one line per method."""
    figure = Figure(figsize=(7, 4.2))
    ax = figure.subplots()
    for results in (r for r in runs.values() if r.config.env == env):
        steps, curves = eval_curves(results)
        x = {"steps": steps, "frames": steps * frames_per_step,
             "seconds": steps * seconds_per_step(results)}[against]
        plot_return_curves(ax, x, {DEEP_METHODS[results.config.algorithm].label: curves}, window=1,
                           ylabel="greedy return")
    ax.set_xlabel(AGAINST[against])
    ax.set_title(env)
    return figure


def curves_drawn(runs: Mapping[str, DeepResults], env: str, against: str, path: Path, words: str,
                 frames_per_step: int = 0) -> tuple[str, str]:
    """:func:`curves_figure` saved at ``path``, and its caption (``words``: what it is drawn against)."""
    return (save_figure(curves_figure(runs, env, against, frames_per_step), path),
            f"{env}: greedy return against {words} (mean over seeds, 95% band)")


def pair_finals(runs: Mapping[str, DeepResults], envs: Sequence[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per environment where :data:`PAIR` ran on the same seeds, the final greedy returns of each."""
    pairs = {env: pair_of(runs, env) for env in envs}
    return {env: (final_returns(pair[0]), final_returns(pair[1])) for env, pair in pairs.items() if pair is not None}


def difference_figure(pairs: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> Figure | None:
    """The answer in one picture: per environment (by its name), SARSA(λ) minus Q(λ) seed by seed, from ``pairs``
    of their final greedy returns, with the mean and its interval."""
    if not pairs:
        return None
    figure = Figure(figsize=(3.4 * len(pairs) + 1, 4), layout="constrained")
    axes = figure.subplots(1, len(pairs), squeeze=False)[0]
    for ax, (name, (on, off)) in zip(axes, pairs.items(), strict=True):
        plot_paired_differences(ax, {name: on - off}, {name: f"{name}\n{len(on)} seeds"})
        ax.set_ylabel("SARSA(λ) - Q(λ), final greedy return")
    figure.suptitle("SARSA(λ) minus Q(λ) on the same seeds:\neach dot one seed, the bar the mean with its 95% "
                    "BCa interval")
    return figure


def answer_section(lines: list[str], runs: Mapping[str, DeepResults], envs: Sequence[str],
                   title: Callable[[str], str], figures_dir: Path) -> Section:
    """"The answer": its ``lines`` and its picture, saved as ``paired-differences.png``, each environment under
    ``title(env)`` (no picture where no environment has both methods)."""
    pictured = difference_figure({title(env): pair for env, pair in pair_finals(runs, envs).items()})
    figures = [] if pictured is None else [(save_figure(pictured, figures_dir / "paired-differences.png"),
                                            "SARSA(λ) minus Q(λ), seed by seed, per game")]
    return Section("The answer", lines, figures=figures)
