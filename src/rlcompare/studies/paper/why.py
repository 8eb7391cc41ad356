"""Why does SARSA win here? A factorial that separates the on-policy target from the order of choosing.

Q-Learning (Algorithm 1) and SARSA (Algorithm 2) differ in two ways, not one: the target (the max over next
actions against the action taken next) and the order (Q-Learning draws A' after updating Q(S, A), SARSA
before). The order matters whenever S' = S, which on the paper's 20 x 20 grid is most steps: the car moves
less than a cell per step. Q-Learning that draws A' before its update is still Q-Learning (any behaviour
policy is allowed), so the order is a confound of "on- against off-policy".

Cells, per ε schedule, on the paper's setting: target (``max``: Q-Learning; ``taken``: SARSA; ``expectation``:
Expected SARSA, on-policy) x order (``before_update``, ``after_update``). SARSA's target needs A' before its
update, so its ``after_update`` cell draws the target's A' before the update and the action it takes after
(``docs/why.md``): the target is then a sample of the policy, not the action taken.

The decomposition, per seed and so paired on the same start states:

    SARSA - Q-Learning = order + target + interaction
    order       = Q-Learning(before) - Q-Learning(after)
    target      = SARSA(after) - Q-Learning(after)
    interaction = SARSA(before) - SARSA(after) - Q-Learning(before) + Q-Learning(after)

which holds exactly for every seed, so for the means too; each term has a 95% BCa interval over seeds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.algorithms.registry import AFTER_UPDATE, BEFORE_UPDATE
from rlcompare.experiment import rundir, store
from rlcompare.experiment.engines import load_run
from rlcompare.formatting import NO_DATA, number
from rlcompare.report.findings import BEHAVIOUR_AND_GREEDY, SCHEDULE_TEXT, amount, more_or_less
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.stats.design import INTERVAL
from rlcompare.stats.intervals import Estimate, interval
from rlcompare.stats.metrics import returns_per_seed
from rlcompare.studies.interface import UI, Report, run_each
from rlcompare.studies.plans import Question, StudyPlan, episodic
from rlcompare.studies.registry import WhyOptions
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results

STUDY = "why"
TARGETS = {"max": "q_learning", "taken": "sarsa", "expectation": "expected_sarsa"}
ORDERS = (BEFORE_UPDATE, AFTER_UPDATE)
SCHEDULES = ("constant", "decay")
WINDOW = 1000
"""Episodes of the "first" and "last" windows (at most half of training)."""
TERMS = {
    "SARSA - Q-Learning": ((1, "sarsa", BEFORE_UPDATE), (-1, "q_learning", AFTER_UPDATE)),
    "order": ((1, "q_learning", BEFORE_UPDATE), (-1, "q_learning", AFTER_UPDATE)),
    "target": ((1, "sarsa", AFTER_UPDATE), (-1, "q_learning", AFTER_UPDATE)),
    "interaction": ((1, "sarsa", BEFORE_UPDATE), (-1, "sarsa", AFTER_UPDATE), (-1, "q_learning", BEFORE_UPDATE),
                    (1, "q_learning", AFTER_UPDATE)),
    "expectation target": ((1, "expected_sarsa", AFTER_UPDATE), (-1, "q_learning", AFTER_UPDATE)),
    "order, expectation target": ((1, "expected_sarsa", BEFORE_UPDATE), (-1, "expected_sarsa", AFTER_UPDATE)),
}
"""Each term as a signed sum of cells (algorithm, order), per seed."""
DECOMPOSITION = ("order", "target", "interaction")
REQUIRED = tuple((algorithm, order) for algorithm in ("q_learning", "sarsa") for order in ORDERS)
"""The cells the decomposition needs: Q-Learning and SARSA, each drawing before and after its update."""
NAN = Estimate(np.nan, np.nan, np.nan)
RETURNS = {"behaviour": "behaviour (ε-greedy) return", "greedy": "greedy-policy return"}


def cell_name(config: ExperimentConfig) -> str:
    """A cell's run directory: ``sarsa-decay-after_update``."""
    return f"{config.algorithm}-{config.schedule}-{config.next_action}"


