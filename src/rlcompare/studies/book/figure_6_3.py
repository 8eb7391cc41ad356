"""Sutton and Barto's Figure 6.3 (after van Seijen et al. 2009): SARSA, Expected SARSA and Q-Learning on Cliff
Walking against the step size α, at the book's run counts.

- interim: the mean return per episode over the first 100 episodes, averaged over 50,000 runs;
- asymptotic: the mean return per episode over 100,000 episodes, averaged over 10 runs;

for α = 0.1, 0.2, ..., 1.0, on Gymnasium's ``CliffWalking-v1`` (the table the ``cliff`` study steps), ε = 0.1,
γ = 1, Q starting at 0, greedy ties broken at random. Every configuration of a phase runs the same seeds
(common random numbers), so every comparison is paired.

A run directory per (phase, method, α) holds what the figure and the verdicts read, not every episode
(``docs/algorithms.md``): ``runs.parquet``, one row per run with its mean return per episode, its steps and
the episodes the step limit cut; ``qtables.npz``, the final Q-table of each asymptotic run; ``config.json`` and
``meta.json`` as in every run directory. 50,000 runs x 100 episodes would be 5 million rows per configuration,
150 million for the phase, written and read back in minutes, where the study itself takes about that.
"""

from __future__ import annotations

import dataclasses
import functools
import io
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.algorithms.registry import label as method_label
from rlcompare.experiment import rundir, store
from rlcompare.experiment.runner import run
from rlcompare.formatting import cut, number
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.stats.design import T_TEST
from rlcompare.stats.intervals import Estimate, interval, mean_interval
from rlcompare.stats.significance import ALPHA
from rlcompare.stats.verdicts import Claim, judge, margin_text
from rlcompare.studies.margins import margin
from rlcompare.studies.plans import Question
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.memory import run_bytes

ENV = "CliffWalking-v1"
METHODS = ("sarsa", "expected_sarsa", "q_learning")
ALPHAS = tuple(round(k / 10, 1) for k in range(1, 11))
PHASES = ("interim", "asymptotic")
INTERIM_EPISODES, INTERIM_RUNS = 100, 50_000
ASYMPTOTIC_EPISODES, ASYMPTOTIC_RUNS = 100_000, 10
MAX_STEPS = 1_000_000
"""The book gives no step limit; none of our episodes comes near this one (the report counts those cut)."""
SETTINGS: dict[str, Any] = {"env": ENV, "schedule": "constant", "epsilon": 0.1, "gamma": 1.0, "max_steps": MAX_STEPS,
                            "eval_every": 0}
STAGES = {"interim": (), "asymptotic": (("final", 1.0),)}
"""Q-tables kept: none of the 50,000 interim runs, the final one of each asymptotic run."""
BLOCK_BYTES = 32 * 2**20
"""Runs are trained in blocks that take at most this much memory while they train (at least one run a block,
:func:`run_bytes`), and summarised before the next block: memory stays bounded whatever the runs and episodes."""
BOOTSTRAP_RUNS = 500
"""Intervals over more runs than this are Student t intervals (:func:`mean_interval`), fewer the bootstrap's."""

NONINFERIORITY_MARGIN = margin("book 6.3", "Expected SARSA at least as good as SARSA")
"""Expected SARSA is 'at least as good' as SARSA where its mean return per episode is above SARSA's minus this."""
COLLAPSE_MARGIN = margin("book 6.3", "an asymptote collapses")
"""An asymptote 'collapses' from α = 0.1 to α = 1.0 when it falls by more than this (return per episode)."""

RUNS_FILE = "runs.parquet"
RETURN = "return"
"""What every claim reads: a run's mean return per episode (a column of ``runs.parquet``)."""
CONTENT_FILES = (rundir.CONFIG_FILE, RUNS_FILE, rundir.QTABLES_FILE)
RUN_FILES = (*CONTENT_FILES, rundir.META_FILE)
COLOURS = {"sarsa": "tab:blue", "expected_sarsa": "tab:red", "q_learning": "black"}
"""The book's colours."""
FLOOR = -160.0
"""The bottom of the book's axis; points below it are drawn off the axis, their values written at its edge."""


