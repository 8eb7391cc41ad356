"""Sutton and Barto's results, reproduced as studies: Mountain Car with tile coding, and Cliff Walking.

- ``book-10.2``: semi-gradient SARSA with 8 tilings of 8 x 8 tiles, ε = 0 (the zero start is optimistic),
  γ = 1, α = 0.1/8, 0.2/8, 0.5/8: steps per episode over 500 episodes (Figure 10.2).
- ``book-12.10``: SARSA(λ) with replacing traces, the same features, λ = 0, 0.5, 0.9, 0.95, 0.99 over a range
  of α: steps per episode averaged over the first 50 episodes (Figure 12.10).

Both use ``MountainCar-book`` (Example 10.1: Gymnasium's dynamics, position bounded at the goal, 0.5; the
tiles span [-1.2, 0.5] x [-0.07, 0.07]). The book gives no step limit; episodes are cut at 10,000 steps,
which only the worst step sizes of Figure 12.10 reach.

- ``cliff``: Example 6.6 (Figure 6.4) on Gymnasium's ``CliffWalking-v1``: SARSA, Q-Learning and Expected
  SARSA with ε = 0.1, α = 0.5, γ = 1, 500 episodes, 50 runs. The book's contrast with the paper: on the
  cliff Q-Learning learns the optimal edge path (return -13) but falls off while exploring, so SARSA,
  which learns the safe path, collects more reward online.
- ``book-6.3``: Figure 6.3 on the same table: SARSA, Expected SARSA and Q-Learning against α, interim (100
  episodes x 50,000 runs) and asymptotic (100,000 episodes x 10 runs); :mod:`rlcompare.studies.book.figure_6_3`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from rlcompare.algorithms.registry import label as method_label
from rlcompare.envs.registry import table_of
from rlcompare.envs.table import TableEnv
from rlcompare.experiment import store
from rlcompare.experiment.engines import load_run
from rlcompare.report import plots
from rlcompare.report.findings import BEHAVIOUR_AND_GREEDY
from rlcompare.report.page import Section, save_figure, write_report
from rlcompare.stats.curves import mean_band
from rlcompare.stats.design import SIGNED_RANK
from rlcompare.stats.intervals import interval
from rlcompare.studies.book import figure_6_3 as book_6_3
from rlcompare.studies.book.contrast import contrast_table, sibling_studies
from rlcompare.studies.interface import UI, Report, Seeded, run_each
from rlcompare.studies.plans import Question, StudyPlan, episodic
from rlcompare.tabular.config import ExperimentConfig
from rlcompare.tabular.results import Results

BOOK: dict[str, Any] = {"env": "MountainCar-book", "features": "tiles", "tilings": 8, "tiles": 8,
                        "schedule": "constant", "epsilon": 0.0, "gamma": 1.0, "max_steps": 10_000, "eval_every": 0,
                        "stages": (("final", 1.0),)}
FIG_10_2_ALPHAS = (0.1, 0.2, 0.5)  # times 1/8
FIG_12_10_LAMBDAS = (0.0, 0.5, 0.9, 0.95, 0.99)
FIG_12_10_ALPHAS = (0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4)  # times 1/8
FIG_12_10_EPISODES = 50


@dataclass(frozen=True)
class BookStudy:
    """A set of the book's configurations, each run into its own directory, and how to report them."""

    configs: Callable[..., dict[str, ExperimentConfig]]
    """``configs(seeds, **options)``: every configuration by run directory; ``options`` are the study's beyond its
    seeds (:mod:`rlcompare.studies.registry`)."""
    draw: Callable[[Path, dict[str, Any]], Path]
    """Writes the report of the runs into the study's directory."""
    train: Callable[..., Any] | None = None
    """Trains a configuration into its run directory in place of its engine (``run_or_load``'s ``train``), with
    ``load`` (``load(run_dir, expected=None)``) that reads what it writes."""
    load: Callable[..., Any] | None = None
    questions: Callable[[dict[str, ExperimentConfig]], tuple[Question, ...]] = lambda configs: ()
    """The tests its report makes of these configurations; none where it only draws the book's figure."""

    def configs_of(self, options: Seeded) -> dict[str, ExperimentConfig]:
        extra = {f.name: getattr(options, f.name) for f in dataclasses.fields(options)
                 if f.name not in ("seeds", "first_seed")}
        return self.configs(options.seed_range, **extra)

    def study_plan(self, options: Seeded) -> StudyPlan:
        """What the study trains and the tests its report makes."""
        configs = self.configs_of(options)
        return StudyPlan(episodic(configs, memory_checked=self.train is None), self.questions(configs))

    def run(self, out: Path, options: Seeded, ui: UI, *, study: str, force: bool = False) -> dict[str, Any]:
        """Each configuration into ``out / name``, or loaded when already complete there."""
        return run_each(out, self.configs_of(options), ui, study=study, force=force, train=self.train,
                        load=self.load)

    def report(self, out: Path, ui: UI | None = None, *, runs: dict[str, Any] | None = None, videos: bool = True
               ) -> Report:
        """The study's report in ``out``, from ``runs`` or, without them, from its run directories (it draws no
        videos)."""
        out = Path(out)
        with store.rewriting(out, "study"):
            if runs is None:
                runs = {name: (self.load or load_run)(out / name) for name in self.configs((0,))}
            return Report(self.draw(out, runs))


