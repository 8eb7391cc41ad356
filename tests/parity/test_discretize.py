"""The compiled uniform grid against ``gymnasium.wrappers.DiscretizeObservation``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import DiscretizeObservation

from rlcompare.envs import mountain_car
from rlcompare.envs.discretize import cell_index, cell_indices, cell_of, make_grid

BINS = [20, 7, 2, (10, 13), (1, 5)]


def _bins_id(bins) -> str:
    return "x".join(map(str, bins)) if isinstance(bins, tuple) else str(bins)


@pytest.fixture(scope="module")
def base_env():
    """Gymnasium's Mountain Car, shared by the tests of this module."""
    environment = gym.make(mountain_car.ENV_ID, max_episode_steps=200)
    yield environment
    environment.close()


@pytest.fixture(scope="module")
def rollout_observations(base_env) -> np.ndarray:
    """About 6,000 float32 observations from random and bang-bang Gymnasium episodes."""
    generator = np.random.default_rng(11)
    observations = []
    for episode in range(30):
        observation, _ = base_env.reset(seed=episode)
        observations.append(observation)
        for _ in range(200):
            velocity = observation[1]
            action = int(generator.integers(3)) if episode % 2 else (2 if velocity >= 0 else 0)
            observation, _, terminated, truncated, _ = base_env.step(action)
            observations.append(observation)
            if terminated or truncated:
                break
    result = np.array(observations)
    assert result.dtype == np.float32
    return result


@pytest.fixture(params=BINS, ids=[_bins_id(b) for b in BINS])
def bins(request):
    return request.param


@pytest.fixture
def wrapper(base_env, bins):
    return DiscretizeObservation(base_env, bins=bins)


@pytest.fixture
def grid(base_env, bins):
    space = base_env.observation_space
    return make_grid(space.low, space.high, bins)


def _assert_same_cells(grid, wrapper, observations: np.ndarray) -> None:
    observations = np.asarray(observations, dtype=np.float32)
    expected = np.array([wrapper.observation(o) for o in observations])
    flat = np.array([cell_index(grid, o) for o in observations])
    flat_2d = np.array([cell_of(grid, (float(o[0]), float(o[1]))) for o in observations])
    vectorised = cell_indices(grid, observations)
    mismatch = np.flatnonzero((flat != expected) | (flat_2d != expected) | (vectorised != expected))
    assert mismatch.size == 0, [(observations[i].tolist(), expected[i], flat[i], flat_2d[i]) for i in mismatch[:5]]
    assert np.all((expected >= 0) & (expected < grid.n_cells))


def test_grid_matches_wrapper_edges(grid, wrapper):
    """Same cell count, and the same inner edges (float32 values), padded with +inf."""
    assert grid.n_cells == wrapper.observation_space.n
    np.testing.assert_array_equal(grid.bins, wrapper.bins)
    for dim, edges in enumerate(wrapper.bin_edges):
        assert edges.dtype == np.float32
        np.testing.assert_array_equal(grid.edges[dim, : edges.size], edges.astype(np.float64))
        assert np.all(np.isposinf(grid.edges[dim, edges.size :]))


def test_module_bounds_give_the_same_grid(base_env):
    """``OBSERVATION_LOW/HIGH`` of the port build the grid Gymnasium's observation space builds."""
    space = base_env.observation_space
    ours = make_grid(mountain_car.OBSERVATION_LOW, mountain_car.OBSERVATION_HIGH, 20)
    theirs = make_grid(space.low, space.high, 20)
    for a, b in zip(ours, theirs, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow("compiles or trains for a second or more")
def test_rollout_observations(grid, wrapper, rollout_observations):
    """Every observation of real Gymnasium episodes lands in the wrapper's cell."""
    _assert_same_cells(grid, wrapper, rollout_observations)
    assert len(np.unique([wrapper.observation(o) for o in rollout_observations])) > 1


def _edge_cases(low: np.ndarray, high: np.ndarray, edges: list[np.ndarray]) -> list[np.ndarray]:
    """For each dimension, values on and one float32 ulp either side of every edge and bound, and outside."""
    per_dim = []
    for dim in range(low.size):
        lo, hi = low[dim], high[dim]
        points = [*edges[dim], lo, hi]
        values = [np.float32(0.0), np.float32(-0.0), np.float32(np.inf), np.float32(-np.inf)]
        values += [lo - np.float32(1.0), hi + np.float32(1.0), lo * np.float32(3), hi * np.float32(3)]
        for point in points:
            point = np.float32(point)
            values += [
                point,
                np.nextafter(point, np.float32(-np.inf)),
                np.nextafter(point, np.float32(np.inf)),
            ]
            values += [np.nextafter(np.nextafter(point, np.float32(np.inf)), np.float32(np.inf))]
        per_dim.append(np.array(values, dtype=np.float32))
    return per_dim


def test_edges_bounds_and_outside(grid, wrapper):
    """Values on every edge, one float32 ulp either side, the bounds, and beyond them in both directions."""
    low, high = wrapper.low, wrapper.high
    dim0, dim1 = _edge_cases(low, high, wrapper.bin_edges)
    # Each edge value of one dimension, paired with a mid value and with every edge value of the other.
    middle = (low + high) / 2
    observations = [(x, middle[1]) for x in dim0] + [(middle[0], y) for y in dim1]
    observations += [(x, y) for x in dim0[::3] for y in dim1[::3]]
    _assert_same_cells(grid, wrapper, np.array(observations, dtype=np.float32))


def test_cell_on_edge_is_the_upper_one(grid, wrapper):
    """An observation exactly on an edge belongs to the cell above it (``np.digitize``, right=False)."""
    low = wrapper.low
    checked = 0
    for dim, edges in enumerate(wrapper.bin_edges):
        for k, edge in enumerate(edges):
            for value, cell in ((edge, k + 1), (np.nextafter(edge, np.float32(-np.inf)), k)):
                observation = low.copy()
                observation[dim] = value
                flat = cell_index(grid, observation)
                assert np.unravel_index(flat, tuple(grid.bins))[dim] == cell
                checked += 1
    assert checked == 2 * sum(edges.size for edges in wrapper.bin_edges)


def test_float64_state_is_rounded_to_float32(grid, wrapper):
    """``cell_of`` on the float64 state equals the wrapper on Gymnasium's float32 observation."""
    generator = np.random.default_rng(3)
    states = np.column_stack([generator.uniform(-1.3, 0.7, 3000), generator.uniform(-0.08, 0.08, 3000)])
    # Include float64 values just beside float32 edges, where rounding decides the cell.
    for edge in wrapper.bin_edges[0]:
        states = np.vstack([states, [float(edge) - 1e-12, 0.0], [float(edge) + 1e-12, 0.0]])
    expected = [wrapper.observation(np.array(s, dtype=np.float32)) for s in states]
    got = [cell_of(grid, (float(p), float(v))) for p, v in states]
    assert got == expected


def test_make_grid_rejects_infinite_bounds():
    """A uniform grid needs finite bounds, as Gymnasium's wrapper does."""
    with pytest.raises(ValueError, match="finite"):
        make_grid(np.array([0.0, -np.inf], dtype=np.float32), np.array([1.0, 1.0], dtype=np.float32), 4)
