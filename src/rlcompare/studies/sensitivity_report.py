"""The sensitivity study's report (:mod:`rlcompare.studies.sensitivity`, whose docstring lists the files it
writes), from the sweep's store alone: the cells in words and in a table, the heatmaps, what is missing, and
``report.html``.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from rlcompare.analysis.report import Section, save_figure, write_report, write_table
from rlcompare.analysis.stats import Estimate
from rlcompare.experiment import rundir, store
from rlcompare.experiment.sweep_store import read_manifest, trial_path
from rlcompare.studies.interface import Report
from rlcompare.studies.sensitivity import (
    ALGORITHMS,
    GRID,
    LEVEL,
    METRICS,
    NOT_RESOLVED,
    PAPER_CELL,
    Q_BETTER,
    SARSA_BETTER,
    STUDY,
    SWEEP_DIR,
    SYMBOLS,
    compare_cells,
    seed_returns,
)

SHORT_MARKS = {SARSA_BETTER: "SARSA", Q_BETTER: "Q-Learning", NOT_RESOLVED: "n.r."}
LISTED_CELLS = 12
"""Cells named one by one in the summary; beyond that, the table."""


# --- what is missing ----------------------------------------------------------------------------------------

def missing(seeds: pd.DataFrame, manifest: dict) -> list[str]:
    """What the report lacks: unfinished trials, and cells with one algorithm alone."""
    problems = []
    unfinished = len(manifest["trials"]) - len(seeds)
    if unfinished:
        problems.append(f"{unfinished} of {len(manifest['trials'])} trials not finished; run 'rlcompare reproduce "
                        f"{STUDY}' again with the same options to finish them")
    for cell, group in seeds.groupby(list(GRID), sort=True):
        lacking = [a for a in ALGORITHMS if a not in set(group["algorithm"])]
        if lacking:
            problems.append(f"cell {setting(dict(zip(GRID, cell, strict=True)))}: no finished trial of "
                            f"{', '.join(lacking)}")
    return problems


# --- words --------------------------------------------------------------------------------------------------

def _value(key: str, value) -> str:
    if key == "truncation_as_terminal":
        return "terminal" if value else "bootstrapped"
    return f"{value:g}"


def setting(row: dict, keys: Iterable[str] = GRID) -> str:
    """``α = 0.5, γ = 1, ε_end = 0, time limit terminal``."""
    return ", ".join(f"time limit {_value(k, row[k])}" if k == "truncation_as_terminal"
                     else f"{SYMBOLS[k]} = {_value(k, row[k])}" for k in keys)


def _counts(marks: pd.Series) -> str:
    counts = marks.value_counts()
    return (f"SARSA better in {counts.get(SARSA_BETTER, 0)} of {len(marks)} cells, Q-Learning better in "
            f"{counts.get(Q_BETTER, 0)}, not resolved in {counts.get(NOT_RESOLVED, 0)}")


def _where(chosen: pd.DataFrame, cells: pd.DataFrame) -> str:
    """Which values of each key the chosen cells fall on, out of the cells with that value."""
    parts = []
    for key in GRID:
        if cells[key].nunique() < 2:
            continue
        counts = [(value, int((chosen[key] == value).sum()), int((cells[key] == value).sum()))
                  for value in sorted(cells[key].unique())]
        parts.append(f"{SYMBOLS[key]}: " + ", ".join(f"{_value(key, v)} {n} of {total}" for v, n, total in counts))
    return "; ".join(parts)


def _spread(chosen: pd.DataFrame, cells: pd.DataFrame) -> str:
    where = _where(chosen, cells)
    return f", by setting: {where}" if where else ""


def metric_summary(cells: pd.DataFrame, metric: str) -> list[str]:
    """Cells each way on ``metric``, where the conclusion flips (Q-Learning better) and where it is not
    resolved."""
    marks = cells[f"{metric}_mark"]
    lines = [f"{METRICS[metric].capitalize()}: {_counts(marks)}."]
    flips, unresolved = cells[marks == Q_BETTER], cells[marks == NOT_RESOLVED]
    if not flips.empty:
        named = "; ".join(setting(row) for row in flips.head(LISTED_CELLS).to_dict("records"))
        more = f"; and {len(flips) - LISTED_CELLS} more (see the table)" if len(flips) > LISTED_CELLS else ""
        lines.append(f"The conclusion flips (Q-Learning better) in {len(flips)} cells{_spread(flips, cells)}. "
                     f"They are: {named}{more}.")
    if not unresolved.empty:
        lines.append(f"Not resolved in {len(unresolved)} cells{_spread(unresolved, cells)}.")
    if not (marks == Q_BETTER).any():
        lines.append("The conclusion never flips on this metric: no cell has Q-Learning better.")
    return lines


def paper_cell_line(cells: pd.DataFrame) -> str | None:
    """The paper's own setting, where the grid holds it."""
    at = np.logical_and.reduce([np.isclose(cells[k].astype(float), float(v)) for k, v in PAPER_CELL.items()])
    if not at.any():
        return None
    row = cells[at].iloc[0]
    told = "; ".join(f"{metric} {_difference(row, metric)}: {row[f'{metric}_mark']}" for metric in METRICS)
    return f"The paper's setting ({setting(row)}): SARSA - Q-Learning, {told}."


