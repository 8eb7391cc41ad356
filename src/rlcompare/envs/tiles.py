"""Tile coding of a box of observations (Sutton and Barto, 2nd ed., section 9.5.4).

Spec sheet:

| item         | value                                                                                   |
|--------------|-----------------------------------------------------------------------------------------|
| box          | ``low[d] <= x[d] <= high[d]`` for each of ``dims`` dimensions, finite, ``high > low``       |
| tilings      | ``tilings`` grids of ``tiles[d]`` tiles per dimension across the box, each one tile wide  |
|              | ``w[d] = (high[d] - low[d]) / tiles[d]``; the book's Mountain Car (section 10.1) uses 8   |
|              | tilings of 8 x 8 tiles over position x velocity                                          |
| displacement | tiling ``t`` is displaced by ``offsets[t, d] = (t * displacement[d] / tilings) mod 1``    |
|              | tiles along ``d``; the default displacement is the first odd integers ``(1, 3, 5, ...)``  |
|              | (asymmetric offsets, Miller and Glanz 1990), the book's recommendation together with a   |
|              | number of tilings that is a power of two ``>= 4 * dims``                                  |
| coordinate   | ``c[t, d] = floor((x[d] - low[d]) * scale[d] + offsets[t, d])`` clipped to              |
|              | ``[0, tiles[d]]``: ``tiles[d] + 1`` coordinates cover the displaced tiling, a point on or |
|              | beyond ``high`` lands in the last tile and one below ``low`` in the first (NaN: first)    |
| feature      | ``t * per_tiling + sum_d c[t, d] * strides[d]`` (row-major, first dimension most        |
|              | significant), ``per_tiling = prod(tiles + 1)``; exactly one feature per tiling is active |
| hashed       | with ``hash_size``: ``_hash(t, c[t, :]) % hash_size`` instead, a fixed 32-bit            |
|              | multiply-xorshift hash (see :func:`_mix`), so ``n_features = hash_size``                 |

Two points less than one tile width ``w`` apart along one axis share on average ``1 - distance / w`` of
their tilings, and points more than a tile width apart along an axis share none.

Sutton's ``tiles3`` software hashes through an index hash table (IHT) that hands out indices in the order
tiles are first seen, so its indices depend on the history of calls (state shared by every caller). The
hash here is a pure function of ``(t, c[t, :])``: equal on every run and platform, free of state, and so
different from ``tiles3``'s indices (and, unlike an IHT with room to spare, it may collide before
``hash_size`` features are used). The unhashed layout needs no hash at all and has no collisions; use it
whenever ``tilings * prod(tiles + 1)`` features fit.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from rlcompare.compiled import njit
from rlcompare.validation import Integer, is_integer

_MASK32 = 0xFFFFFFFF
_SEED = 0x9E3779B9
MAX_HASH_SIZE = 1 << 32
"""The hash has 32 bits, so a larger ``hash_size`` would leave features unused."""


class TileCoding(NamedTuple):
    """Arrays that describe the tilings, passed as they are to compiled code."""

    low: np.ndarray
    """``(dims,)`` float64 lower bounds of the box."""
    scale: np.ndarray
    """``(dims,)`` float64 tiles per unit, ``tiles / (high - low)`` (raised by an ulp where needed so that
    ``(high - low) * scale >= tiles``: a point on the upper bound lands in the last tile)."""
    offsets: np.ndarray
    """``(tilings, dims)`` float64 displacement of each tiling in units of one tile, in ``[0, 1)``."""
    tiles: np.ndarray
    """``(dims,)`` int64 tiles per dimension across the box, before the extra tile the offset needs."""
    strides: np.ndarray
    """``(dims,)`` int64 strides that flatten a tile's coordinates within a tiling, row-major over
    ``tiles + 1``."""
    per_tiling: int
    """Features in one tiling, ``prod(tiles + 1)``."""
    n_features: int
    """Length of the feature vector: ``tilings * per_tiling``, or ``hash_size`` when hashed."""
    hashed: bool
    """Whether indices are hashed into ``n_features``."""

    @property
    def n_tilings(self) -> int:
        """Number of tilings, the number of active features of every point (compiled code reads
        ``offsets.shape[0]``)."""
        return int(self.offsets.shape[0])


def _per_dim_ints(name: str, value: npt.ArrayLike, dims: int) -> np.ndarray:
    """``value`` as ``(dims,)`` int64: one integer for every dimension, or a sequence of ``dims`` integers."""
    array = np.asarray(value)
    if array.ndim > 1 or not (np.issubdtype(array.dtype, np.integer) and array.dtype != np.bool_):
        raise ValueError(f"{name} must be an integer or a sequence of {dims} integers (one per dimension of "
                         f"the bounds), got {value!r}")
    if array.ndim == 1 and array.size != dims:
        raise ValueError(f"{name} has {array.size} entries but the bounds have {dims} dimensions; give one "
                         f"integer or {dims} integers, got {value!r}")
    return np.broadcast_to(array.astype(np.int64), (dims,)).copy()


def make_tile_coding(
    low: npt.ArrayLike,
    high: npt.ArrayLike,
    *,
    tilings: int = 8,
    tiles: int | tuple[int, ...] = 8,
    hash_size: int | None = None,
    displacement: tuple[int, ...] | None = None,
) -> TileCoding:
    """Tilings of the box ``[low, high]``, as the module docstring says.

    ``low`` and ``high`` are scalars or 1-D sequences of equal length (a Gymnasium ``Box``'s bounds);
    ``tiles`` is one integer for every dimension or one per dimension; ``displacement`` is one positive
    integer per dimension (default ``(1, 3, 5, ...)``). Raises ``ValueError`` naming the argument when
    the layout does not fit the bounds or a value is out of range.
    """
    low_array = np.atleast_1d(np.asarray(low, dtype=np.float64))
    high_array = np.atleast_1d(np.asarray(high, dtype=np.float64))
    if low_array.ndim != 1 or high_array.ndim != 1 or low_array.shape != high_array.shape or low_array.size == 0:
        raise ValueError(f"low and high must be 1-D bounds of the same length >= 1, got shapes "
                         f"{np.shape(low)} and {np.shape(high)}")
    if not (np.all(np.isfinite(low_array)) and np.all(np.isfinite(high_array))):
        raise ValueError(f"tile coding needs finite bounds low and high, got low={low_array}, high={high_array}")
    with np.errstate(over="ignore"):
        extent = high_array - low_array
    if not np.all(np.isfinite(extent)):
        raise ValueError(f"tile coding needs a finite width high - low, got low={low_array}, high={high_array}")
    if not np.all(high_array > low_array):
        raise ValueError(f"tile coding needs high > low in every dimension, got low={low_array}, high={high_array}")
    dims = low_array.size

    if not is_integer(tilings) or tilings < 1:
        raise ValueError(f"tilings must be an integer >= 1, got {tilings!r}")
    tilings = int(tilings)
    per_dim = _per_dim_ints("tiles", tiles, dims)
    if np.any(per_dim < 1):
        raise ValueError(f"tiles must be >= 1 in every dimension, got {tiles!r}")
    if displacement is None:
        steps = 2 * np.arange(dims, dtype=np.int64) + 1
    else:
        steps = np.asarray(displacement)
        if steps.ndim != 1 or steps.size != dims:
            raise ValueError(f"displacement must give one integer per dimension ({dims}), got {displacement!r}")
        steps = _per_dim_ints("displacement", steps, dims)
        if np.any(steps < 1):
            raise ValueError(f"displacement must hold positive integers, got {displacement!r}")
    if hash_size is not None and not Integer(1, MAX_HASH_SIZE).holds(hash_size):
        raise ValueError(f"hash_size must be None or an integer in [1, 2**32], got {hash_size!r}")

    scale = per_dim / extent
    for dim in range(dims):
        while extent[dim] * scale[dim] < per_dim[dim]:
            scale[dim] = np.nextafter(scale[dim], np.inf)
    # Integer remainder first, then one division: the offsets are exact multiples of 1 / tilings.
    offsets = (np.arange(tilings, dtype=np.int64)[:, None] * steps[None, :] % tilings) / tilings
    per_tiling = 1
    for size in per_dim:
        per_tiling *= int(size) + 1
    if tilings * per_tiling >= 1 << 62:
        raise ValueError(f"tilings * prod(tiles + 1) = {tilings * per_tiling} features do not fit an int64 "
                         f"index; reduce tiles or tilings")
    strides = np.ones(dims, dtype=np.int64)
    for dim in range(dims - 2, -1, -1):
        strides[dim] = strides[dim + 1] * (per_dim[dim + 1] + 1)
    n_features = int(hash_size) if hash_size is not None else tilings * per_tiling
    return TileCoding(low=low_array.copy(), scale=scale, offsets=np.ascontiguousarray(offsets),
                      tiles=per_dim, strides=strides, per_tiling=per_tiling, n_features=n_features,
                      hashed=hash_size is not None)


@njit(inline="always")
def _coordinate(position: float, tiles: int) -> int:
    """``floor(position)`` clipped to ``[0, tiles]``; NaN gives 0. Clipped as a float by selects: with two
    branches instead, a step of SARSA on tiles took 125 ns instead of 97."""
    clipped = position if position >= 0.0 else 0.0
    return int(clipped if clipped < tiles else float(tiles))


@njit(inline="always")
def _mix(x: int) -> int:
    """A 32-bit multiply-xorshift finaliser (shifts of ``lowbias32``, odd multipliers below 2**31).

    ``x`` is in ``[0, 2**32)`` and every product stays below 2**63, so compiled int64 arithmetic and
    Python integers give the same value without overflow.
    """
    x ^= x >> 16
    x = (x * 0x7FEB352D) & _MASK32
    x ^= x >> 15
    x = (x * 0x31848BAB) & _MASK32
    x ^= x >> 16
    return x


@njit(inline="always")
def _hash_start(tiling: int) -> int:
    """Hash state after the tiling number: ``_mix(tiling ^ seed)``."""
    return _mix((tiling ^ _SEED) & _MASK32)


@njit(inline="always")
def _hash_step(state: int, coordinate: int) -> int:
    """Hash state after one more coordinate: ``_mix(state ^ coordinate)``."""
    return _mix((state ^ coordinate) & _MASK32)


@njit(inline="always")
def active_tiles_at(coding: TileCoding, x: np.ndarray | tuple[np.float32, ...], out: np.ndarray, row: int) -> None:
    """Write the ``n_tilings`` active features of the point ``x`` (``(dims,)``, or a tuple) into ``out[row]``.

    Tiling by tiling, its flat index (or hash state) accumulated in a register over the dimensions and written
    once."""
    for t in range(coding.offsets.shape[0]):
        index = _hash_start(t) if coding.hashed else 0
        for d in range(len(x)):
            c = _coordinate((x[d] - coding.low[d]) * coding.scale[d] + coding.offsets[t, d], coding.tiles[d])
            index = _hash_step(index, c) if coding.hashed else index + c * coding.strides[d]
        out[row, t] = index % coding.n_features if coding.hashed else t * coding.per_tiling + index


@njit(inline="always")
def states_buffer(features: TileCoding, size: int) -> np.ndarray:
    """Room for the active tiles of ``size`` states, one row each."""
    return np.empty((size, features.offsets.shape[0]), np.int64)


@njit(inline="always")
def features_of(features: TileCoding, observation: np.ndarray | tuple[np.float32, ...], buffer: np.ndarray,
                at: int) -> np.ndarray:
    """The observation's active tiles, written into and returned as ``buffer[at]``."""
    active_tiles_at(features, observation, buffer, at)
    active: np.ndarray = buffer[at]
    return active


@njit(cache=True)
def active_tiles_nd(coding: TileCoding, x: np.ndarray, out: np.ndarray) -> None:
    """Write the ``n_tilings`` active features of the point ``x`` (``(dims,)``) into ``out``."""
    active_tiles_at(coding, x, out.reshape((1, out.size)), 0)