def fig_10_2_configs(seeds: tuple[int, ...]) -> dict[str, ExperimentConfig]:
    return {f"alpha-{a:g}of8": ExperimentConfig(algorithm="sarsa", alpha=a / 8, episodes=500, seeds=seeds, **BOOK)
            for a in FIG_10_2_ALPHAS}


def fig_12_10_configs(seeds: tuple[int, ...]) -> dict[str, ExperimentConfig]:
    return {f"lambda-{lam:g}-alpha-{a:g}of8": ExperimentConfig(
        algorithm="sarsa_lambda", lam=lam, trace="replacing", alpha=a / 8, episodes=FIG_12_10_EPISODES,
        seeds=seeds, **BOOK) for lam in FIG_12_10_LAMBDAS for a in FIG_12_10_ALPHAS}


def report_10_2(out: Path, runs: dict[str, Results]) -> Path:
    """Figure 10.2: mean steps per episode (log scale) with 95% bands, one line per step size."""
    figure = Figure(figsize=(7.5, 5), layout="constrained")
    ax = figure.subplots()
    rows = []
    for results in runs.values():
        lengths = results.records.lengths.astype(np.float64)
        mean, low, high = mean_band(lengths)
        episodes = np.arange(1, lengths.shape[1] + 1)
        (line,) = ax.plot(episodes, mean, label=f"α = {results.config.alpha * 8:g}/8")
        ax.fill_between(episodes, low, high, color=line.get_color(), alpha=0.25, linewidth=0)
        rows.append({"α": f"{results.config.alpha * 8:g}/8", "seeds": len(results.seeds),
                     "first episode": interval(lengths[:, 0]).format(0),
                     "episodes 1-50": interval(lengths[:, :50].mean(axis=1)).format(0),
                     "episodes 451-500": interval(lengths[:, -50:].mean(axis=1)).format(0)})
    ax.set_yscale("log")
    ax.set_xlabel("episode")
    ax.set_ylabel("steps per episode (log scale)")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    figure.suptitle("Semi-gradient SARSA, 8 tilings, Mountain Car (Sutton and Barto, Figure 10.2)")
    image = save_figure(figure, Path(out) / "figures" / "fig10_2.png")
    table = pd.DataFrame(rows)
    return write_report(Path(out) / "report.html", "Figure 10.2: semi-gradient SARSA on Mountain Car", [
        Section("Steps per episode", [
            "MountainCar-book, 8 tilings of 8 x 8 tiles with asymmetric offsets, ε = 0, γ = 1, weights start at "
            "0. Mean over seeds with 95% bootstrap intervals. The book shows about 1000 steps in the first "
            "episodes falling to about 150-200 by episode 500, fastest for α = 0.5/8."],
            tables=[("Steps per episode", table)], figures=[(image, "Figure 10.2, redrawn")]),
    ], [])


