"""The paper study's tables, verdicts, figures, videos and ``report.html``, rebuilt from stored runs.

Everything here reads run directories; nothing trains. A configuration whose directory is missing or
damaged is named in the report and left out of what needs it; the rest is still built. The same report
answers the paper's question on another environment (``reproduce cartpole``, ``reproduce acrobot``): the
paper's printed values and its Mountain Car pictures (maps over position and velocity, first actions)
then stay out, and its claims are tested as they would read there.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import ParamSpec

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_run
from rlcompare.report.aggregate_plots import Aggregates, draw_aggregates
from rlcompare.report.drawn import Drawn
from rlcompare.report.findings import BEHAVIOUR_AND_GREEDY, opening, paper_findings
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.report.video import VideoJob, VideoRenders, start_videos
from rlcompare.stats.aggregates import by_method, score_scales
from rlcompare.stats.convergence import DEFAULT_RULE, RULES
from rlcompare.stats.intervals import interval
from rlcompare.stats.significance import ALPHA
from rlcompare.stats.verdicts import RATIO_FACTOR, holm_family, judge_by_rule
from rlcompare.studies.interface import Report
from rlcompare.studies.measures import (
    PAPER_TABLE_I,
    PAPER_TABLE_II,
    convergence_by_rule,
    noise_floors,
    per_seed_metrics,
    table_i,
    table_ii,
)
from rlcompare.studies.paper.claims import CLAIMS, NAMES, claims_asked, scaled
from rlcompare.studies.paper.figures import (
    curve_figure,
    differences_figure,
    first_actions_figure,
    label,
    paired_differences,
    stages_figure,
    visits_figure,
)
from rlcompare.studies.paper.videos import CONFIGURATIONS, WATCH_FOR, video_key, video_plan
from rlcompare.studies.paper.why import decomposition, decomposition_figure, formatted, in_brief
from rlcompare.studies.paper.why import findings as why_findings
from rlcompare.studies.start_region import has_start_region
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results

Arguments = ParamSpec("Arguments")

FIGURES = (
    ("fig3-random", ("random",), "Fig. 3: the random baseline"),
    ("fig4-q_learning-constant", ("q_learning-constant",), "Fig. 4: Q-Learning with ε constant at 0.5"),
    ("fig5-sarsa-constant", ("sarsa-constant",), "Fig. 5: SARSA with ε constant at 0.5"),
    ("fig6-constant", ("q_learning-constant", "sarsa-constant"), "Fig. 6: Q-Learning and SARSA, ε constant"),
    ("fig7-q_learning-decay", ("q_learning-decay",), "Fig. 7: Q-Learning with ε decaying from 1"),
    ("fig8-sarsa-decay", ("sarsa-decay",), "Fig. 8: SARSA with ε decaying from 1"),
    ("fig9-decay", ("q_learning-decay", "sarsa-decay"), "Fig. 9: Q-Learning and SARSA, ε decaying"),
)
def load_study(study_dir: Path) -> tuple[dict[str, Results], list[str]]:
    """Every configuration that loads, and a line for each that does not: the paper's five, then any other
    algorithm run on the paper's grid (``reproduce --algorithms``), which adds rows to the tables."""
    loaded, problems = {}, []
    extra = sorted(p.name for p in Path(study_dir).glob("*/") if (p / rundir.CONFIG_FILE).is_file()
                   and p.name not in CONFIGURATIONS) if Path(study_dir).is_dir() else []
    for name in (*CONFIGURATIONS, *extra):
        run_dir = Path(study_dir) / name
        if not run_dir.is_dir():
            problems.append(f"{name}: no run directory at {run_dir}")
            continue
        try:
            loaded[name] = load_run(run_dir)
        except (store.StoreError, ValueError, KeyError) as error:
            problems.append(f"{name}: {error}")
    named = [problem.split(":")[0] for problem in problems]
    return loaded, problems + (rundir.missing_members(Path(study_dir), named) if Path(study_dir).is_dir() else [])


def build_report(study_dir: Path, *, videos: bool = True, video_seed: int | None = None,
                 video_workers: int | None = None) -> Report:
    """Tables (Markdown and CSV), verdicts, figures, videos and ``report.html`` inside ``study_dir``.

    The videos render on ``video_workers`` other processes (default: see
    :func:`~rlcompare.report.video.default_workers`) while this process builds the tables and figures; the
    files are the same whatever the number.
    """
    with store.rewriting(Path(study_dir), "study"):
        return _build_report(Path(study_dir), videos, video_seed, video_workers)


AGGREGATE_POINTS = 50
"""Points of the sample-efficiency curves: training cut into this many equal spans of episodes."""


