"""How long ``rlcompare compare`` takes on 100 TensorBoard files of 10,000 points each (2 methods x 50 seeds, as
CleanRL lays its runs out), reading and report apart, on this machine; beside TensorBoard's own
``EventAccumulator`` reading the same files. Run: ``python scripts/bench_compare.py``."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from rlcompare.experiment.outside import grouping, read_runs, run_files
from rlcompare.studies import compare_runs

FILES, POINTS = 100, 10_000


def write(root: Path) -> None:
    from tensorboard.summary import Writer

    rng = np.random.default_rng(0)
    for index in range(FILES):
        method, seed = ("ppo", "dqn")[index % 2], index // 2
        writer = Writer(str(root / f"CartPole-v1__{method}__{seed}__1700000000"))
        values = np.cumsum(rng.normal(0.05 if method == "ppo" else 0.04, 1.0, POINTS))
        for step, value in enumerate(values):
            writer.add_scalar("charts/episodic_return", float(value), step=100 * step)
        writer.close()


def accumulator_seconds(files: list[Path]) -> float:
    from tensorboard.backend.event_processing.event_accumulator import TENSORS, EventAccumulator

    started = time.perf_counter()
    for path in files:
        accumulator = EventAccumulator(str(path), size_guidance={TENSORS: 0})
        accumulator.Reload()
        accumulator.Tensors("charts/episodic_return")
    return time.perf_counter() - started


def main() -> None:
    with tempfile.TemporaryDirectory() as directory:
        root = Path(directory) / "runs"
        write(root)
        started = time.perf_counter()
        top, files = run_files([root])
        frame = read_runs(files, top, grouping("{env}__{method}__{seed}__*/*"))
        read = time.perf_counter() - started
        started = time.perf_counter()
        compare_runs.report(Path(directory) / "out", frame, paired=False, margin=None)
        reported = time.perf_counter() - started
        theirs = accumulator_seconds(files)
    print(f"{FILES} TensorBoard files x {POINTS:,} points ({len(frame):,} in all):")
    print(f"  read:   {read:6.2f} s ({len(frame) / read:,.0f} points/s)")
    print(f"  report: {reported:6.2f} s")
    print(f"  total:  {read + reported:6.2f} s (the issue's bound: 20 s)")
    print(f"  TensorBoard's EventAccumulator on the same files: {theirs:6.2f} s; ours / theirs {read / theirs:.2f}")


if __name__ == "__main__":
    main()
