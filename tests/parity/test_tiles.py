"""Tile coding (Sutton and Barto, section 9.5.4) against its spec: partition, sharing, offsets, hashing."""

from __future__ import annotations

import numpy as np
import pytest

from rlcompare.envs import mountain_car
from rlcompare.envs.tiles import TileCoding, active_tiles_at, active_tiles_nd, make_tile_coding

MC_LOW = mountain_car.OBSERVATION_LOW
MC_HIGH = mountain_car.OBSERVATION_HIGH

LAYOUTS = {
    "mountain-car-8x8x8": ((-1.2, -0.07), (0.6, 0.07), {}),
    "2d-4-tilings-5x3": ((0.0, -1.0), (2.0, 1.0), {"tilings": 4, "tiles": (5, 3)}),
    "1d-16x10": ((-1.0,), (3.0,), {"tilings": 16, "tiles": 10}),
    "3d-16-tilings-4x5x6": ((0.0, -2.0, 10.0), (1.0, 2.0, 11.5), {"tilings": 16, "tiles": (4, 5, 6)}),
}


@pytest.fixture(params=list(LAYOUTS), scope="module")
def layout(request) -> TileCoding:
    low, high, kwargs = LAYOUTS[request.param]
    return make_tile_coding(low, high, **kwargs)


def _high(coding: TileCoding) -> np.ndarray:
    return coding.low + coding.tiles / coding.scale


def _features(coding: TileCoding, points: np.ndarray, function=active_tiles_nd) -> np.ndarray:
    """``(n, tilings)`` active features of each point."""
    out = np.zeros((len(points), coding.n_tilings), dtype=np.int64)
    for i, point in enumerate(points):
        function(coding, np.ascontiguousarray(point, dtype=np.float64), out[i])
    return out


def _features_at(coding: TileCoding, points: np.ndarray, function=active_tiles_at) -> np.ndarray:
    """The same, written row by row into one array, as the kernels do."""
    out = np.zeros((len(points), coding.n_tilings), dtype=np.int64)
    for i, point in enumerate(points):
        function(coding, np.ascontiguousarray(point, dtype=np.float64), out, i)
    return out


def _test_points(low: np.ndarray, high: np.ndarray, seed: int) -> np.ndarray:
    """Random points inside the box, on its faces and corners (and one ulp either side), and outside."""
    generator = np.random.default_rng(seed)
    dims = low.size
    width = high - low
    inside = generator.uniform(low, high, (400, dims))
    # Each coordinate drawn from {low, high, an ulp inside or outside either bound, a random inner value}.
    choices = np.stack([low, high, np.nextafter(low, -np.inf), np.nextafter(low, np.inf),
                        np.nextafter(high, -np.inf), np.nextafter(high, np.inf)])
    pick = generator.integers(0, 7, (300, dims))
    edges = generator.uniform(low, high, (300, dims))
    for d in range(dims):
        on_edge = pick[:, d] < 6
        edges[on_edge, d] = choices[pick[on_edge, d], d]
    outside = generator.uniform(low - 2 * width, high + 2 * width, (300, dims))
    infinite = np.where(generator.integers(0, 2, (20, dims)) == 1, np.inf, -np.inf)
    return np.vstack([inside, edges, outside, infinite])


def _reference_coordinates(coding: TileCoding, points: np.ndarray) -> np.ndarray:
    """``(n, tilings, dims)`` tile coordinates straight from the spec, in numpy."""
    scaled = (points[:, None, :] - coding.low) * coding.scale + coding.offsets[None, :, :]
    with np.errstate(invalid="ignore"):
        return np.clip(np.floor(scaled), 0, coding.tiles).astype(np.int64)


def test_one_tile_per_tiling(layout):
    """Every point, inside, on the edges or outside the box, activates exactly one tile of each tiling."""
    points = _test_points(layout.low, _high(layout), seed=1)
    features = _features(layout, points)
    tilings = np.arange(layout.n_tilings)
    assert layout.n_features == layout.n_tilings * layout.per_tiling == layout.n_tilings * np.prod(layout.tiles + 1)
    assert np.all(features >= tilings * layout.per_tiling)
    assert np.all(features < (tilings + 1) * layout.per_tiling)
    assert all(len(set(row)) == layout.n_tilings for row in features.tolist())
    # The index is the row-major flattening of the clipped coordinates of the spec.
    coordinates = _reference_coordinates(layout, points)
    expected = tilings * layout.per_tiling + np.ravel_multi_index(
        np.moveaxis(coordinates, -1, 0), tuple(layout.tiles + 1))
    np.testing.assert_array_equal(features, expected)