def paper_aggregates(runs: dict[str, Results], figures_dir: Path, drawn: Drawn | None = None) -> Aggregates | None:
    """rliable's aggregates of the paper's four learners on its one task (Agarwal et al. 2021): each seed's
    behaviour return normalised between the random baseline's mean (0) and the best learner's mean (1), and its
    learning curve on the same scale, averaged over :data:`AGGREGATE_POINTS` spans of episodes."""
    learners = [name for name in CONFIGURATIONS if name != "random" and name in runs]
    if "random" not in runs or len(learners) < 2:
        return None
    task = runs["random"].config.env
    finals = {task: {label(runs[n]): runs[n].records.returns.mean(axis=1) for n in learners}}
    scales = score_scales(finals, {task: float(runs["random"].records.returns.mean())})
    episodes = runs[learners[0]].config.episodes
    spans = np.array_split(np.arange(episodes), min(AGGREGATE_POINTS, episodes))
    curves = {task: {label(runs[n]): np.stack([runs[n].records.returns[:, span].mean(axis=1) for span in spans],
                                                axis=1) for n in learners}}
    return draw_aggregates(by_method(finals, scales), figures_dir, xlabel="normalised return while learning",
                           tasks="task", curves=by_method(curves, scales),
                           x=np.array([span[-1] + 1 for span in spans]), curve_xlabel="episode",
                           figure=None if drawn is None else
                           lambda path, draw: drawn.figure(path, draw, [runs["random"], *(runs[n] for n in learners)]))


def _build_report(study_dir: Path, videos: bool, video_seed: int | None, video_workers: int | None) -> Report:
    started = time.perf_counter()
    runs, problems = load_study(study_dir)
    if not runs:
        raise store.StoreError(f"{study_dir}: no configuration of the paper study could be read: "
                               + "; ".join(problems))
    plan = video_plan(study_dir, runs, video_seed) if videos else []
    drawn = Drawn(study_dir)
    keys = {job.mp4: video_key(runs, job) for _, job in plan}
    kept = {path for _, job in plan for path in job.outputs if drawn.kept(path, keys[job.mp4])}
    pending = [job for _, job in plan if not set(job.outputs) <= kept]
    with start_videos(pending, workers=video_workers) as renders:
        return _build_report_beside(study_dir, runs, problems, plan, renders, started, drawn, keys, kept)