def report_12_10(out: Path, runs: dict[str, Results]) -> Path:
    """Figure 12.10: steps per episode averaged over the first 50 episodes, against α x 8, per λ."""
    figure = Figure(figsize=(7.5, 5), layout="constrained")
    ax = figure.subplots()
    rows = []
    for lam in FIG_12_10_LAMBDAS:
        chosen = [r for r in runs.values() if r.config.lam == lam]
        if not chosen:
            continue
        alphas = np.array([r.config.alpha * 8 for r in chosen])
        estimates = [interval(r.records.lengths[:, :FIG_12_10_EPISODES].mean(axis=1)) for r in chosen]
        ax.errorbar(alphas, [e.value for e in estimates], yerr=np.array(
            [[e.value - e.low for e in estimates], [e.high - e.value for e in estimates]]), marker="o",
            capsize=3, label=f"λ = {lam:g}")
        rows += [{"λ": lam, "α x 8": a, "mean steps per episode": e.format(0)} for a, e in zip(alphas, estimates,
                                                                                                 strict=True)]
    ax.set_xlabel("α x number of tilings (8)")
    ax.set_ylabel(f"steps per episode, averaged over the first {FIG_12_10_EPISODES} episodes")
    ax.set_ylim(top=min(ax.get_ylim()[1], 600))
    ax.legend()
    ax.grid(alpha=0.3)
    figure.suptitle("SARSA(λ) with replacing traces on Mountain Car (Sutton and Barto, Figure 12.10)")
    image = save_figure(figure, Path(out) / "figures" / "fig12_10.png")
    return write_report(Path(out) / "report.html", "Figure 12.10: SARSA(λ) on Mountain Car", [
        Section("Early performance against the step size", [
            "MountainCar-book, 8 tilings, replacing traces, ε = 0, γ = 1. The book finds intermediate λ best "
            "(about 0.9), with a best α that shrinks as λ grows, and large α making high λ diverge."],
            tables=[("Mean steps per episode over the first 50 episodes", pd.DataFrame(rows))],
            figures=[(image, "Figure 12.10, redrawn")]),
    ], [])


CLIFF: dict[str, Any] = {"env": "CliffWalking-v1", "schedule": "constant", "epsilon": 0.1, "alpha": 0.5,
                         "gamma": 1.0, "episodes": 500, "max_steps": 1000, "eval_every": 500, "eval_episodes": 1,
                         "stages": (("final", 1.0),)}
CLIFF_ALGORITHMS = ("sarsa", "q_learning", "expected_sarsa")
CLIFF_SHAPE = (4, 12)
"""Rows and columns of Gymnasium's Cliff Walking grid, for drawing; the cliff is the bottom row between the
start and the goal."""


def cliff_configs(seeds: tuple[int, ...]) -> dict[str, ExperimentConfig]:
    return {name: ExperimentConfig(algorithm=name, seeds=seeds, **CLIFF) for name in CLIFF_ALGORITHMS}


def greedy_path(q_table: np.ndarray, table: TableEnv | None = None, limit: int = 100) -> list[int]:
    """States visited by the greedy policy (first maximum) from the start until the episode ends or ``limit``
    steps, stepped through ``table`` (default: Gymnasium's Cliff Walking, whose moves are deterministic)."""
    table = table_of("CliffWalking-v1") if table is None else table
    state = int(np.argmax(table.start > 0))
    path = [state]
    for _ in range(limit):
        action = int(np.argmax(q_table[state]))
        state, ends = int(table.next_state[state, action, 0]), bool(table.ends[state, action, 0])
        path.append(state)
        if ends:
            break
    return path


def report_cliff(out: Path, runs: dict[str, Results]) -> Path:
    """Online return per episode with bands (Figure 6.4), greedy paths on the grid, and a table."""
    figure = Figure(figsize=(12, 4.5), layout="constrained")
    curves_ax, paths_ax = figure.subplots(1, 2, width_ratios=(1.2, 1))
    paths_ax.imshow(_cliff_mask(), cmap="Greys", vmin=0, vmax=1.5, origin="upper")
    rows = []
    for offset, (name, results) in enumerate(runs.items()):
        label = method_label(name)
        returns = results.records.returns
        plots.plot_return_curves(curves_ax, np.arange(1, returns.shape[1] + 1), {label: returns}, window=10)
        line = curves_ax.get_lines()[-1]
        path = greedy_path(results.records.snapshots[0, -1])
        cols = [p % 12 + (offset - 1) * 0.12 for p in path]
        paths_ax.plot(cols, [p // 12 + (offset - 1) * 0.12 for p in path], color=line.get_color(), linewidth=2,
                      label=label)
        greedy, reached = results.records.eval_returns[:, -1, 0], results.records.eval_terminated[:, -1, 0]
        rows.append({"method": label, "seeds": len(results.seeds),
                     "online return, last 100 episodes": interval(returns[:, -100:].mean(axis=1)).format(1),
                     "greedy return of the final policy": interval(greedy).format(1),
                     "seeds whose greedy path is optimal (-13)": f"{int(np.sum(greedy == -13))} of {len(greedy)}",
                     "seeds whose greedy path reaches the goal": f"{int(reached.sum())} of {len(greedy)}"})
    curves_ax.set_ylim(-100, 0)
    curves_ax.set_xlabel("episode")
    curves_ax.set_ylabel("sum of rewards during episode (10-episode mean)")
    curves_ax.legend(loc="lower right")
    curves_ax.grid(alpha=0.3)
    paths_ax.set_title("greedy path of the first seed (cliff shaded)")
    paths_ax.set_xticks(range(12))
    paths_ax.set_yticks(range(4))
    paths_ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize="small")
    figure.suptitle("Cliff Walking, ε = 0.1, α = 0.5 (Sutton and Barto, Example 6.6 and Figure 6.4)")
    image = save_figure(figure, Path(out) / "figures" / "cliff.png")
    return write_report(Path(out) / "report.html", "Example 6.6: Cliff Walking", [
        Section("SARSA against Q-Learning where the optimal path is dangerous", [
            "Gymnasium's CliffWalking-v1 (stepping into the cliff costs -100 and sends the agent back to the "
            "start without ending the episode), ε-greedy with ε = 0.1, α = 0.5, γ = 1, 500 episodes. The paper "
            "found SARSA better on Mountain Car and explained it by the kind of problem; here the book's "
            "contrast: Q-Learning learns the optimal edge path but falls off while exploring, so its online "
            "return is lower, while SARSA learns a safer path. With a constant α = 0.5 SARSA's values keep moving, "
            "and in some seeds its final greedy policy steps back and forth between two states of nearly equal "
            "value until the 1000-step limit (return -1000): its ε-greedy behaviour is what the book measures."],
            tables=[("Online and greedy returns", pd.DataFrame(rows))], figures=[(image, "Figure 6.4, redrawn")]),
        _contrast_section(out, runs),
    ], [])


