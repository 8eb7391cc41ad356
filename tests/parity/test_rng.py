"""The compiled PCG64 port against NumPy's own ``PCG64`` and ``Generator``."""

from __future__ import annotations

import numpy as np
import pytest

from rlcompare import rng
from rlcompare.rng import next_below, next_double, next_uint64, stream_state

N_DRAWS = 2_000
N_DRAWS_PY = 300  # the pure-Python versions are slower

SEEDS = {
    "zero": lambda: 0,
    "one": lambda: 1,
    "small": lambda: 12345,
    "huge": lambda: 2**100 + 7,
    "sequence": lambda: np.random.SeedSequence([3, 1, 4, 1, 5]),
    "spawned-child": lambda: np.random.SeedSequence(42).spawn(3)[2],
}


@pytest.fixture(params=list(SEEDS), ids=list(SEEDS))
def seed(request):
    """A fresh seed (an int or a SeedSequence) of each kind."""
    return SEEDS[request.param]()


def _implementation(name: str, fn):
    """The compiled dispatcher, or its Python source function.

    The ``py_func`` versions run on NumPy ``uint64`` scalars, whose wrap-around multiplications raise
    overflow RuntimeWarnings (errors under ``filterwarnings = error``). The wrap-around is the intended
    modular arithmetic, so callers run them under ``np.errstate(over="ignore")``.
    """
    return fn if name == "compiled" else fn.py_func


def _generator_state_as_int(state: np.ndarray) -> int:
    return (int(state[0]) << 64) | int(state[1])


def test_stream_state_layout(seed):
    """``[state_high, state_low, inc_high, inc_low]`` of ``PCG64(seed)``."""
    state = stream_state(seed)
    reference = np.random.PCG64(seed).state["state"]
    assert state.dtype == np.uint64
    assert state.shape == (4,)
    assert _generator_state_as_int(state) == reference["state"]
    assert (int(state[2]) << 64) | int(state[3]) == reference["inc"]
    assert int(state[3]) % 2 == 1  # a PCG increment is always odd


@pytest.mark.parametrize("impl", ["compiled", "py_func"])
def test_next_uint64_equals_random_raw(seed, impl):
    """The raw 64-bit stream equals ``PCG64(seed).random_raw``."""
    n = N_DRAWS if impl == "compiled" else N_DRAWS_PY
    fn = _implementation(impl, next_uint64)
    state = stream_state(seed)
    bit_generator = np.random.PCG64(seed)
    expected = bit_generator.random_raw(n)
    with np.errstate(over="ignore"):
        got = np.array([fn(state) for _ in range(n)], dtype=np.uint64)
    np.testing.assert_array_equal(got, expected)
    # The state advanced in place to exactly where NumPy's is.
    assert _generator_state_as_int(state) == bit_generator.state["state"]["state"]


@pytest.mark.parametrize("impl", ["compiled", "py_func"])
def test_next_double_equals_generator_random(seed, impl):
    """Doubles equal ``Generator(PCG64(seed)).random()``, bit for bit."""
    n = N_DRAWS if impl == "compiled" else N_DRAWS_PY
    fn = _implementation(impl, next_double)
    state = stream_state(seed)
    expected = np.random.Generator(np.random.PCG64(seed)).random(n)
    with np.errstate(over="ignore"):
        got = np.array([fn(state) for _ in range(n)])
    np.testing.assert_array_equal(got, expected)
    assert np.all((got >= 0.0) & (got < 1.0))


def test_next_double_interleaves_with_raw(seed):
    """Each double consumes exactly one raw draw, so mixed calls stay in step with NumPy."""
    state = stream_state(seed)
    raw = np.random.PCG64(seed).random_raw(10)
    for k in range(10):
        if k % 2:
            assert next_uint64(state) == raw[k]
        else:
            assert next_double(state) == float(raw[k] >> np.uint64(11)) / 2.0**53


@pytest.mark.parametrize("n", [1, 2, 3, 7, 1000])
def test_next_below_is_scaled_double(n):
    """``next_below(n)`` is ``int(random() * n)``, always in ``[0, n)``, and reaches every value."""
    state = stream_state(99)
    doubles = np.random.Generator(np.random.PCG64(99)).random(3000)
    got = np.array([next_below(state, n) for _ in range(doubles.size)])
    np.testing.assert_array_equal(got, (doubles * n).astype(np.int64))
    assert 0 <= got.min() <= got.max() < n
    if n <= 7:
        assert set(got.tolist()) == set(range(n))


def test_streams_of_different_seeds_differ():
    """Distinct seeds, and a parent and its spawned children, give distinct streams."""
    parent = np.random.SeedSequence(5)
    children = parent.spawn(2)
    states = [stream_state(5), stream_state(6), stream_state(children[0]), stream_state(children[1])]
    firsts = [tuple(next_uint64(s) for _ in range(4)) for s in states]
    assert len(set(firsts)) == len(firsts)


_MASK64 = (1 << 64) - 1
_HARD_FACTORS = [0, 1, 2**32 - 1, 2**32, 2**63, _MASK64, 4865540595714422341, 2549297995355413924]


@pytest.mark.parametrize("impl", ["compiled", "py_func"])
def test_multiply_high_matches_big_integers(impl):
    """The high half of the 128-bit product, on edge values and random pairs, against Python ints."""
    fn = _implementation(impl, rng._multiply_high)
    generator = np.random.default_rng(0)
    pairs = [(a, b) for a in _HARD_FACTORS for b in _HARD_FACTORS]
    pairs += [tuple(int(x) for x in generator.integers(0, 2**64, size=2, dtype=np.uint64)) for _ in range(200)]
    with np.errstate(over="ignore"):
        for a, b in pairs:
            assert int(fn(np.uint64(a), np.uint64(b))) == (a * b) >> 64, (a, b)