def _build_report_beside(study_dir: Path, runs: dict[str, Results], problems: list[str],
                         plan: list[tuple[str, VideoJob]], renders: VideoRenders,
                         started: float, drawn: Drawn, keys: dict[Path, str | None], kept: set[Path]) -> Report:
    """Tables, figures and the page, built while the videos of ``plan`` render; waits for them before the page.
    A figure or video whose inputs have not changed since the last report is kept (:mod:`rlcompare.report.drawn`):
    ``keys``, each video's key by its MP4; ``kept``, the video files kept."""
    seconds: dict[str, float] = {}
    first, episodes = next(iter(runs.values())), next(iter(runs.values())).config.episodes
    position_velocity = has_start_region(first.config)
    paper_values = first.config.env == "MountainCar-v0"
    learners = [r for n, r in runs.items() if n != "random" and r.config.next_action is None]  # in their own box
    paper_learners = [runs[n] for n in CONFIGURATIONS if n in runs and n != "random"]
    metrics = {name: per_seed_metrics(results) for name, results in runs.items()}
    tables_dir, figures_dir = study_dir / "tables", study_dir / "figures"
    claims = claims_asked(runs, position_velocity)
    judgement = judge_by_rule([scaled(c, episodes) for c in claims], metrics, episodes, names=NAMES,
                              floors=noise_floors(runs) if position_velocity else {},
                              rules={name: convergence_by_rule(r) for name, r in runs.items() if name != "random"})
    tables = {
        "table_i": table_i(metrics, PAPER_TABLE_I if paper_values else {}, episodes),
        "table_ii": table_ii(metrics, PAPER_TABLE_II if paper_values else {}),
        "verdicts": judgement.verdicts,
        "verdict_rules": judgement.rules,
    }
    split = decomposition(runs)
    if not split.empty:
        tables["decomposition"] = formatted(split)
    aggregates = paper_aggregates(runs, figures_dir, drawn)
    if aggregates is not None:
        tables["aggregates"], tables["improvement"] = aggregates.intervals, aggregates.improvements
    files = {name: write_table(frame, tables_dir, name) for name, frame in tables.items()}
    findings = paper_findings(claims, judgement.verdicts, metrics, why_findings(split) if not split.empty else None)
    seconds["tables and verdicts"] = time.perf_counter() - started

    mark = time.perf_counter()
    curve_figures = []
    for file_name, names, title in FIGURES:
        present = [runs[n] for n in names if n in runs]
        if len(present) == len(names):
            curve_figures.append((drawn.figure(figures_dir / f"{file_name}.png", _saved(curve_figure, present, title),
                                               present),
                                  title))
        else:
            problems.append(f"{title}: left out, its runs are missing")
    explanation_figures = [(drawn.figure(figures_dir / f"stages-{r.config.name}.png", _saved(stages_figure, r), [r]),
                            f"{label(r)}: greedy action and state value at each stage") for r in learners
                           if position_velocity]
    if paper_learners and position_velocity:
        explanation_figures += [
            (drawn.figure(figures_dir / "visits.png", _saved(visits_figure, paper_learners), paper_learners),
             "State visits during training"),
            (drawn.figure(figures_dir / "first-actions.png", _saved(first_actions_figure, paper_learners),
                          paper_learners),
             "First greedy action from the start region"),
        ]
    if not split.empty:
        explanation_figures.insert(0, (drawn.figure(figures_dir / "decomposition.png",
                                                    _saved(decomposition_figure, split), runs.values()),
                                       "SARSA minus Q-Learning = order + target + interaction"))
    seconds["figures"] = time.perf_counter() - mark

    video_cells = []
    if plan:
        rendered = set(renders.wait())
        for job in renders.jobs:
            drawn.record([path for path in job.outputs if path in rendered], keys[job.mp4])
        written = rendered | kept
        for caption, job in plan:
            gif = job.gif if job.gif is not None and job.gif in written else None
            video_cells.append((f"videos/{job.mp4.name}", f"videos/{gif.name}" if gif is not None else "", caption))
        seconds["videos"] = time.perf_counter() - (renders.started or started)

    answer = opening(claims, judgement.verdicts, metrics)
    brief = [in_brief(split)] if not split.empty else []
    differences = paired_differences(runs, metrics)  # none: the figure has nothing to show
    answer_figure = [(drawn.figure(figures_dir / "paired-differences.png",
                                   _saved(differences_figure, runs, differences), runs.values()),
                      "SARSA minus Q-Learning, seed by seed: each dot one seed's paired difference; the bar the mean "
                      "and its 95% interval")] if differences else []
    sections = [Section("The answer", [*answer, *brief], figures=answer_figure),
                Section("What the answer rests on", [*findings[len(answer):], BEHAVIOUR_AND_GREEDY]),
                *_sections(first, runs, metrics, tables, files, curve_figures, explanation_figures, video_cells,
                           aggregates.figures if aggregates is not None else [])]
    title = ("On- and off-policy control on Mountain Car: the paper, reproduced" if paper_values
             else f"On- and off-policy control on {first.config.env}: the paper's question")
    path = write_report(study_dir / "report.html", title, sections, problems)
    drawn.remove_unrecorded("figures/*.png")  # figures of runs that are gone must not linger
    drawn.save()
    seconds["total"] = time.perf_counter() - started
    return Report(path=path, lines=findings, problems=problems, seconds=seconds)


def _saved(draw: Callable[Arguments, Figure], *args: Arguments.args, **kwargs: Arguments.kwargs
           ) -> Callable[[Path], str]:
    """What :meth:`Drawn.figure` calls to draw a figure: ``draw(*args)`` saved at the path it is given."""
    return lambda path: save_figure(draw(*args, **kwargs), path)


def _grid_text(config: ExperimentConfig) -> str:
    if config.environment.n_states:
        return f"{config.environment.n_states} states, one feature each"
    bins = config.grid_bins
    per_dim = bins if isinstance(bins, tuple) else (bins,) * config.environment.observation_size
    return f"{' x '.join(map(str, per_dim))} uniform cells"


def schedule_notes(runs: dict[str, Results], metrics: dict[str, pd.DataFrame]) -> list[str]:
    """A sentence for each decaying configuration whose time to converge has ε's last change inside its 95%
    interval: there the metric partly measures the schedule (``docs/why.md``)."""
    notes = []
    for name, results in runs.items():
        c = results.config
        if c.schedule != "decay" or c.algorithm == "random":
            continue
        converged = metrics[name]["convergence_episode"].dropna().to_numpy()
        if converged.size < 2:
            continue
        estimate, settled = interval(converged), max(round(c.decay_fraction * c.episodes), 1)
        if estimate.low <= settled <= estimate.high:
            greedy_sarsa = c.algorithm == "sarsa" and c.epsilon_end == 0
            same_target = " From there SARSA's target is Q-Learning's." if greedy_sarsa else ""
            notes.append(f"{name}: ε reaches {c.epsilon_end:g} at episode {settled}, inside its time to converge "
                         f"{estimate.format(0)}: its convergence partly measures the schedule.{same_target}")
    return notes


