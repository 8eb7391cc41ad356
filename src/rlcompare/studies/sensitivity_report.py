"""The sensitivity study's report (:mod:`rlcompare.studies.sensitivity`, whose docstring lists the files it
writes), from the sweep's store alone: the cells in words and in a table, the heatmaps of the cross and of the
schedule block, what is missing, and ``report.html``.

The summary names every region where the conclusion flips (:func:`flip_regions`: a run of neighbouring γ values
at one schedule, α and time limit where Q-Learning is marked better), with SARSA minus Q-Learning and its
interval at each of its cells, and says "never flips" only of a block that has no such cell, naming the axes
that block sweeps (:func:`blocks`).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from rlcompare.experiment import rundir, store
from rlcompare.experiment.sweep_store import read_manifest, trial_path
from rlcompare.report.page import Section, save_figure, write_report, write_table
from rlcompare.stats.intervals import Estimate
from rlcompare.studies.interface import Report
from rlcompare.studies.sensitivity_grid import (
    ALGORITHMS,
    CELL_KEYS,
    GRID,
    LEVEL,
    METRICS,
    NOT_RESOLVED,
    PAPER_CELL,
    PAPER_CONSTANT_CELL,
    Q_BETTER,
    SARSA_BETTER,
    SCHEDULE_BLOCK,
    STUDY,
    SWEEP_DIR,
    SYMBOLS,
    compare_cells,
    seed_returns,
)

SHORT_MARKS = {SARSA_BETTER: "SARSA", Q_BETTER: "Q-Learning", NOT_RESOLVED: "n.r."}
WORDS = ("alpha", "gamma", "exploration", "truncation_as_terminal")
"""How a cell is named: α, γ, its ε (``ε_end = 0`` or ``constant ε = 0.5``), time limit."""


# --- what is missing ----------------------------------------------------------------------------------------

def missing(seeds: pd.DataFrame, manifest: dict) -> list[str]:
    """What the report lacks: unfinished trials, and cells with one algorithm alone."""
    problems = []
    unfinished = len(manifest["trials"]) - len(seeds)
    if unfinished:
        problems.append(f"{unfinished} of {len(manifest['trials'])} trials not finished; run 'rlcompare reproduce "
                        f"{STUDY}' again with the same options to finish them")
    for cell, group in seeds.groupby(list(CELL_KEYS), sort=True):
        lacking = [a for a in ALGORITHMS if a not in set(group["algorithm"])]
        if lacking:
            problems.append(f"cell {setting(dict(zip(CELL_KEYS, cell, strict=True)))}: no finished trial of "
                            f"{', '.join(lacking)}")
    return problems


# --- words --------------------------------------------------------------------------------------------------

def _value(key: str, value) -> str:
    if key == "truncation_as_terminal":
        return "terminal" if value else "bootstrapped"
    return f"{value:g}"


def exploration(row: dict) -> str:
    """A cell's ε: ``ε_end = 0`` (decaying from 1) or ``constant ε = 0.5``."""
    if row["schedule"] == "constant":
        return f"{SYMBOLS['epsilon']} = {row['epsilon_end']:g}"
    return f"{SYMBOLS['epsilon_end']} = {row['epsilon_end']:g}"


def schedule_label(schedule: str, epsilon: float) -> str:
    """A row of the schedule map: ``constant 0.5`` or ``decaying to 0``."""
    return f"constant {epsilon:g}" if schedule == "constant" else f"decaying to {epsilon:g}"


def setting(row: dict, keys: Iterable[str] = WORDS) -> str:
    """``α = 0.5, γ = 1, ε_end = 0, time limit terminal`` (``constant ε = 0.5`` in place of ``ε_end`` for a
    constant cell)."""
    parts = []
    for key in keys:
        if key == "exploration":
            parts.append(exploration(row))
        elif key == "truncation_as_terminal":
            parts.append(f"time limit {_value(key, row[key])}")
        else:
            parts.append(f"{SYMBOLS[key]} = {_value(key, row[key])}")
    return ", ".join(parts)