def summary(cells: pd.DataFrame) -> list[str]:
    """The report's opening: the family, then each metric's cells, flips and the paper's cell."""
    if cells.empty:
        return ["No cell has both SARSA and Q-Learning finished yet."]
    lines = [f"{len(cells)} cells (α x γ x ε_end x time limit), SARSA against Q-Learning on {_seeds(cells)} paired "
             f"seeds each. Marks: Holm's correction over the {len(cells)} cells of each metric (each metric is "
             f"one family of {len(cells)} tests), family-wise level {LEVEL:g}, and the 95% interval of the "
             "difference on the same side of 0."]
    for metric in METRICS:
        lines += metric_summary(cells, metric)
    paper = paper_cell_line(cells)
    return [*lines, paper] if paper else lines


def _seeds(cells: pd.DataFrame) -> str:
    low, high = int(cells["seeds"].min()), int(cells["seeds"].max())
    return str(low) if low == high else f"{low} to {high}"


def _difference(row, metric: str) -> str:
    return Estimate(row[f"{metric}_difference"], row[f"{metric}_low"], row[f"{metric}_high"]).format(1)


def display_table(cells: pd.DataFrame) -> pd.DataFrame:
    """The cells as the report and ``tables/cells.{md,csv}`` show them."""
    table = pd.DataFrame({SYMBOLS[key]: [_value(key, v) for v in cells[key]] for key in GRID})
    table["seeds"] = cells["seeds"].to_numpy()
    for metric in METRICS:
        table[f"{metric}: SARSA"] = cells[f"{metric}_sarsa"].round(1).to_numpy()
        table[f"{metric}: Q-Learning"] = cells[f"{metric}_q_learning"].round(1).to_numpy()
        table[f"{metric}: SARSA - Q-Learning [95% CI]"] = [_difference(row, metric) for _, row in cells.iterrows()]
        table[f"{metric}: Wilcoxon p"] = cells[f"{metric}_p"].to_numpy()
        table[f"{metric}: Holm p"] = cells[f"{metric}_holm"].to_numpy()
        table[f"{metric}: mark"] = cells[f"{metric}_mark"].to_numpy()
    return table


# --- the heatmap --------------------------------------------------------------------------------------------

def heatmap_figure(cells: pd.DataFrame, metric: str) -> Figure:
    """A panel per (time limit, γ); in each, α x ε_end cells coloured by SARSA minus Q-Learning (diverging,
    centred on 0: blue where SARSA returns more) and annotated with the difference and the mark."""
    rows, columns = sorted(cells["truncation_as_terminal"].unique()), sorted(cells["gamma"].unique())
    alphas, ends = sorted(cells["alpha"].unique()), sorted(cells["epsilon_end"].unique())
    figure = Figure(figsize=(1.0 + 1.1 * len(alphas) * len(columns), 0.9 + 0.75 * len(ends) * len(rows) + 0.6),
                    layout="constrained")
    axes = figure.subplots(len(rows), len(columns), squeeze=False)
    values = cells[f"{metric}_difference"].to_numpy(dtype=np.float64)
    largest = float(np.nanmax(np.abs(values))) if np.isfinite(values).any() else 1.0
    norm = Normalize(-largest or -1.0, largest or 1.0)
    image = None
    for i, truncation in enumerate(rows):
        for j, gamma in enumerate(columns):
            panel = cells[(cells["truncation_as_terminal"] == truncation) & (cells["gamma"] == gamma)]
            image = _heatmap_panel(axes[i, j], panel, metric, alphas, ends, norm)
            axes[i, j].set_title(f"γ = {gamma:g}, time limit {_value('truncation_as_terminal', truncation)}",
                                 fontsize="medium")
    figure.colorbar(image, ax=axes, shrink=0.8, label="SARSA - Q-Learning (return)")
    figure.suptitle(f"{METRICS[metric].capitalize()}: SARSA - Q-Learning, mean over {_seeds(cells)} paired seeds; "
                    f"marks with Holm over {len(cells)} cells at {LEVEL:g}")
    return figure