def _table_i_text(config: ExperimentConfig) -> str:
    """Table I's rule in full (:mod:`rlcompare.stats.convergence`)."""
    window = min(DEFAULT_RULE.window, config.episodes)
    stay = max(2 * window, round(0.1 * config.episodes))
    return (f"A run has converged at the first episode after which its return, averaged over the previous {window} "
            f"episodes, stays within a band around its final level (the mean of its last {window} episodes) to the "
            f"end of training; the band is {DEFAULT_RULE.tolerance:.0%} of the distance from the first "
            f"{window} episodes' level to the final level, and at least 10 reward. A run that entered the band for "
            f"good only in its last {stay} episodes (two windows, or 10% of training if longer) has not shown that "
            f"it stays there, and a run whose last {window} episodes reach the goal less than half the time has "
            "nothing to converge to: both never converged, and count at the last episode where a mean needs a number "
            "(censored). Seconds are CPU seconds of one run up to that episode. The paper's values have no unit "
            "and no rule.")


def _verdict_text() -> list[str]:
    """How the verdicts are reached: labels, tests, margins, Holm's family and the fragile mark."""
    margins = ", ".join(f"{c.bounds[1]:.0%} of training for convergence" if c.metric == "convergence_episode"
                        else f"{c.bounds[1]:g} reward for {c.metric.replace('_', ' ')}s"
                        for c in CLAIMS if c.kind == "within")
    behaviour = [rule for rule in RULES if rule.curve == "behaviour"]
    bands = ", ".join(f"{t:.0%}" for t in sorted({rule.tolerance for rule in behaviour}))
    windows = ", ".join(str(w) for w in sorted({rule.window for rule in behaviour}))
    return [
        "SARSA against Q-Learning on the same seeds (the same start states). Each label says what the seeds "
        "show: supported (the claim's test rejects), contradicted (the test of its opposite rejects), not resolved "
        "(neither does, and more seeds, or longer runs where seeds never converged, could settle it), undecidable "
        "here (the quantity lies below its own noise floor, so more seeds will not settle it; the row gives the "
        "numbers) and no data (nothing to test, e.g. no seed converged).",
        "A direction (\"SARSA higher\", \"SARSA faster\"; for a level such as \"left from most start states\", "
        "the share against one half) is the paired difference with its 95% BCa bootstrap interval and the Wilcoxon "
        "signed-rank p: supported when p (Holm) < 0.05 and the interval excludes 0 on the "
        "claim's side, contradicted when it excludes 0 on the other side. A sameness (\"a similar time frame\", "
        "\"the same solution\") is two one-sided tests (TOST, Schuirmann 1987) against a margin declared before "
        f"any run was read: {margins}. \"About "
        f"R times\" is TOST on the per-seed log ratios with the band R/{RATIO_FACTOR:g} to R*{RATIO_FACTOR:g}. "
        "For these, p is the TOST p (the larger one-sided p) when the estimate lies inside the margin, and twice "
        "the one-sided p that it lies beyond the margin otherwise; the estimate carries its 95% t interval.",
        f"All claims of this table form one family, corrected with Holm's step-down procedure (Holm 1979) at "
        f"family-wise α = {ALPHA:g}: p is each test's own p-value, p (Holm) the adjusted one, and the labels read "
        "p (Holm). A seed that never converged counts at the last episode, a lower bound on its time: a label such "
        "a value could overturn stands only if the sign test, with every such seed at its worst (an infinite "
        "time), rejects too at the claim's place in Holm's family (the note then says so), else it is not "
        "resolved; a ratio with no converged seed on one side has no data. The censored column counts them.",
        "The first-action claims (Mountain Car) read which action the final greedy policy takes in the start "
        "region. The noise floor compares the gap between the best and second-best mean action value in those "
        "cells with the seed-to-seed standard deviation of the action values; a gap below that spread is "
        "undecidable here.",
        f"Convergence verdicts are read again under other reasonable rules: bands of {bands} crossed with windows "
        f"of {windows} episodes on the behaviour returns, and the {DEFAULT_RULE.tolerance:.0%} band on the greedy "
        "curve (the mean greedy-evaluation return of each round, smoothed over the rounds of "
        f"{DEFAULT_RULE.window} episodes, its rounds converted back to episodes). Each rule recomputes the whole "
        "family. A verdict that two rules decide opposite ways is marked fragile: the conclusion then rests on the "
        "choice of rule, not on the runs alone. A rule under which the data cannot decide is named in the row's "
        "note; the second table gives the label under each rule.",
    ]


