"""Figures of a comparison. Every function draws on the ``ax`` it is given and returns it; only a study
or the command line saves files."""

from __future__ import annotations

from typing import overload

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.collections import PatchCollection
from matplotlib.colorbar import Colorbar
from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm
from matplotlib.figure import Figure
from matplotlib.patches import Patch, Rectangle
from mpl_toolkits.axes_grid1 import make_axes_locatable

from rlcompare.report.map_frame import MapFrame
from rlcompare.stats.curves import mean_band, moving_average, thinned
from rlcompare.stats.intervals import Estimate, interval

ACTION_COLORS = ("#3b6fb6", "#bdbdbd", "#d1495b")


def plot_return_curves(
    ax: Axes, x: np.ndarray, curves: dict[str, np.ndarray], *, window: int = 100,
    colors: dict[str, str] | None = None, ylabel: str = "return per episode",
) -> Axes:
    """Smoothed mean return over seeds with a shaded 95% bootstrap band, one line per label.

    ``curves[label]`` is ``(seeds, points)``, plotted against ``x``; ``window`` smooths each seed first.
    """
    for label, values in curves.items():
        smooth = moving_average(values, window) if window > 1 else np.asarray(values, dtype=np.float64)
        keep = thinned(smooth.shape[1])
        mean, low, high = mean_band(smooth[:, keep])
        color = (colors or {}).get(label)
        (line,) = ax.plot(x[keep], mean, label=label, color=color, linewidth=1.5)
        ax.fill_between(x[keep], low, high, color=line.get_color(), alpha=0.25, linewidth=0)
    ax.set_xlabel("episode")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize="small")
    return ax


def _cell_grid(values: np.ndarray, bins: int) -> np.ndarray:
    """Flat cells ``x_bin * bins + y_bin`` to an image with the second dimension on rows."""
    return np.asarray(values).reshape(bins, bins).T


def _label_axes(ax: Axes, frame: MapFrame) -> None:
    ax.set_xlabel(frame.axes[0])
    ax.set_ylabel(frame.axes[1])


def plot_policy_map(ax: Axes, q_tables: np.ndarray, bins: int, frame: MapFrame, *, visits: np.ndarray | None = None,
                    few_visits: float = 0.0, legend: bool = True) -> Axes:
    """Greedy action in each cell, by majority over the seeds that updated it; cells none updated are blank.

    ``q_tables`` is ``(seeds, cells, actions)``. A fresh table holds zeros and every update with a reward
    of -1 makes a value negative, so an all-zero row marks a cell that was never updated. ``visits`` and
    ``few_visits`` mark the cells visited never, later or rarely (:func:`mark_visits`); ``legend=False`` leaves
    the key to the figure (:func:`action_handles`, :func:`visit_handles`).
    """
    greedy = q_tables.argmax(axis=2)
    updated = np.any(q_tables != 0, axis=2)  # a seed that never updated a cell has no say in it
    counts = np.stack([((greedy == a) & updated).sum(axis=0) for a in range(q_tables.shape[2])])
    majority = counts.argmax(axis=0).astype(np.float64)
    majority[~np.any(q_tables != 0, axis=(0, 2))] = np.nan
    cmap = ListedColormap(ACTION_COLORS).with_extremes(bad=(0, 0, 0, 0))  # blank: what lies beneath shows
    ax.imshow(_cell_grid(majority, bins), origin="lower", extent=frame.extent, aspect="auto", cmap=cmap,
              norm=BoundaryNorm([-0.5, 0.5, 1.5, 2.5], cmap.N), interpolation="nearest", zorder=1)
    marks = mark_visits(ax, np.isnan(majority), bins, frame, visits, few_visits)
    if legend:
        ax.legend(handles=action_handles(frame) + marks, loc="upper left", fontsize="x-small", framealpha=0.8)
    _label_axes(ax, frame)
    return ax


def plot_value_map(ax: Axes, q_tables: np.ndarray, bins: int, frame: MapFrame, *, vmin: float | None = None,
                   visits: np.ndarray | None = None, few_visits: float = 0.0, legend: bool = True) -> Axes:
    """State value ``max_a Q(s, a)`` averaged over seeds; never-updated cells blank. ``visits``, ``few_visits``
    and ``legend`` as for :func:`plot_policy_map`."""
    values = q_tables.max(axis=2).mean(axis=0)
    values[~np.any(q_tables != 0, axis=(0, 2))] = np.nan
    cmap = mpl.colormaps["viridis"].with_extremes(bad=(0, 0, 0, 0))
    image = ax.imshow(_cell_grid(values, bins), origin="lower", extent=frame.extent, aspect="auto", cmap=cmap,
                      vmin=vmin, vmax=0.0, interpolation="nearest", zorder=1)
    colorbar_beside(ax, image, "max_a Q(s, a)")
    marks = mark_visits(ax, np.isnan(values), bins, frame, visits, few_visits)
    if legend and marks:
        ax.legend(handles=marks, loc="upper left", fontsize="x-small", framealpha=0.8)
    _label_axes(ax, frame)
    return ax


