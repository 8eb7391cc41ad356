"""Seconds the retrograde analysis of KRK and KQK takes, after compiling (or loading) its kernel, with the counts it
finds.

    .venv/bin/python scripts/bench_chess_solver.py [--repeats 5]

For each endgame: the first call (compiling the kernel, or loading it from numba's cache), then the median and the
fastest of ``--repeats`` further solves; the legal positions with each side to move, the positions won for white
(all of white's), the checkmates, and the longest mate in half-moves with each side to move.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from rlcompare.envs.chess import rules as chess_rules
from rlcompare.envs.chess import solver as chess_solver


def seconds(piece: int) -> float:
    """Wall-clock seconds of one retrograde analysis (not the cached ``solve``)."""
    start = time.perf_counter()
    chess_solver.retrograde(piece)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="solves timed after the first (default 5)")
    repeats = parser.parse_args().repeats
    print("| endgame | first call (s) | median (s) | fastest (s) | legal, white / black to move | won, white / black "
          "to move | checkmates | longest mate, white / black to move (half-moves) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, piece in chess_rules.ENDGAMES.items():
        first = seconds(piece)
        timings = [seconds(piece) for _ in range(repeats)]
        white, black = chess_solver.solve(piece)
        legal = [sum(chess_rules.is_legal(piece, index, side) for index in range(chess_rules.N_POSITIONS))
                 for side in (True, False)]
        print(f"| {name} | {first:.3f} | {statistics.median(timings):.4f} | {min(timings):.4f} | "
              f"{legal[0]:,} / {legal[1]:,} | {np.sum(white >= 0):,} / {np.sum(black >= 0):,} | "
              f"{np.sum(black == 0):,} | {white.max()} / {black.max()} |")


if __name__ == "__main__":
    main()