def test_bounds_land_in_the_first_and_last_tiles(layout):
    """On or beyond ``high`` is the last tile (``tiles``), on or below ``low`` the first (0), in every tiling;
    NaN is the first."""
    high = _high(layout)
    points = np.vstack([high, high + 1.0, np.full(high.size, np.inf), layout.low, layout.low - 1.0,
                        np.full(high.size, -np.inf), np.full(high.size, np.nan)])
    features = _features(layout, points) - np.arange(layout.n_tilings) * layout.per_tiling
    last = np.ravel_multi_index(tuple(layout.tiles), tuple(layout.tiles + 1))
    assert np.all(features[:3] == last)
    assert np.all(features[3:] == 0)


def test_upper_bound_is_the_last_tile_for_awkward_bounds():
    """``x == high`` lands in tile ``tiles`` of the undisplaced tiling even where ``tiles / (high - low)``
    rounds down (about one bounds-and-tiles draw in fifteen)."""
    generator = np.random.default_rng(5)
    for _ in range(300):
        low, high = np.sort(generator.uniform(-3.0, 3.0, 2))
        tiles = int(generator.integers(1, 20))
        coding = make_tile_coding((low,), (high,), tilings=1, tiles=tiles)
        out = np.zeros(1, dtype=np.int64)
        active_tiles_nd(coding, np.array([high]), out)
        assert out[0] == tiles, (low, high, tiles)
        # Just below: the tile before (an ulp or two below may round up, as floating point allows).
        active_tiles_nd(coding, np.array([high - 1e-9 * (high - low)]), out)
        assert out[0] == tiles - 1, (low, high, tiles)


@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("distance", [0.0, 0.25, 0.3, 0.5, 0.8])
def test_near_points_share_one_minus_distance_of_their_tilings(axis, distance):
    """Points ``distance`` tile widths apart along one axis share on average ``1 - distance`` of the tilings."""
    coding = make_tile_coding(MC_LOW, MC_HIGH)
    width = 1.0 / coding.scale
    generator = np.random.default_rng(17 + axis)
    # Far enough from the bounds that clipping plays no part.
    points = generator.uniform(coding.low + width, _high(coding) - 2 * width, (1000, 2))
    moved = points.copy()
    moved[:, axis] += distance * width[axis]
    shared = np.mean(_features_at(coding, points) == _features_at(coding, moved))
    assert shared == pytest.approx(1.0 - distance, abs=0.1)


@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("distance", [1.001, 1.5, 3.0])
def test_points_a_tile_apart_share_nothing(axis, distance):
    """Points more than one tile width apart along an axis share no tile in any tiling."""
    coding = make_tile_coding(MC_LOW, MC_HIGH)
    width = 1.0 / coding.scale
    generator = np.random.default_rng(29 + axis)
    points = generator.uniform(coding.low, _high(coding), (500, 2))
    moved = points.copy()
    moved[:, axis] += np.where(points[:, axis] < (coding.low[axis] + _high(coding)[axis]) / 2, 1, -1) * (
        distance * width[axis])
    assert not np.any(_features_at(coding, points) == _features_at(coding, moved))


def test_offsets_are_the_books_asymmetric_displacement():
    """8 tilings in 2-D: tiling ``t`` is displaced by ``(t * 1 / 8, t * 3 / 8)`` tiles, mod 1."""
    coding = make_tile_coding(MC_LOW, MC_HIGH)
    expected = np.array([((t * 1 / 8) % 1, (t * 3 / 8) % 1) for t in range(8)])
    np.testing.assert_array_equal(coding.offsets, expected)
    assert coding.n_tilings == 8
    np.testing.assert_array_equal(coding.tiles, [8, 8])
    assert coding.per_tiling == 81
    assert coding.n_features == 648
    # Each axis sees the eight distinct displacements k / 8, so the tilings differ along both.
    for d in range(2):
        np.testing.assert_array_equal(np.sort(coding.offsets[:, d]), np.arange(8) / 8)
    # 3-D default displacement (1, 3, 5) and an explicit one.
    three = make_tile_coding((0, 0, 0), (1, 1, 1), tilings=16, tiles=4)
    np.testing.assert_array_equal(three.offsets[3], [3 / 16, 9 / 16, 15 / 16])
    diagonal = make_tile_coding(MC_LOW, MC_HIGH, tilings=4, displacement=(1, 1))
    np.testing.assert_array_equal(diagonal.offsets, [[0, 0], [0.25, 0.25], [0.5, 0.5], [0.75, 0.75]])