NOT_YET = "#e6e6e6"
"""The fill of a map's cells that training visits only after the map's snapshot; cells it never visits stay
white."""
FEW_HATCH = (0.0, 0.0, 0.0, 0.55)


def action_handles(frame: MapFrame) -> list[Patch]:
    """The key to a policy map's colours."""
    return [Patch(color=c, label=n) for c, n in zip(ACTION_COLORS, frame.actions, strict=True)]


def visit_handles(few_visits: float = 0.0) -> list[Patch]:
    """The key to :func:`mark_visits`."""
    handles = [Patch(facecolor="white", edgecolor="#999999", linewidth=0.5, label="never visited"),
               Patch(facecolor=NOT_YET, label="not visited yet")]
    if few_visits > 0:
        handles.append(Patch(facecolor="white", edgecolor=FEW_HATCH, hatch="////", linewidth=0,
                             label=f"fewer than {few_visits:g} visits a seed: value still near its initial 0"))
    return handles


def mark_visits(ax: Axes, blank: np.ndarray, bins: int, frame: MapFrame, visits: np.ndarray | None,
                few_visits: float = 0.0) -> list[Patch]:
    """What a map's ``blank`` cells (transparent in its image) and its rarely visited cells are, from ``visits``
    (``(seeds, cells)``, steps taken from each cell in all of training): cells no seed ever visited stay white,
    cells visited only after the map's snapshot are filled light grey (:data:`NOT_YET`) beneath the image, and
    cells visited fewer than ``few_visits`` times a seed on average are hatched over it. Returns the key's
    entries (:func:`visit_handles`) of what is on this map."""
    if visits is None:
        return []
    never = np.asarray(visits).sum(axis=0) == 0
    later = blank & ~never
    few = ~never & ~blank & (np.asarray(visits).mean(axis=0) < few_visits)
    if later.any():
        ax.imshow(_cell_grid(np.where(later, 1.0, np.nan), bins), origin="lower", extent=frame.extent,
                  aspect="auto", cmap=ListedColormap([NOT_YET]), vmin=0, vmax=1, interpolation="nearest",
                  zorder=0.5)
    if few.any():
        x_low, x_high, y_low, y_high = frame.extent
        width, height = (x_high - x_low) / bins, (y_high - y_low) / bins
        boxes = [Rectangle((x_low + (cell // bins) * width, y_low + (cell % bins) * height), width, height)
                 for cell in np.flatnonzero(few)]  # cells are x_bin * bins + y_bin
        ax.add_collection(PatchCollection(boxes, facecolor="none", edgecolor=FEW_HATCH, hatch="////", linewidth=0,
                                          zorder=2, gid="few-visits"))
    never_handle, later_handle, *few_handle = visit_handles(few_visits)
    return ([never_handle] * bool(never.any()) + [later_handle] * bool(later.any())
            + few_handle * bool(few.any()))


def plot_visits(ax: Axes, visits: np.ndarray, bins: int, frame: MapFrame) -> Axes:
    """Training steps taken from each cell, summed over seeds, on a log scale; unvisited cells blank."""
    total = visits.sum(axis=0).astype(np.float64)
    total[total == 0] = np.nan
    image = ax.imshow(_cell_grid(total, bins), origin="lower", extent=frame.extent, aspect="auto", cmap="magma",
                      norm=LogNorm(), interpolation="nearest")
    colorbar_beside(ax, image, "steps from cell (all seeds)").minorticks_off()  # a tick a decade
    _label_axes(ax, frame)
    return ax


@overload
def colorbar_beside(ax: Axes, image: ScalarMappable, label: str = "") -> Colorbar: ...


@overload
def colorbar_beside(ax: Axes, image: None, label: str = "") -> None: ...


def colorbar_beside(ax: Axes, image: ScalarMappable | None, label: str = "") -> Colorbar | None:
    """A colorbar in a slot cut from the right of ``ax``; with no ``image`` the slot is cut and left empty, so
    that maps in one column of a figure keep one width. The slot's size is fixed, so a figure of maps can be
    laid out once by hand (:func:`map_layout`)."""
    slot = make_axes_locatable(ax).append_axes("right", size="5%", pad=0.08)
    if image is None:
        slot.set_axis_off()
        return None
    return ax.figure.colorbar(image, cax=slot, label=label)


def fixed_layout(figure: Figure, rows: int, columns: int, *, left: float, right: float, bottom: float, top: float,
                 column_gap: float = 0.0, row_gap: float = 0.0) -> None:
    """Place a ``rows`` x ``columns`` grid of axes with margins and gaps given in inches, the room their labels
    take: once, by hand, where the constrained layout measured every label on every draw and took longer than
    drawing the figure."""
    width, height = figure.get_size_inches()
    axes_width = (width - left - right - (columns - 1) * column_gap) / columns
    axes_height = (height - bottom - top - (rows - 1) * row_gap) / rows
    figure.subplots_adjust(left=left / width, right=1 - right / width, bottom=bottom / height, top=1 - top / height,
                           wspace=column_gap / axes_width, hspace=row_gap / axes_height)


def map_layout(figure: Figure, rows: int, columns: int) -> None:
    """A grid of maps with colorbars beside them (:func:`colorbar_beside`): room for each map's tick labels and
    axis names, its colorbar's labels, and the titles above."""
    fixed_layout(figure, rows, columns, left=0.8, right=0.65, bottom=0.5, top=0.65, column_gap=1.4, row_gap=0.8)


def plot_first_actions(ax: Axes, shares: dict[str, np.ndarray], actions: tuple[str, ...]) -> Axes:
    """Stacked bars: the share of start states from which each configuration's first greedy action is each
    of ``actions`` (``shares[label]`` sums to 1 over them)."""
    labels = list(shares)
    bottom = np.zeros(len(labels))
    for action, (name, color) in enumerate(zip(actions, ACTION_COLORS, strict=True)):
        heights = np.array([shares[label][action] for label in labels])
        ax.bar(labels, heights, bottom=bottom, color=color, label=name)
        bottom += heights
    ax.set_ylim(0, 1)
    ax.set_ylabel("share of start states")
    ax.legend(loc="upper right", fontsize="small")
    ax.tick_params(axis="x", labelrotation=15)
    return ax


def plot_paired_differences(ax: Axes, differences: dict[str, np.ndarray], labels: dict[str, str] | None = None
                            ) -> dict[str, Estimate]:
    """Each group's per-seed paired differences as dots, their mean with its 95% BCa interval as a bar beside
    them (:func:`~rlcompare.stats.intervals.interval`, as the verdicts use), the numbers written beside it, and a
    line at 0; a group with a value that is not finite is left out. The dots' and bars' artists have the gids
    ``seeds-<key>`` and ``interval-<key>``. Returns each drawn group's estimate."""
    drawn = {}
    for position, (key, values) in enumerate(differences.items()):
        values = np.asarray(values, dtype=np.float64)
        if not np.isfinite(values).all():
            continue
        estimate = drawn[key] = interval(values)
        jitter = ((np.arange(values.size) * 0.618034) % 1 - 0.5) * 0.24  # evenly spread, in seed order
        ax.scatter(position - 0.1 + jitter, values, s=22, color="#3b6fb6", alpha=0.75, linewidths=0, zorder=3,
                   gid=f"seeds-{key}", label="one seed" if len(drawn) == 1 else None)
        low, high = (estimate.low, estimate.high) if np.isfinite(estimate.low) else (estimate.value,) * 2
        bar = ax.errorbar([position + 0.2], [estimate.value], yerr=[[estimate.value - low], [high - estimate.value]],
                          fmt="o", color="black", capsize=5, linewidth=1.6, zorder=4,
                          label="mean, 95% BCa interval" if len(drawn) == 1 else None)
        bar.lines[2][0].set_gid(f"interval-{key}")
        ax.annotate(f"{estimate.value:+.1f}\n[{low:.1f}, {high:.1f}]", (position + 0.28, estimate.value),
                    fontsize="small", va="center")
    ax.axhline(0, color="black", linewidth=0.8, zorder=1)
    ax.set_xticks(range(len(differences)), [(labels or {}).get(key, key) for key in differences])
    ax.set_xlim(-0.4, len(differences) - 0.25)
    ax.grid(alpha=0.3, axis="y")
    return drawn
