"""The returns of each seed: one definition of behaviour return, greedy return and greedy AUC for every engine."""

from __future__ import annotations

import numpy as np
import pytest

from rlcompare.stats.metrics import returns_from_tables, returns_per_seed


def test_returns_by_hand_from_a_table_of_episodes_and_rounds():
    training = np.array([[-10.0, -20.0, -30.0], [-1.0, -2.0, -3.0]])
    evaluations = np.array([[[-5.0, -7.0], [-1.0, -3.0]],  # seed 3: round means -6, -2
                            [[0.0, 0.0], [-4.0, -4.0]]])  # seed 9: round means 0, -4
    frame = returns_per_seed((3, 9), training, evaluations)
    assert frame["seed"].tolist() == [3, 9]
    assert frame["behaviour_return"].tolist() == [-20.0, -2.0]
    assert frame["greedy_return"].tolist() == [-2.0, -4.0]  # the last round
    assert frame["greedy_auc"].tolist() == [-4.0, -2.0]  # the mean over rounds


def test_seeds_that_ended_different_numbers_of_episodes_and_curves_of_round_means():
    frame = returns_per_seed((0, 1), [np.array([1.0, 3.0]), np.array([10.0])], np.array([[1.0, 2.0], [5.0, 9.0]]))
    assert frame["behaviour_return"].tolist() == [2.0, 10.0]
    assert frame["greedy_return"].tolist() == [2.0, 9.0]
    assert frame["greedy_auc"].tolist() == [1.5, 7.0]


def test_no_evaluation_round_leaves_the_greedy_columns_empty():
    frame = returns_per_seed((0, 1), np.ones((2, 4)), np.zeros((2, 0, 3)))
    assert frame["behaviour_return"].tolist() == [1.0, 1.0]
    assert frame[["greedy_return", "greedy_auc"]].isna().all().all()


@pytest.mark.parametrize("shape", [(2, 5, 3), (2, 5)])
def test_the_greedy_return_is_the_last_rounds_mean_bit_for_bit(shape):
    evaluations = np.random.default_rng(1).normal(size=shape)
    frame = returns_per_seed((0, 1), np.zeros((2, 1)), evaluations)
    last = evaluations[:, -1].mean(axis=1) if len(shape) == 3 else evaluations[:, -1]
    np.testing.assert_array_equal(frame["greedy_return"].to_numpy(), last)


def test_the_long_tables_give_the_same_numbers_as_the_arrays():
    """A sweep's trials read as two Parquet tables: the same definitions as the arrays of a loaded run."""
    import pandas as pd

    rng = np.random.default_rng(2)
    training, evaluations = rng.normal(size=(3, 7)), rng.normal(size=(3, 4, 5))
    seeds = (4, 5, 6)
    episodes = pd.DataFrame({"seed": np.repeat(seeds, 7), "return": training.ravel()})
    rounds = pd.DataFrame({"seed": np.repeat(seeds, 20), "round": np.tile(np.repeat(np.arange(4), 5), 3),
                           "return": evaluations.ravel()})
    arrays = returns_per_seed(seeds, training, evaluations)
    tables = returns_from_tables(episodes, rounds, ["seed"])
    pd.testing.assert_frame_equal(tables, arrays, check_dtype=False, rtol=1e-12)
