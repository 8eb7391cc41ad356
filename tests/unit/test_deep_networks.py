"""The deep engine's networks: the convolution's windows, gathered, are XLA's patches bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

import jax.numpy as jnp  # noqa: E402

from rlcompare.deep.networks import patches_3x3  # noqa: E402


def xla_patches(x: jax.Array) -> jax.Array:
    """The reference: ``lax.conv_general_dilated_patches`` (a convolution with a one-hot kernel) over any leading
    axes."""
    leading, image = x.shape[:-3], x.shape[-3:]
    patches = jax.lax.conv_general_dilated_patches(x.reshape(-1, *image), (3, 3), (1, 1), "VALID",
                                                   dimension_numbers=("NHWC", "OIHW", "NHWC"))
    return patches.reshape(*leading, *patches.shape[1:])


@pytest.mark.parametrize(("leading", "depth"), [((), 4), ((1,), 5), ((32,), 6), ((2, 3), 7), ((4, 64), 8),
                                               ((128,), 9), ((32,), 10)])  # MinAtar's games: 4 to 10 channels
@pytest.mark.slow("compiles XLA's patches")
def test_gathered_windows_are_xlas_patches(leading: tuple[int, ...], depth: int) -> None:
    rng = np.random.default_rng(depth)
    shape = (*leading, 10, 10, depth)
    booleans = rng.random(shape) < 0.3
    for x in map(jnp.asarray, (booleans, booleans.astype(np.float32), rng.standard_normal(shape, np.float32))):
        expected = jax.jit(xla_patches)(x)
        assert expected.shape == (*leading, 8, 8, 9 * depth)
        found = jax.jit(patches_3x3)(x)
        assert found.dtype == x.dtype
        np.testing.assert_array_equal(found, expected)


@pytest.mark.slow("compiles or trains for a second or more")
def test_gathered_windows_are_ordered_by_channel_then_row_then_column() -> None:
    depth = 3
    image = jnp.arange(5 * 6 * depth).reshape(5, 6, depth)  # each cell's value is its flat position
    found = np.asarray(patches_3x3(image))
    assert found.shape == (3, 4, 9 * depth)
    row, column = 1, 2
    expected = [image[row + r, column + c, channel] for channel in range(depth) for r in range(3) for c in range(3)]
    np.testing.assert_array_equal(found[row, column], np.asarray(expected))
    np.testing.assert_array_equal(found, xla_patches(image.astype(jnp.float32)))


def test_gathered_windows_under_vmap_are_xlas_patches() -> None:
    x = jnp.asarray(np.random.default_rng(5).random((4, 128, 10, 10, 6)) < 0.5, jnp.float32)
    np.testing.assert_array_equal(jax.jit(jax.vmap(patches_3x3))(x), xla_patches(x))