def _labelled(cells: pd.DataFrame) -> pd.DataFrame:
    """The cells with ``exploration``: each one's schedule label."""
    return cells.assign(exploration=[schedule_label(s, e) for s, e in zip(
        cells["schedule"], cells["epsilon_end"], strict=True)])


def _counts(marks: pd.Series) -> str:
    counts = marks.value_counts()
    return (f"SARSA better in {counts.get(SARSA_BETTER, 0)} of {len(marks)} cells, Q-Learning better in "
            f"{counts.get(Q_BETTER, 0)}, not resolved in {counts.get(NOT_RESOLVED, 0)}")


def _where(chosen: pd.DataFrame, cells: pd.DataFrame) -> str:
    """Which values of each key the chosen cells fall on, out of the cells with that value."""
    chosen, cells = _labelled(chosen), _labelled(cells)
    parts = []
    for key in WORDS:
        if cells[key].nunique() < 2:
            continue
        values = sorted(cells[key].unique(), key=lambda v: (str(v).startswith("decaying"), v))
        counts = [(value, int((chosen[key] == value).sum()), int((cells[key] == value).sum())) for value in values]
        name = "ε" if key == "exploration" else SYMBOLS[key]
        shown = (lambda v: v) if key == "exploration" else (lambda v, key=key: _value(key, v))
        parts.append(f"{name}: " + ", ".join(f"{shown(v)} {n} of {total}" for v, n, total in counts))
    return "; ".join(parts)


def _spread(chosen: pd.DataFrame, cells: pd.DataFrame) -> str:
    where = _where(chosen, cells)
    return f", by setting: {where}" if where else ""


# --- the blocks and where the conclusion flips ---------------------------------------------------------------

def _at(cells: pd.DataFrame, where: dict) -> np.ndarray:
    """Which cells have every value of ``where``."""
    at = np.ones(len(cells), dtype=bool)
    for key, value in where.items():
        column = cells[key]
        at &= ((column == value).to_numpy(dtype=bool) if key in ("schedule", "truncation_as_terminal")
               else np.isclose(column.to_numpy(dtype=np.float64), float(value)))
    return at


def cross_cells(cells: pd.DataFrame) -> pd.DataFrame:
    """The cross's cells: ε decaying."""
    return cells[(cells["schedule"] == "decay").to_numpy(dtype=bool)]


def schedule_cells(cells: pd.DataFrame) -> pd.DataFrame:
    """The schedule block's cells (every schedule at :data:`SCHEDULE_BLOCK`); none where no cell is constant."""
    if not (cells["schedule"] == "constant").any():
        return cells.iloc[:0]
    return cells[_at(cells, SCHEDULE_BLOCK)]


def schedule_rows(block: pd.DataFrame) -> list[tuple[str, float]]:
    """The schedule map's rows, top to bottom: constant ε ascending, then decaying to each ε_end ascending."""
    rows = {(s, float(e)) for s, e in zip(block["schedule"], block["epsilon_end"], strict=True)}
    return sorted(rows, key=lambda row: (row[0] != "constant", row[1]))


def _axes(block: pd.DataFrame, keys: Iterable[str]) -> tuple[list[str], list[str]]:
    """The keys ``block`` sweeps (more than one value) and the ones it holds, in words."""
    swept, held = [], []
    for key in keys:
        values = sorted(block[key].unique())
        if len(values) > 1:
            swept.append(SYMBOLS[key])
        else:
            held.append(setting({key: values[0]}, [key]))
    return swept, held


def blocks(cells: pd.DataFrame) -> list[tuple[str, str, pd.DataFrame]]:
    """Each block the cells hold, as (``cross`` or ``schedule``; the axes it sweeps and where it sits, in words;
    its cells): the cross (ε decaying), and the schedule block where there are constant cells."""
    out = []
    cross = cross_cells(cells)
    if not cross.empty:
        swept, held = _axes(cross, GRID)
        words = " x ".join(swept) or "its one cell"
        out.append(("cross", words + (f" at {', '.join(held)}" if held else "") + " (ε decaying from 1)", cross))
    block = schedule_cells(cells)
    if not block.empty:
        rows = schedule_rows(block)
        constant = [e for s, e in rows if s == "constant"]
        decaying = [e for s, e in rows if s == "decay"]
        schedules = "; ".join(part for part in (
            f"constant {', '.join(f'{e:g}' for e in constant)}" if constant else "",
            f"decaying from 1 to {', '.join(f'{e:g}' for e in decaying)}" if decaying else "") if part)
        gammas = sorted(block["gamma"].unique())
        where = setting(SCHEDULE_BLOCK, SCHEDULE_BLOCK)
        if len(gammas) > 1:
            words = f"the ε schedule ({schedules}) x γ ({', '.join(f'{g:g}' for g in gammas)}) at {where}"
        else:
            words = f"the ε schedule ({schedules}) at γ = {gammas[0]:g}, {where}"
        out.append(("schedule", words, block))
    return out