ORDER_TEXT = (
    "Q-Learning and SARSA differ in their target and in when they draw the next action A': Q-Learning after its "
    "update, SARSA before it. On this grid the car stays in its cell for most steps, where the two orders act "
    "differently, so the study also runs Q-Learning drawing before its update and SARSA drawing after it (its "
    "target's A' drawn before the update, the action taken drawn after: docs/why.md). Per seed, SARSA - "
    "Q-Learning = order (Q-Learning before - after) + target (SARSA after - Q-Learning after) + interaction; "
    "mean over seeds with 95% BCa intervals. `rlcompare reproduce why` adds Expected SARSA's expectation target.")


def _sections(first: Results, runs: dict[str, Results], metrics: dict[str, pd.DataFrame],
              tables: dict[str, pd.DataFrame], files: dict[str, str], curve_figures: list[tuple[str, str]],
              explanation_figures: list[tuple[str, str]], video_cells: list[tuple[str, str, str]],
              aggregate_figures: list[tuple[str, str]]) -> list[Section]:
    c = first.config
    setting = pd.DataFrame({
        "setting": ["environment", "grid", "α", "γ", "episode limit", "ε constant", "ε decay", "episodes",
                    "seeds", "evaluation", "time limit"],
        "value": [c.env, _grid_text(c), c.alpha, c.gamma, c.max_steps, c.epsilon,
                  f"linear {c.epsilon_start} → {c.epsilon_end} over the first {c.decay_fraction:.0%} of episodes",
                  c.episodes, f"{len(c.seeds)} ({c.seeds[0]}..{c.seeds[-1]})",
                  f"greedy policy, {c.eval_episodes} episodes every {c.eval_every}",
                  "truncation treated as terminal" if c.truncation_as_terminal else "truncation bootstraps"],
    })
    versions = pd.DataFrame(sorted(first.meta.get("versions", {}).items()), columns=["package", "version"])
    return [
        Section("Setting", ["Configurations read: " + ", ".join(runs) + "."],
                tables=[("Configuration", setting.astype(str)), ("Versions", versions)]),
        Section("Table I: time to converge", [_table_i_text(c), *schedule_notes(runs, metrics)],
                tables=[("Table I", tables["table_i"], files["table_i"])]),
        Section("Table II: mean cumulative reward", [
            "Behaviour: the ε-greedy return averaged over every training episode of a seed. Greedy: the return "
            "of the final greedy policy. Mean and interquartile mean over seeds, 95% bootstrap intervals."],
            tables=[("Table II", tables["table_ii"], files["table_ii"])]),
        Section("Verdicts on the paper's claims", [*_verdict_text(), holm_family(tables["verdicts"])],
                tables=[("Verdicts", tables["verdicts"], files["verdicts"]),
                        ("Convergence verdicts under each rule", tables["verdict_rules"], files["verdict_rules"])]),
        Section("Learning curves (the paper's Figures 3 to 9)", figures=curve_figures),
        *([Section("The four learners as rliable draws them", [
            "Each seed's return while learning, normalised between the random baseline's mean (0) and the best "
            f"learner's mean (1), on the one task ({first.config.env}): interval estimates of the median, IQM, mean "
            "and optimality gap, the probability that a seed of one learner beats a seed of another, performance "
            "profiles and IQM learning curves, with 95% stratified bootstrap intervals (Agarwal et al. 2021)."],
            tables=[("Interval estimates", tables["aggregates"], files["aggregates"]),
                    ("Probability of improvement", tables["improvement"], files["improvement"])],
            figures=aggregate_figures)] if aggregate_figures else []),
        *([Section("Why: the target against the order of choosing A'", [ORDER_TEXT],
                   tables=[("SARSA minus Q-Learning, decomposed", tables["decomposition"],
                             files["decomposition"])])]
          if "decomposition" in tables else []),
        Section("Why: policies, values, visits and first actions", figures=explanation_figures)
        if explanation_figures else Section("Why", ["The maps over position and velocity are Mountain Car's."]),
        Section("Videos of the greedy agents at three stages of learning",
                [f"Rendered by Gymnasium's own {c.environment.gymnasium_id} renderer from the same start state: each "
                 "learner's median seed (by its final greedy return) at three stages of learning, then the final "
                 "policies of its lowest and highest seeds.", *([WATCH_FOR] if c.env == "MountainCar-v0" else [])]
                if video_cells else ["Videos were not rendered (--no-videos)."], videos=video_cells),
    ]