def _contrast_section(out: Path, runs: dict[str, Results]) -> Section:
    """The cliff beside the paper's Mountain Car study (and its CartPole and Acrobot versions) where those
    study directories stand beside this one."""
    table = contrast_table({"cliff": runs, **sibling_studies(out)})
    paragraphs = ["SARSA minus Q-Learning on paired seeds, with 95% bootstrap intervals: online, the mean return "
                  "of the ε-greedy behaviour over training (what an agent collects while it learns); greedy, the "
                  "return of the final greedy policy (what it learned).", BEHAVIOUR_AND_GREEDY]
    paragraphs += [_contrast_sentence(row) for row in table.to_dict("records")]
    if set(table["study"]) == {"cliff"}:
        paper_dir = Path(out).parent / "paper"
        paragraphs.append(f"Mountain Car's side is missing: run 'rlcompare reproduce --out {paper_dir}' (and "
                          "'reproduce cartpole', 'reproduce acrobot' beside it), then 'reproduce cliff' again.")
    paragraphs.append("Reading the rows: where SARSA is better online and Q-Learning greedy, as the book finds on the "
                      "cliff, exploring near the optimal path is what costs Q-Learning, which learns the values of "
                      "a greedy policy it does not follow. The paper calls Mountain Car a 'sacrificing problem' "
                      "(things must get worse before they get better) and expects SARSA to be better there on both "
                      "counts; its rows say whether it is.")
    return Section("Cliff Walking against Mountain Car: the contrast in numbers", paragraphs,
                   tables=[("SARSA against Q-Learning, study by study", table)])


def _contrast_sentence(row: dict[Hashable, Any]) -> str:
    return (f"{row['environment']} ({row['exploration']}, {row['seeds']} seeds): online SARSA - Q-Learning = "
            f"{row['online: SARSA - Q-Learning']} ({row['online: better']}); greedy "
            f"{row['greedy: SARSA - Q-Learning']} ({row['greedy: better']}).")


def _cliff_mask() -> np.ndarray:
    mask = np.zeros(CLIFF_SHAPE)
    mask[3, 1:11] = 1.0
    return mask


FIG_10_2 = BookStudy(fig_10_2_configs, report_10_2)
FIG_12_10 = BookStudy(fig_12_10_configs, report_12_10)
def cliff_questions(configs: dict[str, ExperimentConfig]) -> tuple[Question, ...]:
    """SARSA against Q-Learning, online and greedy, on paired seeds (not corrected: the contrast's two numbers)."""
    seeds = len(configs["sarsa"].seeds)
    return (Question("SARSA against Q-Learning online (Example 6.6: SARSA collects more)", SIGNED_RANK, seeds),
            Question("SARSA against Q-Learning's greedy path (Q-Learning's is the better)", SIGNED_RANK, seeds))


CLIFF_STUDY = BookStudy(cliff_configs, report_cliff, questions=cliff_questions)
FIG_6_3 = BookStudy(book_6_3.configs, book_6_3.report_6_3, book_6_3.train, book_6_3.PhaseRuns.load,
                    book_6_3.questions)
