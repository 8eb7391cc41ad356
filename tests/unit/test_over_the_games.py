"""Two pure pieces of the Atari study, on inputs computed by hand: each seed's score over the games (the mean, or
rliable's interquartile mean) and the random policy's table beside each game's margin."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from rlcompare.studies.atari.random_policy import random_table
from rlcompare.studies.paired import over_environments


def test_the_interquartile_mean_drops_a_quarter_of_the_games_at_each_end() -> None:
    scores = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [100.0, 0.0]])  # 4 games x 2 seeds
    np.testing.assert_array_equal(over_environments(scores, "iqm"), [2.5, 0.0])  # the middle two: (2 + 3) / 2
    np.testing.assert_array_equal(over_environments(scores, "mean"), [26.5, 0.0])
    three = np.array([[1.0], [2.0], [9.0]])  # a quarter of 3 rounds down to none: the mean
    np.testing.assert_array_equal(over_environments(three, "iqm"), [4.0])
    ties = np.full((5, 3), 0.25)
    np.testing.assert_array_equal(over_environments(ties, "iqm"), [0.25] * 3)
    assert np.isnan(over_environments(np.array([[np.nan], [1.0], [2.0], [3.0]]), "mean")[0])  # nothing hidden


def test_the_random_policys_table_counts_one_episodes_spread_in_margins() -> None:
    """Breakout (random 1.7, human 30.5): a margin of a tenth is 2.88; returns 0 and 2 have a standard deviation of
    sqrt(2) = 1.41, 0.5 margins; one episode has no spread."""
    table = random_table(pd.DataFrame({"game": ["Breakout", "Breakout", "Pong"], "episode": [0, 1, 0],
                                       "return": [0.0, 2.0, -21.0]}), 0.1)
    breakout, pong = table.iloc[0], table.iloc[1]
    assert breakout["episodes"] == 2
    assert breakout["random here, mean"].startswith("1.0 [")
    assert breakout["one episode's sd"] == pytest.approx(1.41)
    assert breakout["margin"] == pytest.approx(2.88)
    assert breakout["one episode's sd in margins"] == pytest.approx(0.5)
    assert math.isnan(pong["one episode's sd"])
    assert math.isnan(pong["one episode's sd in margins"])