def flip_regions(cells: pd.DataFrame, metric: str) -> list[str]:
    """Every region where the conclusion flips on ``metric``: at one schedule, ε, α and time limit, each run of
    neighbouring γ values (of those the cells hold there) whose cells are marked Q-Learning better, named with
    SARSA minus Q-Learning and its 95% interval at each of its cells and at the cells beside it."""
    others = [key for key in CELL_KEYS if key != "gamma"]
    regions = []
    for _, group in cells.groupby(others, sort=True):
        rows = group.sort_values("gamma").to_dict("records")
        flipped = [row[f"{metric}_mark"] == Q_BETTER for row in rows]
        start = 0
        while start < len(rows):
            if not flipped[start]:
                start += 1
                continue
            stop = start
            while stop < len(rows) and flipped[stop]:
                stop += 1
            regions.append(_region(rows, start, stop, metric))
            start = stop
    return regions


def _region(rows: list[dict], start: int, stop: int, metric: str) -> str:
    first = rows[start]
    head = (f"{exploration(first)} with {_gamma_range([row['gamma'] for row in rows], start, stop)} "
            f"({setting(first, ('alpha', 'truncation_as_terminal'))})")
    values = ", ".join(f"{_difference(row, metric)} at γ = {row['gamma']:g}" for row in rows[start:stop])
    beside = "; ".join(f"γ = {row['gamma']:g}: {_difference(row, metric)}, {row[f'{metric}_mark']}"
                       for row in (rows[i] for i in (start - 1, stop) if 0 <= i < len(rows)))
    return f"{head}: SARSA - Q-Learning {values}" + (f" (beside it, {beside})" if beside else "")


def _gamma_range(gammas: list[float], start: int, stop: int) -> str:
    """``γ ≥ 0.99``, ``γ = 1``, ``γ ≤ 0.99``, ``0.9 ≤ γ ≤ 0.99`` or ``every γ (...)``: positions [start, stop)
    of ``gammas`` (ascending)."""
    low, high = gammas[start], gammas[stop - 1]
    if stop - start == 1:
        return f"γ = {low:g}"
    if stop - start == len(gammas):
        return f"every γ ({', '.join(f'{g:g}' for g in gammas)})"
    if stop == len(gammas):
        return f"γ ≥ {low:g}"
    if start == 0:
        return f"γ ≤ {high:g}"
    return f"{low:g} ≤ γ ≤ {high:g}"


def metric_summary(cells: pd.DataFrame, metric: str) -> list[str]:
    """Cells each way on ``metric``; every region where the conclusion flips (Q-Learning better), with its
    numbers; where it is not resolved; and each block over which it never flips, with the axes it sweeps."""
    marks = cells[f"{metric}_mark"]
    lines = [f"{METRICS[metric].capitalize()}: {_counts(marks)}."]
    regions = flip_regions(cells, metric)
    if regions:
        flips = int((marks == Q_BETTER).sum())
        lines.append(f"The conclusion flips (Q-Learning better) in {flips} cell{'s' * (flips != 1)}, "
                     f"{len(regions)} region{'s' * (len(regions) != 1)}, each below with SARSA - Q-Learning "
                     "[95% interval] at its cells.")
        lines += [f"Flips at {region}." for region in regions]
    unresolved = cells[marks == NOT_RESOLVED]
    if not unresolved.empty:
        lines.append(f"Not resolved in {len(unresolved)} cell{'s' * (len(unresolved) != 1)}"
                     f"{_spread(unresolved, cells)}.")
    for _, words, block in blocks(cells):
        if not (block[f"{metric}_mark"] == Q_BETTER).any():
            lines.append(f"The conclusion never flips on this metric over {words}: no cell there has Q-Learning "
                         "better.")
    return lines


