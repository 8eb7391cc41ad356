"""Learning curves over seeds: smoothing, thinning and a bootstrap band for the mean at every point."""

from __future__ import annotations

import hashlib

import numpy as np


def moving_average(values: np.ndarray, window: int) -> np.ndarray:
    """Trailing mean over ``window`` points along the last axis; the first points average what exists."""
    values = np.asarray(values, dtype=np.float64)
    cumulative = np.cumsum(values, axis=-1)
    shifted = np.zeros_like(cumulative)
    shifted[..., window:] = cumulative[..., :-window]
    counts = np.minimum(np.arange(1, values.shape[-1] + 1), window)
    averaged: np.ndarray = (cumulative - shifted) / counts
    return averaged


def thinned(n_points: int, max_points: int = 500) -> np.ndarray:
    """At most ``max_points`` evenly spread indices of ``n_points``, the last one included."""
    if n_points <= max_points:
        return np.arange(n_points)
    return np.unique(np.linspace(0, n_points - 1, max_points).round().astype(np.int64))


def mean_band(
    curves: np.ndarray, confidence: float = 0.95, n_resamples: int = 2000, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean over seeds (axis 0) at every point, with a percentile-bootstrap band resampling whole seeds.

    Resampling seeds, not points, keeps each seed's curve intact (rliable's stratified bootstrap). A report draws
    the same curve in several figures (a configuration alone, then beside another): the band of curves equal bit
    for bit to ones already banded is taken from a small cache instead of being resampled again.
    """
    curves = np.asarray(curves, dtype=np.float64)
    key = (hashlib.sha256(np.ascontiguousarray(curves).tobytes()).hexdigest(), curves.shape, confidence,
           n_resamples, seed)
    if key not in _BANDS:
        _BANDS[key] = _mean_band(curves, confidence, n_resamples, seed)
        while len(_BANDS) > 64:
            _BANDS.pop(next(iter(_BANDS)))
    mean, low, high = _BANDS[key]
    return mean.copy(), low.copy(), high.copy()


_BANDS: dict[tuple[str, tuple[int, ...], float, int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
"""The last bands computed, by a digest of their curves and the bootstrap's settings."""


def _mean_band(curves: np.ndarray, confidence: float, n_resamples: int, seed: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    mean = curves.mean(axis=0)
    if curves.shape[0] < 2:
        return mean, mean.copy(), mean.copy()
    seeds = curves.shape[0]
    counts = np.random.default_rng(seed).multinomial(seeds, np.full(seeds, 1 / seeds), size=n_resamples)
    resampled = counts @ curves / seeds  # each row: the mean of one resample of whole seeds
    tail = (1 - confidence) / 2 * 100
    low, high = np.percentile(resampled.T, [tail, 100 - tail], axis=1)  # each point's resamples side by side
    return mean, low, high