def test_hand_computed_example():
    """Two tilings of 2 x 2 tiles over the unit square, the point (0.3, 0.8)."""
    coding = make_tile_coding((0.0, 0.0), (1.0, 1.0), tilings=2, tiles=2)
    # scale = 2 tiles per unit; offsets: t=0 -> (0, 0); t=1 -> (1*1/2 mod 1, 1*3/2 mod 1) = (0.5, 0.5).
    # per_tiling = (2+1) * (2+1) = 9; strides = (3, 1).
    # t=0: (0.3*2 + 0, 0.8*2 + 0) = (0.6, 1.6) -> floor (0, 1) -> 0*3 + 1 = 1   -> feature 0*9 + 1 = 1
    # t=1: (0.6 + 0.5, 1.6 + 0.5) = (1.1, 2.1) -> floor (1, 2) -> 1*3 + 2 = 5 -> feature 1*9 + 5 = 14
    np.testing.assert_array_equal(coding.offsets, [[0.0, 0.0], [0.5, 0.5]])
    np.testing.assert_array_equal(coding.strides, [3, 1])
    assert (coding.per_tiling, coding.n_features) == (9, 18)
    out = np.full(2, -1, dtype=np.int64)
    active_tiles_nd(coding, np.array([0.3, 0.8]), out)
    np.testing.assert_array_equal(out, [1, 14])


@pytest.mark.parametrize("hash_size", [None, 4096, 7])
def test_row_writer_and_python_equal_the_compiled_nd_function(hash_size):
    """``active_tiles_at`` == ``active_tiles_nd``, and each compiled function equals its ``.py_func``."""
    coding = make_tile_coding(MC_LOW, MC_HIGH, hash_size=hash_size)
    points = _test_points(coding.low, _high(coding), seed=3)[::3]
    nd = _features(coding, points)
    np.testing.assert_array_equal(_features_at(coding, points), nd)
    np.testing.assert_array_equal(_features_at(coding, points, active_tiles_at.py_func), nd)
    np.testing.assert_array_equal(_features(coding, points, active_tiles_nd.py_func), nd)
    # float32 observations, as Gymnasium returns them, give the features of their float64 values.
    observations = points[np.all(np.isfinite(points), axis=1)].astype(np.float32)
    np.testing.assert_array_equal(_features(coding, observations),
                                  _features(coding, observations.astype(np.float64)))


def _reference_hash(tiling: int, coordinates) -> int:
    """The documented hash in plain Python integers: ``_mix`` of the tiling, then of each coordinate."""

    def mix(x: int) -> int:
        x ^= x >> 16
        x = (x * 0x7FEB352D) & 0xFFFFFFFF
        x ^= x >> 15
        x = (x * 0x31848BAB) & 0xFFFFFFFF
        return x ^ (x >> 16)

    state = mix(tiling ^ 0x9E3779B9)
    for c in coordinates:
        state = mix(state ^ int(c))
    return state