def paper_cell_lines(cells: pd.DataFrame) -> list[str]:
    """The paper's own settings, decaying and constant ε, where the grid holds them."""
    lines = []
    for name, where in (("setting", PAPER_CELL), ("constant-ε setting", PAPER_CONSTANT_CELL)):
        at = _at(cells, where)
        if at.any():
            row = cells[at].iloc[0]
            told = "; ".join(f"{metric} {_difference(row, metric)}: {row[f'{metric}_mark']}" for metric in METRICS)
            lines.append(f"The paper's {name} ({setting(row)}): SARSA - Q-Learning, {told}.")
    return lines


def summary(cells: pd.DataFrame) -> list[str]:
    """The report's opening: the family and its blocks, then each metric's cells, flips and blocks without a
    flip, and the paper's cells."""
    if cells.empty:
        return ["No cell has both SARSA and Q-Learning finished yet."]
    parts = [f"{len(block)} of {words}" for _, words, block in blocks(cells)]
    shared = len(cross_cells(schedule_cells(cells)))
    both = f", {shared} of them in both (the same configurations, trained once)" if shared and len(parts) > 1 else ""
    lines = [f"{len(cells)} cells: {' and '.join(parts)}{both}. SARSA against Q-Learning on {_seeds(cells)} paired "
             f"seeds each. Marks: Holm's correction over the {len(cells)} cells of each metric (each metric is one "
             f"family of {len(cells)} tests), family-wise level {LEVEL:g}, and the 95% interval of the difference "
             "on the same side of 0."]
    for metric in METRICS:
        lines += metric_summary(cells, metric)
    return lines + paper_cell_lines(cells)


def _seeds(cells: pd.DataFrame) -> str:
    low, high = int(cells["seeds"].min()), int(cells["seeds"].max())
    return str(low) if low == high else f"{low} to {high}"


def _difference(row, metric: str) -> str:
    return Estimate(row[f"{metric}_difference"], row[f"{metric}_low"], row[f"{metric}_high"]).format(1)


def display_table(cells: pd.DataFrame) -> pd.DataFrame:
    """The cells as the report and ``tables/cells.{md,csv}`` show them."""
    labelled = _labelled(cells)
    table = pd.DataFrame({"ε" if key == "exploration" else SYMBOLS[key]: (
        labelled[key].tolist() if key == "exploration" else [_value(key, v) for v in cells[key]]) for key in WORDS})
    table["seeds"] = cells["seeds"].to_numpy()
    for metric in METRICS:
        table[f"{metric}: SARSA"] = cells[f"{metric}_sarsa"].round(1).to_numpy()
        table[f"{metric}: Q-Learning"] = cells[f"{metric}_q_learning"].round(1).to_numpy()
        table[f"{metric}: SARSA - Q-Learning [95% CI]"] = [_difference(row, metric) for _, row in cells.iterrows()]
        table[f"{metric}: Wilcoxon p"] = cells[f"{metric}_p"].to_numpy()
        table[f"{metric}: Holm p"] = cells[f"{metric}_holm"].to_numpy()
        table[f"{metric}: mark"] = cells[f"{metric}_mark"].to_numpy()
    return table


# --- the heatmaps -------------------------------------------------------------------------------------------

def _norm(cells: pd.DataFrame, metric: str) -> Normalize:
    """Diverging, centred on 0, as wide as the largest difference."""
    values = cells[f"{metric}_difference"].to_numpy(dtype=np.float64)
    largest = float(np.nanmax(np.abs(values))) if np.isfinite(values).any() else 1.0
    return Normalize(-largest or -1.0, largest or 1.0)


def _title(cells: pd.DataFrame, metric: str, what: str) -> str:
    return (f"{METRICS[metric].capitalize()}: SARSA - Q-Learning{what}, mean over {_seeds(cells)} paired seeds; "
            f"marks with Holm over {len(cells)} cells at {LEVEL:g}")


