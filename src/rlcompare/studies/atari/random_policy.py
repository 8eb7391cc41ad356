"""The uniformly random policy measured here under the study's protocol (Machado et al. 2018's sticky actions and
cut, every game's 18 actions), beside the published random scores, which DQN's protocol measured (no-op starts, no
sticky actions), and beside each game's margin: where one random episode's spread is larger than the margin, the
game's verdict rests on seeds that must outnumber that noise.

Each game's episodes are kept in the study's directory (:data:`TABLE`, entered in its record), so a report made
again reads them instead of playing them again; a table the record does not vouch for is played again.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from rlcompare.envs.atari import scores as atari_scores
from rlcompare.experiment import rundir, store
from rlcompare.stats import intervals as stats
from rlcompare.studies.paired_plan import random_returns

EPISODES = 30
"""Episodes of the random policy per game: enough for a 95% interval of its mean and the spread of one episode."""
SEED = 0
"""The key of the episodes' draws (:func:`~rlcompare.studies.paired_plan.random_returns`)."""
TABLE = "tables/atari_random_episodes.csv"
"""``game, episode, return``: every random episode played, relative to the study's directory."""


def random_episodes(out: Path, titles: Sequence[str], episodes: int) -> pd.DataFrame:
    """``game, episode, return`` of ``episodes`` random episodes of each of ``titles``: read from the study's
    :data:`TABLE` where it holds that many of the game (verified against the study's record), else played in the
    engine's emulator (ε = 1 through its evaluation); the table written and recorded again where any was played."""
    known = _recorded(Path(out))
    frames, played = [], False
    for title in titles:
        rows = known[known["game"] == title] if known is not None else None
        if rows is None or len(rows) != episodes:
            returns = random_returns(f"{title}-Atari", episodes, SEED)
            rows = pd.DataFrame({"game": title, "episode": np.arange(episodes), "return": returns})
            played = True
        frames.append(rows)
    table = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["game", "episode", "return"])
    if played:
        data = table.to_csv(index=False).encode()
        store.write_atomic(Path(out) / TABLE, lambda handle: handle.write(data))
        rundir.enter_members(Path(out), [], {TABLE: data})
    return table


def _recorded(out: Path) -> pd.DataFrame | None:
    """The study's :data:`TABLE` where its record vouches for it and it has its columns; None otherwise."""
    try:
        found = pd.read_csv(io.BytesIO(rundir.read_member_file(out, TABLE)))
    except (store.StoreError, ValueError):
        return None
    return found if {"game", "episode", "return"} <= set(found.columns) else None


def random_table(episodes: pd.DataFrame, margin_share: float) -> pd.DataFrame:
    """Per game: the random policy's mean return here (95% interval) and one episode's standard deviation, the
    published random and human scores, the game's margin (``margin_share`` of its random-to-human range) and one
    episode's spread in margins."""
    rows = []
    for title, returns in episodes.groupby("game", sort=False)["return"]:
        game = atari_scores.GAMES[str(title)]
        spread = float(np.std(returns.to_numpy(), ddof=1)) if len(returns) > 1 else float("nan")
        margin = margin_share * (game.human - game.random)
        rows.append({"game": title, "episodes": len(returns),
                     "random here, mean": stats.interval(returns.to_numpy()).format(1),
                     "one episode's sd": round(spread, 2), "published random": game.random,
                     "human": game.human, "margin": round(margin, 2),
                     "one episode's sd in margins": round(spread / margin, 1)})
    return pd.DataFrame(rows)