def run_name(phase: str, method: str, alpha: float) -> str:
    return f"{phase}-{method}-alpha-{alpha:g}"


def asymptotic_runs(runs: int) -> int:
    """Asymptotic runs for ``runs`` interim runs: the book's 10 for its 50,000, scaled (at least 2 where there
    are 2, so that paired differences have a spread)."""
    return max(min(runs, 2), round(runs * ASYMPTOTIC_RUNS / INTERIM_RUNS))


def configs(seeds: tuple[int, ...], episodes: int = ASYMPTOTIC_EPISODES) -> dict[str, ExperimentConfig]:
    """Every (phase, method, α): the interim phase runs ``seeds``, the asymptotic phase the first of them for
    ``episodes``."""
    phases = {"interim": (tuple(seeds), INTERIM_EPISODES),
              "asymptotic": (tuple(seeds)[:asymptotic_runs(len(seeds))], episodes)}
    return {run_name(phase, method, alpha): ExperimentConfig(
        algorithm=method, alpha=alpha, episodes=episodes, seeds=phase_seeds, stages=STAGES[phase], **SETTINGS)
        for phase, (phase_seeds, episodes) in phases.items() for method in METHODS for alpha in ALPHAS}


def phase_of(config: ExperimentConfig) -> str:
    return "asymptotic" if config.stages else "interim"


# --- a run directory: what the figure needs ----------------------------------------------------------------


@dataclasses.dataclass
class PhaseRuns:
    """One configuration's runs, each summarised: its mean return per episode, steps and episodes cut."""

    content_files: ClassVar[tuple[str, ...]] = CONTENT_FILES
    """The files of its run directory beside ``meta.json``."""

    config: ExperimentConfig
    runs: pd.DataFrame
    """One row per seed: ``seed``, ``return`` (mean per episode), ``steps``, ``cut`` (episodes cut by the limit)."""
    q_tables: np.ndarray
    """(runs, stages, states, actions) Q-tables at the configuration's stages (none for the interim phase)."""
    meta: dict[str, Any]

    @property
    def seeds(self) -> tuple[int, ...]:
        return self.config.seeds

    @property
    def returns(self) -> np.ndarray:
        return self.runs["return"].to_numpy()

    def save(self, run_dir: Path) -> Path:
        """Write the run directory (:func:`~rlcompare.experiment.rundir.write_run`)."""
        arrays = io.BytesIO()
        np.savez_compressed(arrays, snapshots=self.q_tables, seeds=np.asarray(self.seeds))
        table = io.BytesIO()
        self.runs.to_parquet(table, index=False)
        timings = self.meta["timings"]
        timings["finished"] = time.time()
        timings["summary_seconds"] = timings["finished"] - timings.get("trained", timings["finished"])
        return rundir.write_run(run_dir, self.config.to_dict(), {RUNS_FILE: table.getvalue(),
                                                                 rundir.QTABLES_FILE: arrays.getvalue()},
                                self.meta, {"seeds": list(self.seeds), "rows": {"runs": len(self.runs)}})

    @classmethod
    def load(cls, run_dir: Path, expected: ExperimentConfig | None = None) -> PhaseRuns:
        """Read a finished run directory back, after checking that its files belong together (and hold
        ``expected`` where given); anything else is a :class:`~rlcompare.experiment.store.StoreError`."""
        run_dir = Path(run_dir)
        meta, data = rundir.read_run(run_dir, cls.content_files, None if expected is None else expected.to_dict())
        try:
            data["seeds"], data["stages"] = tuple(data["seeds"]), tuple(tuple(s) for s in data["stages"])
            config = ExperimentConfig.from_dict(data)
            runs = pd.read_parquet(run_dir / RUNS_FILE)
            with np.load(run_dir / rundir.QTABLES_FILE, allow_pickle=False) as arrays:
                q_tables, seeds = arrays["snapshots"], arrays["seeds"].tolist()
        except (ValueError, KeyError, OSError) as error:
            raise store.StoreError(f"{run_dir}: cannot read the stored runs ({cut(str(error), 200)})") from None
        if runs["seed"].tolist() != list(config.seeds) or seeds != list(config.seeds):
            raise store.StoreError(f"{run_dir}: the runs stored are not those of {rundir.CONFIG_FILE}")
        return cls(config, runs, q_tables, meta)