def heatmap_figure(cells: pd.DataFrame, metric: str) -> Figure:
    """The cross: a panel per (time limit, γ); in each, α x ε_end cells coloured by SARSA minus Q-Learning
    (diverging, centred on 0: blue where SARSA returns more) and annotated with the difference and the mark.
    ``cells``: the whole family (the title counts it); the constant ones are the schedule map's."""
    cross = cross_cells(cells)
    rows, columns = sorted(cross["truncation_as_terminal"].unique()), sorted(cross["gamma"].unique())
    alphas, ends = sorted(cross["alpha"].unique()), sorted(cross["epsilon_end"].unique())
    figure = Figure(figsize=(1.0 + 1.1 * len(alphas) * len(columns), 0.9 + 0.75 * len(ends) * len(rows) + 0.6),
                    layout="constrained")
    axes = figure.subplots(len(rows), len(columns), squeeze=False)
    norm = _norm(cross, metric)
    image = None
    for i, truncation in enumerate(rows):
        for j, gamma in enumerate(columns):
            panel = cross[(cross["truncation_as_terminal"] == truncation) & (cross["gamma"] == gamma)]
            grid = np.full((len(ends), len(alphas)), np.nan)
            marks = np.full(grid.shape, "", dtype=object)
            for row in panel.to_dict("records"):
                at = (ends.index(row["epsilon_end"]), alphas.index(row["alpha"]))
                grid[at], marks[at] = row[f"{metric}_difference"], row[f"{metric}_mark"]
            ax = axes[i, j]
            image = _draw(ax, grid, marks, norm, origin="lower")
            ax.set_xticks(range(len(alphas)), [f"{a:g}" for a in alphas])
            ax.set_yticks(range(len(ends)), [f"{e:g}" for e in ends])
            ax.set_xlabel("α")
            ax.set_ylabel("ε_end")
            ax.set_title(f"γ = {gamma:g}, time limit {_value('truncation_as_terminal', truncation)}",
                         fontsize="medium")
    figure.colorbar(image, ax=axes, shrink=0.8, label="SARSA - Q-Learning (return)")
    figure.suptitle(_title(cells, metric, ", ε decaying from 1"))
    return figure


def schedule_figure(cells: pd.DataFrame, metric: str) -> Figure:
    """The schedule block: one panel of ε schedule (rows: constant ε, then decaying to each ε_end) x γ
    (columns) cells, coloured and annotated as :func:`heatmap_figure`'s. ``cells``: the whole family."""
    block = schedule_cells(cells)
    rows, gammas = schedule_rows(block), sorted(block["gamma"].unique())
    grid = np.full((len(rows), len(gammas)), np.nan)
    marks = np.full(grid.shape, "", dtype=object)
    for row in block.to_dict("records"):
        at = (rows.index((row["schedule"], float(row["epsilon_end"]))), gammas.index(row["gamma"]))
        grid[at], marks[at] = row[f"{metric}_difference"], row[f"{metric}_mark"]
    figure = Figure(figsize=(4.5 + 1.2 * len(gammas), 1.6 + 0.5 * len(rows)), layout="constrained")
    ax = figure.subplots()
    image = _draw(ax, grid, marks, _norm(block, metric), origin="upper")
    ax.set_xticks(range(len(gammas)), [f"{g:g}" for g in gammas])
    ax.set_yticks(range(len(rows)), [schedule_label(*row) for row in rows])
    ax.set_xlabel("γ")
    ax.set_ylabel("ε schedule")
    ax.set_title(setting(SCHEDULE_BLOCK, SCHEDULE_BLOCK), fontsize="medium")
    figure.colorbar(image, ax=ax, shrink=0.8, label="SARSA - Q-Learning (return)")
    figure.suptitle(_title(cells, metric, " by ε schedule and γ"), fontsize="medium", wrap=True)
    return figure


