"""The sensitivity study's cells in words: what is missing, each setting as a reader says it, the two blocks of the
grid, the regions where SARSA's lead over Q-Learning flips, and the table of every cell."""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Mapping
from typing import Any, Protocol

import numpy as np
import pandas as pd

from rlcompare.stats.intervals import Estimate
from rlcompare.studies.sensitivity.grid import (
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
    SYMBOLS,
    AxisValue,
)

SHORT_MARKS = {SARSA_BETTER: "SARSA", Q_BETTER: "Q-Learning", NOT_RESOLVED: "n.r."}
WORDS = ("alpha", "gamma", "exploration", "truncation_as_terminal")
"""How a cell is named: α, γ, its ε (``ε_end = 0`` or ``constant ε = 0.5``), time limit."""


class Row(Protocol):
    """A cell's values by key: a mapping, or a row of the cells' frame."""

    def __getitem__(self, key: str, /) -> Any: ...


# --- what is missing ----------------------------------------------------------------------------------------

def missing(seeds: pd.DataFrame, manifest: dict[str, Any]) -> list[str]:
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

def value_text(key: str, value: object) -> str:
    if key == "truncation_as_terminal":
        return "terminal" if value else "bootstrapped"
    return f"{value:g}"


def exploration(row: Row) -> str:
    """A cell's ε: ``ε_end = 0`` (decaying from 1) or ``constant ε = 0.5``."""
    if row["schedule"] == "constant":
        return f"{SYMBOLS['epsilon']} = {row['epsilon_end']:g}"
    return f"{SYMBOLS['epsilon_end']} = {row['epsilon_end']:g}"


def schedule_label(schedule: str, epsilon: float) -> str:
    """A row of the schedule map: ``constant 0.5`` or ``decaying to 0``."""
    return f"constant {epsilon:g}" if schedule == "constant" else f"decaying to {epsilon:g}"


def setting(row: Row, keys: Iterable[str] = WORDS) -> str:
    """``α = 0.5, γ = 1, ε_end = 0, time limit terminal`` (``constant ε = 0.5`` in place of ``ε_end`` for a
    constant cell)."""
    parts = []
    for key in keys:
        if key == "exploration":
            parts.append(exploration(row))
        elif key == "truncation_as_terminal":
            parts.append(f"time limit {value_text(key, row[key])}")
        else:
            parts.append(f"{SYMBOLS[key]} = {value_text(key, row[key])}")
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
        shown = (lambda v: v) if key == "exploration" else (lambda v, key=key: value_text(key, v))
        parts.append(f"{name}: " + ", ".join(f"{shown(v)} {n} of {total}" for v, n, total in counts))
    return "; ".join(parts)


def _spread(chosen: pd.DataFrame, cells: pd.DataFrame) -> str:
    where = _where(chosen, cells)
    return f", by setting: {where}" if where else ""


# --- the blocks and where the conclusion flips ---------------------------------------------------------------

def _at(cells: pd.DataFrame, where: Mapping[str, str | AxisValue]) -> np.ndarray:
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


def _region(rows: list[dict[Hashable, Any]], start: int, stop: int, metric: str) -> str:
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
    lines = [f"{len(cells)} cells: {' and '.join(parts)}{both}. SARSA against Q-Learning on {seeds_text(cells)} paired "
             f"seeds each. Marks: Holm's correction over the {len(cells)} cells of each metric (each metric is one "
             f"family of {len(cells)} tests), family-wise level {LEVEL:g}, and the 95% interval of the difference "
             "on the same side of 0."]
    for metric in METRICS:
        lines += metric_summary(cells, metric)
    return lines + paper_cell_lines(cells)


def seeds_text(cells: pd.DataFrame) -> str:
    low, high = int(cells["seeds"].min()), int(cells["seeds"].max())
    return str(low) if low == high else f"{low} to {high}"


def _difference(row: Row, metric: str) -> str:
    return Estimate(row[f"{metric}_difference"], row[f"{metric}_low"], row[f"{metric}_high"]).format(1)


def display_table(cells: pd.DataFrame) -> pd.DataFrame:
    """The cells as the report and ``tables/cells.{md,csv}`` show them."""
    labelled = _labelled(cells)
    table = pd.DataFrame({"ε" if key == "exploration" else SYMBOLS[key]: (
        labelled[key].tolist() if key == "exploration" else [value_text(key, v) for v in cells[key]]) for key in WORDS})
    table["seeds"] = cells["seeds"].to_numpy()
    for metric in METRICS:
        table[f"{metric}: SARSA"] = cells[f"{metric}_sarsa"].round(1).to_numpy()
        table[f"{metric}: Q-Learning"] = cells[f"{metric}_q_learning"].round(1).to_numpy()
        table[f"{metric}: SARSA - Q-Learning [95% CI]"] = [_difference(row, metric) for _, row in cells.iterrows()]
        table[f"{metric}: Wilcoxon p"] = cells[f"{metric}_p"].to_numpy()
        table[f"{metric}: Holm p"] = cells[f"{metric}_holm"].to_numpy()
        table[f"{metric}: mark"] = cells[f"{metric}_mark"].to_numpy()
    return table