def why_configs(seeds: tuple[int, ...], episodes: int = WhyOptions.episodes) -> dict[str, ExperimentConfig]:
    """Every cell of the factorial on the paper's setting, by run directory."""
    base = ExperimentConfig(seeds=seeds, episodes=episodes)
    configs = [replace(base, algorithm=algorithm, schedule=schedule, next_action=order)
               for schedule in SCHEDULES for algorithm in TARGETS.values() for order in ORDERS]
    return {cell_name(c): c for c in configs}


def run(out: Path, options: WhyOptions, ui: UI, *, study: str = STUDY, force: bool = False
        ) -> dict[str, Results]:
    """Each cell into ``out / name``, or loaded when already complete there."""
    return run_each(out, why_configs(options.seed_range, options.episodes), ui, study=study, force=force)


def study_plan(options: WhyOptions) -> StudyPlan:
    """What the study trains and can decide: each part of SARSA - Q-Learning, read by its 95% bootstrap interval."""
    return StudyPlan(episodic(why_configs(options.seed_range, options.episodes)), (
        Question("which part of SARSA - Q-Learning (order, target, interaction) is not 0", INTERVAL, options.seeds),))


def windows(episodes: int) -> dict[str, tuple[int, int]]:
    """``[start, stop)`` episode ranges: all training, the first and the last :data:`WINDOW` episodes."""
    width = min(WINDOW, episodes // 2) or episodes
    return {"all training": (0, episodes), f"first {width}": (0, width),
            f"last {width}": (episodes - width, episodes)}


def per_seed_returns(results: Results, kind: str, start: int, stop: int) -> np.ndarray:
    """Each seed's mean return over episodes ``[start, stop)``: of the behaviour, or of the greedy policy
    evaluated after episodes in that range, the greedy curve's area there (NaN where no evaluation falls in it);
    :func:`~rlcompare.stats.metrics.returns_per_seed` on that window."""
    records, config = results.records, results.config
    after = (np.arange(config.evaluation_rounds) + 1) * config.eval_every
    rounds = (after > start) & (after <= stop)
    window = returns_per_seed(results.seeds, records.returns[:, start:stop], records.eval_returns[:, rounds])
    return window["behaviour_return" if kind == "behaviour" else "greedy_auc"].to_numpy()


def term_per_seed(cells: Mapping[tuple[str, str | None], np.ndarray], term: str) -> np.ndarray:
    """One term of :data:`TERMS`, seed by seed: ``cells`` by (algorithm, order)."""
    return np.asarray(sum(sign * cells[(algorithm, order)] for sign, algorithm, order in TERMS[term]))


def decomposition(runs: dict[str, Results]) -> pd.DataFrame:
    """One row per schedule, return and window: each term of :data:`TERMS` whose cells were run, as an
    Estimate (NaN where a cell is missing: the paper study runs the four cells of Q-Learning and SARSA, not
    Expected SARSA's). A schedule needs at least those four cells."""
    rows = []
    for schedule in SCHEDULES:
        present = {(r.config.algorithm, r.config.drawn_next): r for r in runs.values()
                   if r.config.schedule == schedule and r.config.algorithm in TARGETS.values()}
        if not set(REQUIRED) <= set(present):
            continue
        _check_paired(list(present.values()))
        episodes = next(iter(present.values())).config.episodes
        for kind in RETURNS:
            for window, (start, stop) in windows(episodes).items():
                cells = {key: per_seed_returns(r, kind, start, stop) for key, r in present.items()}
                row = {"schedule": schedule, "return": kind, "episodes": window}
                rows.append(row | {term: interval(term_per_seed(cells, term)) if _has_cells(cells, term) else NAN
                                   for term in TERMS})
    return pd.DataFrame(rows)


def _has_cells(cells: Mapping[tuple[str, str | None], np.ndarray], term: str) -> bool:
    return all((algorithm, order) in cells for _, algorithm, order in TERMS[term])


def _check_paired(runs: list[Results]) -> None:
    seeds = {tuple(r.seeds) for r in runs}
    if len(seeds) != 1:
        raise store.StoreError(f"the cells of the factorial were run on different seeds: {sorted(seeds)}")


def formatted(frame: pd.DataFrame) -> pd.DataFrame:
    """The decomposition with each Estimate as ``mean [low, high]``."""
    return frame.assign(**{term: frame[term].map(lambda e: e.format(1) if np.isfinite(e.value) else "not run")
                           for term in TERMS})


def cells_table(runs: dict[str, Results]) -> pd.DataFrame:
    """Mean return of every cell over all training (behaviour) and at the last evaluation (greedy)."""
    rows = []
    for name, results in runs.items():
        c = results.config
        final = (interval(per_seed_returns(results, "greedy", c.episodes - c.eval_every, c.episodes)).format(1)
                 if c.evaluation_rounds else NO_DATA)  # no greedy evaluation in so short a training
        rows.append({"cell": name, "schedule": c.schedule, "target": _target_of(c.algorithm),
                     "A' drawn": str(c.drawn_next).replace("_", " "),
                     "behaviour return": interval(per_seed_returns(results, "behaviour", 0, c.episodes)).format(1),
                     "final greedy return": final})
    return pd.DataFrame(rows)


def _target_of(algorithm: str) -> str:
    return next(target for target, a in TARGETS.items() if a == algorithm)


def decomposition_figure(frame: pd.DataFrame) -> Figure:
    """Bars of the total and its three parts with 95% intervals: one panel per schedule and return."""
    panels = frame.groupby(["schedule", "return"], sort=False)
    figure = Figure(figsize=(12, 3.6 * len(SCHEDULES)), layout="constrained")
    axes = figure.subplots(len(SCHEDULES), len(RETURNS), squeeze=False)
    terms = ("SARSA - Q-Learning", *DECOMPOSITION)
    colors = ("#444444", "#3b6fb6", "#2a9d8f", "#e07b00")
    for ax, ((schedule, kind), panel) in zip(axes.flat, panels, strict=False):
        x = np.arange(len(panel))
        width = 0.8 / len(terms)
        for k, (term, color) in enumerate(zip(terms, colors, strict=True)):
            estimates: list[Estimate] = list(panel[term])
            values = np.array([e.value for e in estimates])
            errors = np.array([[e.value - e.low, e.high - e.value] for e in estimates]).T
            ax.bar(x + (k - 1.5) * width, values, width, yerr=errors, color=color, label=term, capsize=2)
        ax.axhline(0, color="black", linewidth=0.8)
        ax.set_xticks(x, list(panel["episodes"]))
        ax.set_title(f"{SCHEDULE_TEXT[str(schedule)]}: {RETURNS[str(kind)]}")
        ax.set_ylabel("difference in return")
        ax.grid(alpha=0.3, axis="y")
    axes.flat[0].legend(fontsize="small")
    figure.suptitle("SARSA minus Q-Learning = order + target + interaction (paired seeds, 95% BCa intervals)")
    return figure


CAUSE_TEXT = {"order": "the order of choosing A' and updating", "target": "the target (the action taken "
              "against the max)", "interaction": "the interaction of the two"}


def findings(frame: pd.DataFrame) -> list[str]:
    """Two sentences per schedule: how large the gap is while learning and what it is made of, each part signed,
    the largest named; then the same for the greedy policies of the last window."""
    sentences = []
    for schedule in SCHEDULES:
        rows = frame[(frame["schedule"] == schedule) & (frame["return"] == "behaviour")
                     & (frame["episodes"] == "all training")]
        if rows.empty:
            continue
        row = rows.iloc[0]
        total: Estimate = row["SARSA - Q-Learning"]
        largest = max(DECOMPOSITION, key=lambda term: abs(row[term].value))
        sentences.append(
            f"With {SCHEDULE_TEXT[schedule]}, SARSA's return while learning is {more_or_less(total)} than "
            f"Q-Learning's. It is the sum of {_parts(row)}; the largest in size is {CAUSE_TEXT[largest]} "
            f"{_decided(row[largest])}.")
        greedy = frame[(frame["schedule"] == schedule) & (frame["return"] == "greedy")]
        if not greedy.empty and np.isnan(greedy.iloc[-1]["SARSA - Q-Learning"].value):
            sentences.append(f"The greedy policies of the {greedy.iloc[-1]['episodes']} episodes: no greedy "
                             "evaluation fell in them, so there is nothing to compare.")
        elif not greedy.empty:
            last = greedy.iloc[-1]
            sentences.append(f"The greedy policies of the {last['episodes']} episodes: SARSA's return is "
                             f"{more_or_less(last['SARSA - Q-Learning'])}; {CAUSE_TEXT['order']} "
                             f"{amount(last['order'], signed=True)}, {CAUSE_TEXT['target']} "
                             f"{amount(last['target'], signed=True)}.")
    return sentences


def in_brief(frame: pd.DataFrame) -> str:
    """One sentence: per schedule, the part of SARSA - Q-Learning while learning that is largest in size."""
    parts = []
    for schedule in SCHEDULES:
        rows = frame[(frame["schedule"] == schedule) & (frame["return"] == "behaviour")
                     & (frame["episodes"] == "all training")]
        if not rows.empty:
            row = rows.iloc[0]
            largest = max(DECOMPOSITION, key=lambda term: abs(row[term].value))
            value = row[largest].value
            parts.append(f"with {SCHEDULE_TEXT[schedule]}, {CAUSE_TEXT[largest]}, at {'+' if value > 0 else ''}"
                         f"{number(value)}")
    return f"Why, while learning: the largest part of the difference is, {'; '.join(parts)}." if parts else ""


def _parts(row: pd.Series) -> str:
    parts = [f"{CAUSE_TEXT[term]} {amount(row[term], signed=True)}" for term in DECOMPOSITION]
    return f"{', '.join(parts[:-1])} and {parts[-1]}"


def _decided(estimate: Estimate) -> str:
    if np.isnan(estimate.low):
        return "(no interval: too few seeds)"
    if estimate.low > 0 or estimate.high < 0:
        return "(its interval excludes 0)"
    return "(its interval includes 0: not resolved)"


def load_why(out: Path) -> tuple[dict[str, Results], list[str]]:
    """The cells of a why study whose files belong together, and a line for each that does not load."""
    runs, problems = {}, []
    for name in why_configs((0,)):
        try:
            runs[name] = load_run(Path(out) / name)
        except (OSError, ValueError, KeyError) as error:  # StoreError included
            problems.append(f"{name}: {error}")
    return runs, problems + rundir.missing_members(Path(out), [problem.split(":")[0] for problem in problems])


def report(out: Path, ui: UI | None = None, *, runs: dict[str, Results] | None = None, videos: bool = True
           ) -> Report:
    """Tables, the figure and ``report.html`` of the factorial in ``out``, from ``runs`` or its run directories
    (it draws no videos)."""
    out = Path(out)
    with store.rewriting(out, "study"):
        runs, problems = load_why(out) if runs is None else (runs, [])
        frame = decomposition(runs)
        if frame.empty:
            raise store.StoreError(f"{out}: no schedule has the four cells of Q-Learning and SARSA, each drawing "
                                   "before and after its update: " + "; ".join(problems))
        table = formatted(frame)
        cells = cells_table(runs)
        files = {name: write_table(frame, out / "tables", name) for name, frame in
                 (("decomposition", table), ("cells", cells))}
        image = save_figure(decomposition_figure(frame), out / "figures" / "decomposition.png")
        first, sentences = next(iter(runs.values())), findings(frame)
        path = write_report(out / "report.html", "Why does SARSA win on Mountain Car? Target against order", [
            Section("Findings", sentences),
            Section("Decomposition", [
                "Per seed, on the same start states: SARSA - Q-Learning = order + target + interaction, where "
                "order = Q-Learning drawing A' before its update - Q-Learning drawing it after (its box); target "
                "= SARSA drawing after - Q-Learning drawing after; interaction = what the order changes in "
                "SARSA beyond what it changes in Q-Learning. Two more rows check the target with Expected "
                "SARSA's expectation, which needs no draw. SARSA drawing after its update takes a fresh action "
                "after the update; its target's A' is drawn before it (docs/why.md). Mean over seeds with 95% "
                f"BCa bootstrap intervals; {len(first.seeds)} seeds x {first.config.episodes} episodes, the "
                "paper's setting otherwise.", BEHAVIOUR_AND_GREEDY],
                tables=[("SARSA minus Q-Learning, decomposed", table.astype(str), files["decomposition"]),
                        ("Every cell", cells, files["cells"])],
                figures=[(image, "The total and its three parts, per schedule and return")]),
        ], problems)
        return Report(path, sentences, problems)
