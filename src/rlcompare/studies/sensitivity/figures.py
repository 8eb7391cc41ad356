"""The sensitivity study's heatmaps: SARSA minus Q-Learning in every cell of the cross (a panel per time limit and
γ, α x ε_end) and of the schedule block (ε schedule x γ), coloured by the difference and marked by its verdict."""

from __future__ import annotations

from typing import Literal

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.image import AxesImage

from rlcompare.studies.sensitivity.grid import (
    LEVEL,
    METRICS,
    Q_BETTER,
    SARSA_BETTER,
    SCHEDULE_BLOCK,
)
from rlcompare.studies.sensitivity.words import (
    SHORT_MARKS,
    cross_cells,
    schedule_cells,
    schedule_label,
    schedule_rows,
    seeds_text,
    setting,
    value_text,
)


def _norm(cells: pd.DataFrame, metric: str) -> Normalize:
    """Diverging, centred on 0, as wide as the largest difference."""
    values = cells[f"{metric}_difference"].to_numpy(dtype=np.float64)
    largest = float(np.nanmax(np.abs(values))) if np.isfinite(values).any() else 1.0
    return Normalize(-largest or -1.0, largest or 1.0)


def _title(cells: pd.DataFrame, metric: str, what: str) -> str:
    return (f"{METRICS[metric].capitalize()}: SARSA - Q-Learning{what}, mean over {seeds_text(cells)} paired seeds; "
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
    images = [_cross_panel(axes[i, j], cross, metric, norm, truncation, gamma, alphas, ends)
              for i, truncation in enumerate(rows) for j, gamma in enumerate(columns)]
    figure.colorbar(images[-1], ax=axes, shrink=0.8, label="SARSA - Q-Learning (return)")
    figure.suptitle(_title(cells, metric, ", ε decaying from 1"))
    return figure


def _cross_panel(ax: Axes, cross: pd.DataFrame, metric: str, norm: Normalize, truncation: bool, gamma: float,
                 alphas: list[float], ends: list[float]) -> AxesImage:
    """The panel of the cross at one time limit and γ: α x ε_end cells, drawn by :func:`_draw`."""
    panel = cross[(cross["truncation_as_terminal"] == truncation) & (cross["gamma"] == gamma)]
    grid = np.full((len(ends), len(alphas)), np.nan)
    marks = np.full(grid.shape, "", dtype=object)
    for row in panel.to_dict("records"):
        at = (ends.index(row["epsilon_end"]), alphas.index(row["alpha"]))
        grid[at], marks[at] = row[f"{metric}_difference"], row[f"{metric}_mark"]
    image = _draw(ax, grid, marks, norm, origin="lower")
    ax.set_xticks(range(len(alphas)), [f"{a:g}" for a in alphas])
    ax.set_yticks(range(len(ends)), [f"{e:g}" for e in ends])
    ax.set_xlabel("α")
    ax.set_ylabel("ε_end")
    ax.set_title(f"γ = {gamma:g}, time limit {value_text('truncation_as_terminal', truncation)}", fontsize="medium")
    return image


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


def _draw(ax: Axes, grid: np.ndarray, marks: np.ndarray, norm: Normalize, origin: Literal["upper", "lower"]
          ) -> AxesImage:
    """The cells of one panel, each annotated with its difference and mark (bold where resolved)."""
    image = ax.imshow(grid, cmap="RdBu", norm=norm, origin=origin, aspect="auto")
    for (y, x), value in np.ndenumerate(grid):
        mark = str(marks[y, x])
        text = "n/a" if np.isnan(value) else f"{value:+.1f}\n{SHORT_MARKS.get(mark, '')}"
        strong = np.isfinite(value) and abs(norm(value) - 0.5) > 0.3
        ax.text(x, y, text, ha="center", va="center", fontsize="x-small", color="white" if strong else "black",
                fontweight="bold" if mark in (SARSA_BETTER, Q_BETTER) else "normal")
    return image