def _heatmap_panel(ax, panel: pd.DataFrame, metric: str, alphas: list, ends: list, norm: Normalize):
    grid = np.full((len(ends), len(alphas)), np.nan)
    marks = np.full(grid.shape, "", dtype=object)
    for row in panel.to_dict("records"):
        at = (ends.index(row["epsilon_end"]), alphas.index(row["alpha"]))
        grid[at], marks[at] = row[f"{metric}_difference"], row[f"{metric}_mark"]
    image = ax.imshow(grid, cmap="RdBu", norm=norm, origin="lower", aspect="auto")
    for (y, x), value in np.ndenumerate(grid):
        text = "n/a" if np.isnan(value) else f"{value:+.1f}\n{SHORT_MARKS.get(marks[y, x], '')}"
        strong = np.isfinite(value) and abs(norm(value) - 0.5) > 0.3
        ax.text(x, y, text, ha="center", va="center", fontsize="x-small", color="white" if strong else "black",
                fontweight="bold" if marks[y, x] in (SARSA_BETTER, Q_BETTER) else "normal")
    ax.set_xticks(range(len(alphas)), [f"{a:g}" for a in alphas])
    ax.set_yticks(range(len(ends)), [f"{e:g}" for e in ends])
    ax.set_xlabel("α")
    ax.set_ylabel("ε_end")
    return image


# --- the report ---------------------------------------------------------------------------------------------

def build_report(out: Path) -> Report:
    root = out / SWEEP_DIR
    manifest = read_manifest(root)
    seeds = seed_returns(root)
    cells = compare_cells(seeds)
    problems = missing(seeds, manifest)
    lines = summary(cells)
    sections = [Section("Summary", lines)]
    if not cells.empty:
        table = display_table(cells)
        table_file = write_table(table, out / "tables", "cells")
        config = store.read_json(trial_path(root, seeds["config"].iloc[0], seeds["seed"].iloc[0]) / rundir.CONFIG_FILE)
        sections += [
            Section("The grid", method_paragraphs(config, cells, len(seeds), manifest)),
            *(Section(METRICS[metric].capitalize(), figures=[(
                save_figure(heatmap_figure(cells, metric), out / "figures" / f"heatmap-{metric}.png", dpi=90),
                f"SARSA - Q-Learning on the {METRICS[metric]}; blue: SARSA returns more")]) for metric in METRICS),
            Section("Cells", tables=[("SARSA against Q-Learning, cell by cell", table, table_file)]),
        ]
    path = write_report(out / "report.html", "Sensitivity: SARSA against Q-Learning across settings", sections,
                        problems)
    return Report(path, lines, problems)


def method_paragraphs(config: dict, cells: pd.DataFrame, finished: int, manifest: dict) -> list[str]:
    """What ran (``config``: one trial's ``config.json``) and how the cells are marked."""
    grid = "; ".join(f"{SYMBOLS[k]} ∈ {{{', '.join(_value(k, v) for v in sorted(cells[k].unique()))}}}"
                     for k in GRID)
    return [
        f"{config['env']}, {config['bins']} bins per dimension, a {config['max_steps']}-step limit, "
        f"{config['episodes']} episodes per seed, ε decaying linearly from {config['epsilon_start']:g} to ε_end over "
        f"the first {config['decay_fraction']:.0%} of them; greedy evaluation every {config['eval_every']} episodes "
        f"({config['eval_episodes']} episodes each). Grid: {grid}, each for Q-Learning and SARSA. Everything else "
        "is the paper's setting. Time limit bootstrapped: the update at the cut bootstraps from the next state's "
        "value; terminal: it does not, as old Gym's done made the paper's agents do.",
        f"{finished} of {len(manifest['trials'])} trials finished (root seed {manifest['root_seed']}; every "
        f"configuration runs the same seeds, so SARSA and Q-Learning meet on the same start states). The sweep's "
        f"store is {SWEEP_DIR}/; 'rlcompare report' on it gives its own sweep report.",
        "Per cell: the mean over seeds of SARSA minus Q-Learning on paired seeds, its 95% BCa bootstrap interval, "
        f"and the two-sided Wilcoxon signed-rank p-value. Each metric's {len(cells)} cells form one family: "
        "p-values adjusted by Holm's step-down method; a cell is marked SARSA better (Q-Learning better) when its "
        f"adjusted p-value is below {LEVEL:g} and its interval lies above (below) 0, and not resolved otherwise.",
    ]