def block_runs(config: ExperimentConfig) -> int:
    """Runs trained at once: as many as fit in :data:`BLOCK_BYTES` (:func:`run_bytes`), at least one."""
    return max(1, min(len(config.seeds), BLOCK_BYTES // run_bytes(config)))


def summarise(config: ExperimentConfig, study: str = "", progress: Callable[[float], None] | None = None
              ) -> PhaseRuns:
    """Train every seed of ``config``, a block of runs at a time (:func:`block_runs`), keeping of each run its
    mean return per episode, steps and episodes cut, and its Q-tables at the configuration's stages."""
    started, size = time.time(), block_runs(config)
    parts, q_tables, meta, wall, compiled, steps = [], [], {}, 0.0, 0.0, 0
    for first in range(0, len(config.seeds), size):
        block = config.seeds[first:first + size]
        share = functools.partial(_scaled, progress, len(block) / len(config.seeds)) if progress else None
        results = run(dataclasses.replace(config, seeds=block), study=study, progress=share)
        records = results.records
        parts.append(pd.DataFrame({"seed": np.asarray(block, dtype=np.int64),
                                   "return": records.returns.mean(axis=1),
                                   "steps": records.lengths.sum(axis=1),
                                   "cut": (~records.terminated).sum(axis=1)}))
        q_tables.append(records.snapshots)
        meta, timings = results.meta, results.meta["timings"]
        wall += timings["wall_seconds"]
        compiled += timings["compile_seconds"]
        steps += timings["training_steps"]
        del results, records  # before the next block's are allocated
    meta["seeds"] = list(config.seeds)
    meta["timings"] = {**meta["timings"], "wall_seconds": wall, "compile_seconds": compiled, "training_steps": steps,
                       "steps_per_second": steps / wall if wall > 0 else None, "blocks": len(parts),
                       "block_runs": size, "started": started, "trained": time.time()}
    return PhaseRuns(config, pd.concat(parts, ignore_index=True), np.concatenate(q_tables), meta)


def _scaled(progress: Callable[[float], None], share: float, episodes: int) -> None:
    progress(episodes * share)


def train(config: ExperimentConfig, *, out: Path | None = None, study: str = "",
          progress: Callable[[float], None] | None = None, force: bool = False) -> PhaseRuns:
    """:func:`summarise` into the run directory ``out`` where given (``run_or_load``'s ``train``; ``force``: beside
    files rlcompare did not write)."""
    if out is None:
        return summarise(config, study, progress)
    with store.output_directory(Path(out), store.RUN, force=force):
        runs = summarise(config, study, progress)
        runs.save(out)
    return runs


# --- the book's claims, as verdicts on paired runs ---------------------------------------------------------


def claims() -> list[Claim]:
    """The book's claims on Figure 6.3, each on the mean return per episode of paired runs (A - B), with margins
    fixed before any run was looked at:

    - Expected SARSA is at least as good as SARSA (within :data:`NONINFERIORITY_MARGIN`) at every α, interim
      and asymptotic;
    - SARSA's asymptote collapses at large α (falls by more than :data:`COLLAPSE_MARGIN` from α = 0.1 to 1.0),
      Expected SARSA's does not (falls by less);
    - Q-Learning's online return is the worst asymptotically: below SARSA's and Expected SARSA's at every α.
    """
    found = [Claim(f"Expected SARSA at least as good as SARSA, {phase}, α = {alpha:g}",
                   run_name(phase, "expected_sarsa", alpha), run_name(phase, "sarsa", alpha), RETURN, "within",
                   bounds=(-NONINFERIORITY_MARGIN, np.inf), about="Expected SARSA - SARSA")
             for phase in PHASES for alpha in ALPHAS]
    low, high = ALPHAS[0], ALPHAS[-1]
    for method, bounds, text in (("sarsa", (COLLAPSE_MARGIN, np.inf), "SARSA's asymptotic return collapses"),
                                 ("expected_sarsa", (-np.inf, COLLAPSE_MARGIN),
                                  "Expected SARSA's asymptotic return does not collapse")):
        found.append(Claim(f"{text} at large α", run_name("asymptotic", method, low),
                           run_name("asymptotic", method, high), RETURN, "within", bounds=bounds,
                           about=f"{method_label(method)}, α = {low:g} - α = {high:g}"))
    found += [Claim(f"Q-Learning's asymptotic return below {method_label(other)}'s, α = {alpha:g}",
                    run_name("asymptotic", "q_learning", alpha), run_name("asymptotic", other, alpha), RETURN,
                    "within", bounds=(-np.inf, 0.0), about=f"Q-Learning - {method_label(other)}")
              for other in ("sarsa", "expected_sarsa") for alpha in ALPHAS]
    return found


def questions(found: dict[str, ExperimentConfig]) -> tuple[Question, ...]:
    """The book's claims, one family of t tests on the runs of the phase that has fewest."""
    runs = min(len(config.seeds) for config in found.values())
    return (Question(f"the book's {len(claims())} claims on Figure 6.3", T_TEST, runs, len(claims())),)


def verdicts(found: list[Claim], runs: dict[str, PhaseRuns]) -> pd.DataFrame:
    """Each claim tested by one-sided t tests against its margin (:func:`~rlcompare.stats.significance.tost` with one
    bound infinite), Holm-corrected across the whole family (:func:`~rlcompare.stats.verdicts.judge`): supported
    where the mean lies on the claimed side of the margin at the family-wise level, contradicted where it lies on
    the other side, else not resolved."""
    judged = judge(found, {name: r.runs for name, r in runs.items()}, episodes=0)
    return pd.DataFrame({
        "claim": judged["claim"], "reads": [c.about for c in found], "runs": [len(runs[c.a].seeds) for c in found],
        "mean [95% t interval]": judged["estimate"], "holds where": [margin_text(c.bounds) for c in found],
        "p (Holm)": [number(p, 2) for p in judged["p (Holm)"]], "verdict": judged["verdict"]})


# --- the report -------------------------------------------------------------------------------------------


def point(values: np.ndarray) -> Estimate:
    """The mean over runs with its 95% interval: the bootstrap's (BCa) for up to :data:`BOOTSTRAP_RUNS` runs,
    Student's t beyond."""
    return interval(values) if len(values) <= BOOTSTRAP_RUNS else mean_interval(values)


def numbers(runs: dict[str, PhaseRuns]) -> pd.DataFrame:
    """One row per (phase, method, α): runs, episodes, the mean return per episode with its interval."""
    rows = []
    for phase in PHASES:
        for method in METHODS:
            for alpha in ALPHAS:
                found = runs[run_name(phase, method, alpha)]
                estimate = point(found.returns)
                rows.append({"phase": phase, "method": method, "α": alpha, "runs": len(found.seeds),
                             "episodes": found.config.episodes, "mean": estimate.value, "low": estimate.low,
                             "high": estimate.high, "episodes cut": int(found.runs["cut"].sum())})
    return pd.DataFrame(rows)


def figure_6_3(table: pd.DataFrame) -> Figure:
    """Return per episode against α, a line per method and phase (dashed: interim), with 95% error bars."""
    figure = Figure(figsize=(8, 5.5), layout="constrained")
    ax = figure.subplots()
    for phase, style, marker in (("asymptotic", "-", "o"), ("interim", "--", "s")):
        for method in METHODS:
            rows = table[(table["phase"] == phase) & (table["method"] == method)]
            error = np.nan_to_num(np.array([rows["mean"] - rows["low"], rows["high"] - rows["mean"]]))
            ax.errorbar(rows["α"], rows["mean"], yerr=error, linestyle=style, marker=marker, capsize=3,
                        color=COLOURS[method], markerfacecolor="white" if phase == "interim" else COLOURS[method],
                        label=f"{method_label(method)} ({phase})")
    ax.set_xlabel("α (step size)")
    ax.set_ylabel("sum of rewards per episode")
    ax.set_xticks(ALPHAS)
    ax.set_ylim(FLOOR, 0)
    for row in table[table["mean"] < FLOOR].itertuples():
        colour = COLOURS[str(row.method)]
        ax.annotate(f"{row.mean:.0f}", (row.α, FLOOR), xytext=(0, 12), textcoords="offset points", ha="center",
                    fontsize="small", color=colour, arrowprops={"arrowstyle": "->", "color": colour})
    ax.grid(alpha=0.3)
    ax.legend(loc="lower center", fontsize="small", ncol=2)
    interim, asymptotic = (table[table["phase"] == phase].iloc[0] for phase in PHASES)
    figure.suptitle(f"Cliff Walking, ε = 0.1: interim ({interim['episodes']:,} episodes, {interim['runs']:,} runs) "
                    f"and asymptotic ({asymptotic['episodes']:,} episodes, {asymptotic['runs']:,} runs)\n"
                    "(Sutton and Barto, Figure 6.3; bars: 95% intervals)", fontsize="medium")
    return figure


def wide_table(table: pd.DataFrame) -> pd.DataFrame:
    """The figure's numbers, a row per α and a column per method and phase: mean [95% interval]."""
    cells = table.assign(column=[f"{method_label(m)}, {p}" for m, p in zip(table["method"], table["phase"],
                                                                            strict=True)],
                         cell=[Estimate(v, lo, hi).format(1) for v, lo, hi in zip(table["mean"], table["low"],
                                                                                    table["high"], strict=True)])
    wide = cells.pivot(index="α", columns="column", values="cell")
    order = [f"{method_label(m)}, {p}" for p in PHASES for m in METHODS]
    return wide[order].rename_axis(columns=None).reset_index()


def timing_table(runs: dict[str, PhaseRuns]) -> tuple[pd.DataFrame, float | None]:
    """Per phase: configurations, runs, episodes, steps and seconds; and the study's wall time, from the first
    run's start to the last run's end (None where a run directory does not say)."""
    rows, starts, ends = [], [], []
    for phase in PHASES:
        chosen = [r for r in runs.values() if phase_of(r.config) == phase]
        timings = [r.meta.get("timings", {}) for r in chosen]
        starts += [t.get("started") for t in timings]
        ends += [t.get("finished") for t in timings]
        rows.append({"phase": phase, "configurations": len(chosen), "runs each": len(chosen[0].seeds),
                     "episodes per run": chosen[0].config.episodes,
                     "steps": f"{sum(t.get('training_steps', 0) for t in timings):,}",
                     "training (s)": round(sum(t.get("wall_seconds", 0.0) for t in timings), 1),
                     "compiling or loading (s)": round(sum(t.get("compile_seconds", 0.0) for t in timings), 1),
                     "summarising and writing (s)": round(sum(t.get("summary_seconds", 0.0) for t in timings), 1),
                     "threads": max(t.get("threads", 1) for t in timings)})
    known = None not in starts and None not in ends
    return pd.DataFrame(rows), (max(ends) - min(starts)) if known else None


def report_6_3(out: Path, runs: dict[str, PhaseRuns]) -> Path:
    """The figure, its numbers, the book's claims as verdicts and the study's wall time, in ``report.html``."""
    started = time.perf_counter()
    out = Path(out)
    table = numbers(runs)
    image = save_figure(figure_6_3(table), out / "figures" / "fig6_3.png")
    table_file = write_table(table, out / "tables", "fig6_3")
    judged = verdicts(claims(), runs)
    verdicts_file = write_table(judged, out / "tables", "verdicts")
    timing, wall = timing_table(runs)
    interim, asymptotic = timing.iloc[0], timing.iloc[1]
    counts = (f"{interim['runs each']:,} runs x {interim['episodes per run']:,} episodes (interim) and "
              f"{asymptotic['runs each']:,} runs x {asymptotic['episodes per run']:,} episodes (asymptotic), "
              f"for each of {len(METHODS)} methods x {len(ALPHAS)} step sizes")
    wall_text = (f"The study took {wall:.0f} s of wall time ({wall / 60:.1f} min), from the first run's start to the "
                 "last run's end" if wall is not None else "The run directories do not say when they ran")
    cut = int(table["episodes cut"].sum())
    tally = judged["verdict"].value_counts()
    return write_report(out / "report.html", "Figure 6.3: SARSA, Expected SARSA and Q-Learning on Cliff Walking", [
        Section("Interim and asymptotic return against the step size", [
            f"{ENV}, ε-greedy with ε = 0.1 (ties broken at random), γ = 1, Q starting at 0, constant α. Interim: "
            f"the mean return per episode over the first {interim['episodes per run']:,} episodes of a run; "
            f"asymptotic: over {asymptotic['episodes per run']:,} episodes; each point the mean over runs with its "
            f"95% interval (Student's t over more than {BOOTSTRAP_RUNS} runs, the bootstrap's otherwise). "
            f"Runs: {counts}; the same seeds for every method and α, so comparisons are paired.",
            "The book (after van Seijen et al. 2009) shows Expected SARSA above SARSA at every α, both interim "
            "and asymptotic; SARSA's asymptotic performance falling at large α while Expected SARSA's, in this "
            "deterministic world, stays near its best up to α = 1; and Q-Learning's online return the lowest "
            "asymptotically (about -50: it learns the edge path and falls off while exploring), against about "
            "-20 to -25 for the safe path of the on-policy methods.",
            f"Episodes cut by the step limit ({MAX_STEPS:,} steps; the book has none): {cut}."],
            tables=[("Mean return per episode [95% interval]", wide_table(table), table_file)],
            figures=[(image, "Figure 6.3, redrawn: solid asymptotic, dashed interim; the axis stops at -160 as the "
                             "book's does, and the value of a point below it is written at its edge")]),
        Section("The book's claims, on paired runs", [
            f"Margins fixed before the runs: Expected SARSA is at least as good as SARSA where its mean return is "
            f"above SARSA's minus {NONINFERIORITY_MARGIN:g}; an asymptote collapses when it falls by more than "
            f"{COLLAPSE_MARGIN:g} from α = 0.1 to α = 1; Q-Learning is the worst where it is below the other "
            "method at all. Each claim is a one-sided t test of the paired per-run differences against its "
            f"margin, Holm-corrected across all {len(judged)} claims at {ALPHA:g}. "
            + ", ".join(f"{n} {v}" for v, n in tally.items()) + "."],
            tables=[("Verdicts", judged, verdicts_file)]),
        Section("Run counts and wall time", [
            f"{wall_text}; the report took {time.perf_counter() - started:.1f} s more. The book's run counts "
            "are what the usual Python reproductions cut by 10 to 100 times."],
            tables=[("Runs and seconds, per phase", timing)]),
    ], [])