def _draw(ax, grid: np.ndarray, marks: np.ndarray, norm: Normalize, origin: str):
    """The cells of one panel, each annotated with its difference and mark (bold where resolved)."""
    image = ax.imshow(grid, cmap="RdBu", norm=norm, origin=origin, aspect="auto")
    for (y, x), value in np.ndenumerate(grid):
        text = "n/a" if np.isnan(value) else f"{value:+.1f}\n{SHORT_MARKS.get(marks[y, x], '')}"
        strong = np.isfinite(value) and abs(norm(value) - 0.5) > 0.3
        ax.text(x, y, text, ha="center", va="center", fontsize="x-small", color="white" if strong else "black",
                fontweight="bold" if marks[y, x] in (SARSA_BETTER, Q_BETTER) else "normal")
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
        sections.append(Section("The grid", method_paragraphs(config, cells, len(seeds), manifest)))
        if not cross_cells(cells).empty:
            sections += [Section(METRICS[metric].capitalize(), figures=[(
                save_figure(heatmap_figure(cells, metric), out / "figures" / f"heatmap-{metric}.png", dpi=90),
                f"SARSA - Q-Learning on the {METRICS[metric]}, ε decaying; blue: SARSA returns more")])
                for metric in METRICS]
        if not schedule_cells(cells).empty:
            sections.append(Section("The ε schedule", [
                f"ε's schedule x γ at {setting(SCHEDULE_BLOCK, SCHEDULE_BLOCK)}: SARSA - Q-Learning, the mark under "
                "each value (n.r.: not resolved; bold: resolved, by the family's Holm correction)."], figures=[(
                    save_figure(schedule_figure(cells, metric), out / "figures" / f"schedule-{metric}.png", dpi=90),
                    f"SARSA - Q-Learning on the {METRICS[metric]} by ε schedule and γ; blue: SARSA returns more")
                    for metric in METRICS]))
        sections.append(Section("Cells", tables=[("SARSA against Q-Learning, cell by cell", table, table_file)]))
    path = write_report(out / "report.html", "Sensitivity: SARSA against Q-Learning across settings", sections,
                        problems)
    return Report(path, lines, problems)


def method_paragraphs(config: dict, cells: pd.DataFrame, finished: int, manifest: dict) -> list[str]:
    """What ran (``config``: one trial's ``config.json``) and how the cells are marked."""
    cross = cross_cells(cells)
    grid = "; ".join(f"{SYMBOLS[k]} ∈ {{{', '.join(_value(k, v) for v in sorted(cross[k].unique()))}}}"
                     for k in GRID)
    block = [words for name, words, _ in blocks(cells) if name == "schedule"]
    schedule = (f" Beside that cross, a block of {block[0]}: ε constant throughout (the paper's constant runs: 0.5) "
                "or decaying as in the cross, the cross's own cells where it holds them.") if block else ""
    return [
        f"{config['env']}, {config['bins']} bins per dimension, a {config['max_steps']}-step limit, "
        f"{config['episodes']} episodes per seed; in the cross, ε decaying linearly from {config['epsilon_start']:g} "
        f"to ε_end over the first {config['decay_fraction']:.0%} of them; greedy evaluation every "
        f"{config['eval_every']} episodes ({config['eval_episodes']} episodes each). The cross: {grid}, each for "
        f"Q-Learning and SARSA.{schedule} Everything else is the paper's setting. Time limit bootstrapped: the "
        "update at the cut bootstraps from the next state's value; terminal: it does not, as old Gym's done made "
        "the paper's agents do.",
        f"{finished} of {len(manifest['trials'])} trials finished (root seed {manifest['root_seed']}; every "
        f"configuration runs the same seeds, so SARSA and Q-Learning meet on the same start states). The sweep's "
        f"store is {SWEEP_DIR}/; 'rlcompare report' on it gives its own sweep report.",
        "Per cell: the mean over seeds of SARSA minus Q-Learning on paired seeds, its 95% BCa bootstrap interval, "
        f"and the two-sided Wilcoxon signed-rank p-value. Each metric's {len(cells)} cells, both blocks, form one "
        "family: p-values adjusted by Holm's step-down method; a cell is marked SARSA better (Q-Learning better) "
        f"when its adjusted p-value is below {LEVEL:g} and its interval lies above (below) 0, and not resolved "
        "otherwise.",
    ]