@pytest.mark.parametrize("layout_name", ["mountain-car-8x8x8", "3d-16-tilings-4x5x6"])
def test_hashed_indices_are_in_range_deterministic_and_keep_the_partition(layout_name):
    """Hashed features lie in ``[0, hash_size)``, are a fixed function of (tiling, tile), and with room to
    spare split the points exactly as the unhashed tiles do."""
    low, high, kwargs = LAYOUTS[layout_name]
    plain = make_tile_coding(low, high, **kwargs)
    points = _test_points(plain.low, _high(plain), seed=7)
    unhashed = _features(plain, points)

    small = make_tile_coding(low, high, hash_size=61, **kwargs)
    assert small.hashed
    assert (small.n_features, small.per_tiling) == (61, plain.per_tiling)
    in_small = _features(small, points)
    assert in_small.min() >= 0
    assert in_small.max() < 61
    assert len(np.unique(in_small)) > 30

    large = make_tile_coding(low, high, hash_size=2**32, **kwargs)
    hashed = _features(large, points)
    np.testing.assert_array_equal(_features(make_tile_coding(low, high, hash_size=2**32, **kwargs), points), hashed)
    np.testing.assert_array_equal(hashed % 61, in_small)
    coordinates = _reference_coordinates(plain, points)
    for i in range(0, len(points), 37):
        for t in range(plain.n_tilings):
            assert hashed[i, t] == _reference_hash(t, coordinates[i, t])
    # Same hashed feature <=> same unhashed tile, over every (point, tiling) of the sample.
    pairs = set(zip(unhashed.ravel().tolist(), hashed.ravel().tolist(), strict=True))
    assert len(pairs) == len(np.unique(unhashed)) == len(np.unique(hashed))
    assert len(pairs) > 10 * plain.n_tilings


@pytest.mark.parametrize(
    ("low", "high", "kwargs", "argument"),
    [
        ((0, 0), (1, 1), {"tilings": 0}, "tilings"),
        ((0, 0), (1, 1), {"tilings": 2.5}, "tilings"),
        ((0, 0), (1, 1), {"tilings": True}, "tilings"),
        ((0, 0), (1, 1), {"tiles": 0}, "tiles"),
        ((0, 0), (1, 1), {"tiles": (8, 0)}, "tiles"),
        ((0, 0), (1, 1), {"tiles": (8, 8, 8)}, "tiles"),
        ((0, 0), (1, 1), {"tiles": (8,)}, "tiles"),
        ((0, 0), (1, 1), {"tiles": (8.5, 8)}, "tiles"),
        ((0, 0), (1, 1), {"tiles": ((8, 8), (8, 8))}, "tiles"),
        ((0, 0), (1, 1, 1), {}, "low and high"),
        ([[0, 0], [0, 0]], [[1, 1], [1, 1]], {}, "low and high"),
        ((), (), {}, "low and high"),
        ((0, -np.inf), (1, 1), {}, "low and high"),
        ((0, 0), (1, np.nan), {}, "low and high"),
        ((-1e308, 0), (1e308, 1), {}, "high - low"),
        ((0, 1), (1, 1), {}, "high > low"),
        ((0, 2), (1, 1), {}, "high > low"),
        ((0, 0), (1, 1), {"hash_size": 0}, "hash_size"),
        ((0, 0), (1, 1), {"hash_size": 2**32 + 1}, "hash_size"),
        ((0, 0), (1, 1), {"hash_size": 100.0}, "hash_size"),
        ((0, 0), (1, 1), {"displacement": (1,)}, "displacement"),
        ((0, 0), (1, 1), {"displacement": (1, 3, 5)}, "displacement"),
        ((0, 0), (1, 1), {"displacement": (1, 0)}, "displacement"),
        ((0, 0), (1, 1), {"displacement": (1, 1.5)}, "displacement"),
        ((0,) * 8, (1,) * 8, {"tiles": 1000, "tilings": 64}, "tiles"),
    ],
)
def test_bad_layouts_raise_naming_the_argument(low, high, kwargs, argument):
    """A layout that does not fit the bounds, or a value out of range, is a ValueError naming the argument."""
    with pytest.raises(ValueError, match=argument):
        make_tile_coding(low, high, **kwargs)


def test_good_layouts_are_accepted():
    """Numpy integers, numpy bounds and a scalar (one-dimensional) box build a coding."""
    coding = make_tile_coding(MC_LOW, MC_HIGH, tilings=np.int64(4), tiles=np.array([6, 7]), hash_size=np.int32(512))
    assert (coding.n_tilings, coding.n_features, coding.hashed) == (4, 512, True)
    one = make_tile_coding(0.0, 1.0, tilings=2, tiles=3)
    assert (one.per_tiling, one.n_features) == (4, 8)
    assert isinstance(coding.per_tiling, int)
    assert isinstance(coding.n_features, int)
