"""Figures are checked for what they show: lines, bands, labels and the values behind each image."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from rlcompare.report import plots
from rlcompare.stats.curves import mean_band, moving_average, thinned
from rlcompare.studies.start_region import map_frame
from rlcompare.tabular.config import ExperimentConfig

FRAME = map_frame(ExperimentConfig())  # MountainCar-v0 on the paper's grid


@pytest.fixture
def ax():
    return Figure().subplots()


def test_moving_average_on_a_hand_example() -> None:
    np.testing.assert_allclose(moving_average(np.array([2.0, 4.0, 6.0, 8.0]), 2), [2.0, 3.0, 5.0, 7.0])
    np.testing.assert_allclose(moving_average(np.array([[1.0, 2.0, 3.0]]), 5), [[1.0, 1.5, 2.0]])


def test_thinned_keeps_ends_and_bounds_the_count() -> None:
    keep = thinned(5000, 500)
    assert len(keep) <= 500
    assert (keep[0], keep[-1]) == (0, 4999)
    np.testing.assert_array_equal(thinned(7, 500), np.arange(7))


def test_mean_band_brackets_the_mean_and_shrinks_with_agreement() -> None:
    rng = np.random.default_rng(0)
    noisy = rng.normal(0, 10, size=(30, 50))
    mean, low, high = mean_band(noisy)
    np.testing.assert_allclose(mean, noisy.mean(axis=0))
    assert np.all(low <= mean)
    assert np.all(mean <= high)
    half_width = (high - low).mean() / 2
    assert 1.96 * 10 / np.sqrt(30) * 0.7 < half_width < 1.96 * 10 / np.sqrt(30) * 1.3  # about the normal width
    _, same_low, same_high = mean_band(np.ones((5, 10)))
    np.testing.assert_array_equal(same_low, same_high)


def test_return_curves_draw_one_line_and_one_band_per_label(ax) -> None:
    rng = np.random.default_rng(1)
    curves = {"Q-Learning": rng.normal(-300, 20, (6, 400)), "SARSA": rng.normal(-200, 20, (6, 400))}
    plots.plot_return_curves(ax, np.arange(1, 401), curves, window=10)
    assert [line.get_label() for line in ax.get_lines()] == ["Q-Learning", "SARSA"]
    assert sum(isinstance(c, PolyCollection) for c in ax.collections) == 2
    assert ax.get_xlabel() == "episode"
    assert "return" in ax.get_ylabel()
    sarsa_y = ax.get_lines()[1].get_ydata()
    assert abs(np.mean(sarsa_y) + 200) < 10
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["Q-Learning", "SARSA"]


def _tables_with_greedy(actions: list[int], cells: int = 4, seeds: int = 3) -> np.ndarray:
    q = np.zeros((seeds, cells, 3))
    for cell, action in enumerate(actions):
        q[:, cell] = -5.0
        q[:, cell, action] = -1.0
    return q


def test_policy_map_shows_the_majority_action_and_blanks_unvisited_cells(ax) -> None:
    q = _tables_with_greedy([2, 0, 1])  # cell 3 never updated
    q[0, 0] = [-1.0, -5.0, -5.0]  # one seed of three disagrees in cell 0
    plots.plot_policy_map(ax, q, bins=2, frame=FRAME)
    image = ax.get_images()[0].get_array()
    # cells are position_bin * 2 + velocity_bin; the image has velocity on rows
    assert image[0, 0] == 2  # cell 0: two seeds of three push right
    assert image[1, 0] == 0  # cell 1
    assert image[0, 1] == 1  # cell 2
    assert np.ma.is_masked(image[1, 1]) or np.isnan(image[1, 1])  # cell 3: blank
    assert ax.get_xlabel() == "position"
    assert ax.get_ylabel() == "velocity"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == list(FRAME.actions)


def test_value_map_averages_the_best_value_over_seeds(ax) -> None:
    q = _tables_with_greedy([0, 1, 2])
    q[1, :3] -= 2.0  # seed 1 values every visited cell 2 lower
    plots.plot_value_map(ax, q, bins=2, frame=FRAME)
    image = ax.get_images()[0].get_array()
    assert image[0, 0] == pytest.approx((-1 - 3 - 1) / 3)
    assert np.ma.is_masked(image[1, 1]) or np.isnan(image[1, 1])


def _blank(ax) -> np.ndarray:
    """The cells a map leaves transparent: masked or NaN in its image (the map's own, drawn first)."""
    image = ax.images[0].get_array()
    return np.ma.getmaskarray(image) | np.isnan(np.ma.getdata(image))


def test_value_map_masks_unvisited_cells_and_hatches_rarely_visited_ones(ax) -> None:
    q = _tables_with_greedy([0, 1, 2])  # cells 0-2 updated by every seed; cell 3 by none at this snapshot
    visits = np.array([[50, 50, 3, 0], [50, 50, 5, 0], [50, 50, 1, 0]])  # cell 2: 3 a seed; cell 3: never
    plots.plot_value_map(ax, q, bins=2, frame=FRAME, vmin=-5.0, visits=visits, few_visits=20)
    # cells are position_bin * 2 + velocity_bin; the image has velocity on rows
    np.testing.assert_array_equal(_blank(ax), [[False, False], [False, True]])
    assert ax.images[0].get_array()[0, 1] == pytest.approx(-1.0)  # a rarely visited cell keeps its value ...
    assert ax.images[0].norm.vmin == -5.0
    assert ax.images[0].norm.vmax == 0.0  # ... on the same scale
    hatched = [c for c in ax.collections if c.get_gid() == "few-visits"]
    assert len(hatched) == 1
    (box,) = hatched[0].get_paths()
    x_mid, y_mid = box.get_extents().get_points().mean(axis=0)
    assert x_mid > (FRAME.extent[0] + FRAME.extent[1]) / 2 > FRAME.extent[0]  # cell 2: the right column ...
    assert y_mid < (FRAME.extent[2] + FRAME.extent[3]) / 2  # ... bottom row
    assert len(ax.images) == 1  # no cell is visited only later: nothing drawn beneath
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["never visited", "fewer than 20 visits a seed: value still near its initial 0"]


def test_maps_tell_cells_visited_later_from_cells_never_visited(ax) -> None:
    q = _tables_with_greedy([0, 1])  # cells 2 and 3 not updated at this snapshot
    visits = np.array([[50, 50, 40, 0], [50, 50, 30, 0]])  # cell 2 is visited after it, cell 3 never
    plots.plot_policy_map(ax, q[:2], bins=2, frame=FRAME, visits=visits, few_visits=20)
    np.testing.assert_array_equal(_blank(ax), [[False, True], [False, True]])
    beneath = ax.images[1]
    assert beneath.get_zorder() < ax.images[0].get_zorder()
    drawn_beneath = ~(np.ma.getmaskarray(beneath.get_array()) | np.isnan(np.ma.getdata(beneath.get_array())))
    np.testing.assert_array_equal(drawn_beneath, [[False, True], [False, False]])  # cell 2 only: grey
    assert not [c for c in ax.collections if c.get_gid() == "few-visits"]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == [*FRAME.actions, "never visited", "not visited yet"]
    bare = Figure().subplots()
    plots.plot_policy_map(bare, q[:2], bins=2, frame=FRAME, visits=visits, legend=False)
    assert bare.get_legend() is None


def test_visits_are_summed_over_seeds(ax) -> None:
    visits = np.array([[1, 0, 5, 0], [2, 0, 5, 0]])
    plots.plot_visits(ax, visits, bins=2, frame=FRAME)
    image = ax.get_images()[0].get_array()
    assert image[0, 0] == 3
    assert image[0, 1] == 10
    assert np.ma.is_masked(image[1, 0]) or np.isnan(image[1, 0])


def test_first_actions_stack_to_one(ax) -> None:
    shares = {"Q-Learning": np.array([0.2, 0.1, 0.7]), "SARSA": np.array([0.6, 0.0, 0.4])}
    plots.plot_first_actions(ax, shares, FRAME.actions)
    bars = ax.patches
    assert len(bars) == 6
    tops = {}
    for bar in bars:
        tops[bar.get_x()] = max(tops.get(bar.get_x(), 0), bar.get_y() + bar.get_height())
    assert all(top == pytest.approx(1.0) for top in tops.values())


def test_maps_take_their_frame_from_the_environment() -> None:
    assert FRAME.axes == ("position", "velocity")
    assert FRAME.actions == ("push left", "no push", "push right")
    assert FRAME.extent == pytest.approx((-1.2, 0.6, -0.07, 0.07))
    assert map_frame(ExperimentConfig(env="MountainCar-book")).extent[1] == pytest.approx(0.5)  # the book's bound
    assert map_frame(ExperimentConfig(env="CartPole-v1")) is None  # no maps where the environment names no axes
    assert map_frame(ExperimentConfig(features="tiles")) is None
