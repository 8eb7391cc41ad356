"""Time to converge: the settling time of a smoothed learning curve, on curves whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from rlcompare.stats.convergence import convergence_episodes, episodes_to_seconds
from rlcompare.stats.curves import moving_average

WINDOW = 100


def _step(episodes: int = 2000, at: int = 700, noise: float = 5.0, seed: int = 0) -> np.ndarray:
    """-1000 (the step limit, unsolved) before episode ``at``, then -150 with Gaussian noise."""
    curve = np.where(np.arange(episodes) < at, -1000.0, -150.0)
    curve[at:] += np.random.default_rng(seed).normal(0.0, noise, episodes - at)
    return curve


def _exponential(episodes: int = 3000, tau: float = 100.0, noise: float = 20.0, seed: int = 0) -> np.ndarray:
    """-150 - 850 exp(-t / tau): from the step limit towards -150, with Gaussian noise."""
    t = np.arange(episodes)
    return -150.0 - 850.0 * np.exp(-t / tau) + np.random.default_rng(seed).normal(0.0, noise, episodes)


def _oscillating(episodes: int = 3000, until: int = 1500) -> np.ndarray:
    """Blocks of 100 episodes alternating -1000 and -150 until ``until`` (first and last block -1000), then -150."""
    block = np.arange(episodes) // 100
    return np.where((np.arange(episodes) < until) & (block % 2 == 0), -1000.0, -150.0)


def test_smoothed_returns_is_a_trailing_mean_that_starts_with_what_is_available():
    returns = np.array([[1.0, 2.0, 3.0, 4.0], [4.0, 0.0, 4.0, 0.0]])
    # window 2: episode 0 averages itself, then each pair of (previous, current)
    np.testing.assert_allclose(moving_average(returns, window=2), [[1.0, 1.5, 2.5, 3.5], [4.0, 2.0, 2.0, 2.0]])
    np.testing.assert_allclose(moving_average(returns, window=1), returns)


def test_step_is_detected_within_a_window_after_it():
    # The raw curve settles at episode 701 (count); the trailing mean is within the band (5% of 850 = 42.5)
    # once at most 5 of its 100 episodes are from before the step: about 795.
    detected = convergence_episodes(_step()[None, :])[0]
    assert 701 <= detected <= 701 + WINDOW
    assert 780 <= detected <= 800


def test_noisy_exponential_approach_is_detected_within_a_window_of_where_it_settles():
    curve = _exponential()
    detected = convergence_episodes(curve[None, :])[0]
    # Same levels as the rule: the initial level is the mean of the first window of the noise-free curve,
    # -150 - 850 * mean(exp(-t / 100), t < 100) ≈ -687, so the band is 5% of ≈ 537 ≈ 27 and the noise-free
    # raw curve enters it for good when 850 exp(-t / 100) = band, t = 100 ln(850 / band) ≈ 346.
    t = np.arange(WINDOW)
    band = 0.05 * 850.0 * np.mean(np.exp(-t / 100.0))
    settles = 100.0 * np.log(850.0 / band) + 1
    assert settles == pytest.approx(346, abs=2)
    assert settles <= detected <= settles + WINDOW


def test_a_curve_that_never_solves_never_converges():
    assert np.isnan(convergence_episodes(np.full((1, 500), -1000.0))[0])


def test_success_share_decides_whether_the_final_level_counts():
    # Steady at -150 except that some of the last 100 episodes hit the limit.
    def curve(failures: int) -> np.ndarray:
        returns = np.full(1000, -150.0)
        returns[-WINDOW:][::WINDOW // failures][:failures] = -1000.0
        return returns

    # The failures move the smoothed curve inside the last window, so the settling-length rule is off here.
    # 40% of the last window solved
    assert np.isnan(convergence_episodes(curve(60)[None, :], settled_windows=0, settled_share=0.0)[0])
    assert np.isfinite(convergence_episodes(curve(40)[None, :], settled_windows=0, settled_share=0.0)[0])  # 60% solved
    assert np.isnan(convergence_episodes(curve(40)[None, :], min_success=0.7, settled_windows=0, settled_share=0.0)[0])


def test_a_flat_solved_curve_converges_at_once_thanks_to_the_minimum_band():
    # No improvement to take 5% of; the band is min_band = 10, which noise of sd 2 never leaves.
    flat = -200.0 + np.random.default_rng(1).normal(0.0, 2.0, (1, 600))
    assert convergence_episodes(flat)[0] == 1.0
    # A band thinner than the noise is left again and again until the very end: not settled.
    assert np.isnan(convergence_episodes(flat, min_band=0.01)[0])


def test_a_curve_still_climbing_at_the_end_has_not_converged():
    ramp = np.linspace(-1000.0, -150.0, 5000)[None, :]
    assert np.isnan(convergence_episodes(ramp)[0])
    plateau = np.concatenate([np.linspace(-1000.0, -150.0, 3000), np.full(2000, -150.0)])[None, :]
    # within the 5% band (about 42) some 150 episodes before the plateau: 2850 < episode <= plateau + window
    assert 2850 < convergence_episodes(plateau)[0] <= 3000 + WINDOW


def test_oscillation_until_late_converges_late():
    curve = _oscillating()
    detected = convergence_episodes(curve[None, :])[0]
    # The smoothed curve is at -150 from time to time before 1500 (e.g. around episode 200)...
    smooth = moving_average(curve[None, :], 100)[0]
    assert np.abs(smooth[199] - (-150.0)) < 10.0
    # ...but only stays there once the last -1000 block (1400..1499) has left the window.
    assert 1500 < detected <= 1500 + WINDOW


def test_vectorised_over_runs_equals_one_run_at_a_time():
    runs = np.stack([
        _step(3000, 700), _exponential(3000), np.full(3000, -1000.0), _oscillating(3000),
        _step(3000, 2000, seed=3), _exponential(3000, tau=400.0, seed=4),
    ])
    together = convergence_episodes(runs)
    one_by_one = np.array([convergence_episodes(run[None, :])[0] for run in runs])
    np.testing.assert_array_equal(together, one_by_one)
    assert np.isnan(together[2])
    assert np.all(np.isfinite(np.delete(together, 2)))
    assert together[4] > together[0]  # a later step converges later
    assert together[5] > together[1]  # a slower approach converges later


def test_convergence_needs_a_window_of_episodes():
    with pytest.raises(ValueError, match="fewer than a window"):
        convergence_episodes(np.full((2, 50), -150.0))
    with pytest.raises(ValueError, match="runs, episodes"):
        convergence_episodes(np.full(500, -150.0))


def test_episodes_to_seconds_on_a_hand_example():
    lengths = np.array([[10, 20, 30], [1000, 5, 5], [7, 7, 7]])
    convergence = np.array([2.0, 3.0, np.nan])
    # run 0: 10 + 20 = 30 steps; run 1: 1000 + 5 + 5 = 1010 steps; run 2 never converged
    seconds = episodes_to_seconds(convergence, lengths, seconds_per_step=0.5)
    np.testing.assert_allclose(seconds, [15.0, 505.0, np.nan])
    with pytest.raises(ValueError, match="whole numbers"):
        episodes_to_seconds(np.array([0.0, 1.0, 1.0]), lengths, 0.5)
    with pytest.raises(ValueError, match="whole numbers"):
        episodes_to_seconds(np.array([4.0, 1.0, 1.0]), lengths, 0.5)


def test_episodes_to_seconds_of_detected_convergence():
    returns = np.stack([_step(1000, 300), _step(1000, 500, seed=1)])
    lengths = -returns  # one step per -1 reward
    convergence = convergence_episodes(returns)
    seconds = episodes_to_seconds(convergence, lengths, seconds_per_step=1e-3)
    expected = [lengths[run, : int(convergence[run])].sum() * 1e-3 for run in range(2)]
    np.testing.assert_allclose(seconds, expected)
    assert seconds[1] > seconds[0]
