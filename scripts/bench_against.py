"""Steps per second of this checkout against another commit, measured in one run, alternating processes.

    .venv/bin/python scripts/bench_against.py 38f0cad

Checks the commit out into a temporary worktree, then for each method measures both versions in turn (8 seeds,
ε = 0.5, median of 3, after a warm-up that compiles or loads the loop) with ``kernel_steps_per_second``, which both
versions have, and the method's reference kernel where it has one (``reference_seconds``), and prints a Markdown
table with the ratios.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

PLAN = [("q_learning", "grid", 1000, 1), ("sarsa", "grid", 1000, 1), ("expected_sarsa", "grid", 1000, 1),
        ("double_q_learning", "grid", 1000, 1), ("random", "grid", 1000, 1), ("n_step_sarsa", "grid", 200, 1),
        ("sarsa_lambda", "grid", 150, 1), ("q_lambda", "grid", 150, 1), ("reinforce", "grid", 150, 1),
        ("sarsa", "tiles", 150, 1), ("sarsa_lambda", "tiles", 150, 1), ("q_learning", "grid", 1000, 2)]
MEASURE = """
import json, statistics, sys
try:
    from rlcompare.bench import harness
except ImportError:  # a commit whose benchmark is one module
    from rlcompare.experiment import benchmark as harness
alg, features, episodes, threads = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
harness.kernel_steps_per_second(alg, threads, features=features, runs=2, episodes=3, repeats=1)
m = harness.kernel_steps_per_second(alg, threads, features=features, runs=8, episodes=episodes, repeats=3)
reference = None
if features == "grid" and alg in harness.REFERENCES:
    config = harness.bench_config(alg, 8, episodes)
    with harness.numba_threads(threads):
        timings = [harness.reference_seconds(config) for _ in range(3)]
    reference = timings[0][0] / statistics.median(t[1] for t in timings)
print(json.dumps([m.steps / m.seconds, reference]))
"""


def steps_per_second(src: Path, algorithm: str, features: str, episodes: int, threads: int
                     ) -> tuple[float, float | None]:
    """rlcompare's kernel and the method's reference kernel (None without one), in steps per second, as the
    sources in ``src`` measure them in a process of their own."""
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_NUM_THREADS=str(max(threads, 2)))
    done = subprocess.run([sys.executable, "-W", "ignore", "-c", MEASURE, algorithm, features, str(episodes),
                           str(threads)], env=env, capture_output=True, text=True, check=True)
    kernel, reference = json.loads(done.stdout.strip().splitlines()[-1])
    return kernel, reference


def ratio_cells(old: float | None, new: float | None) -> str:
    """``old | new | new / old`` in millions of steps per second, blank where there is no measurement."""
    if old is None or new is None:
        return " | | "
    return f"{old / 1e6:.2f} | {new / 1e6:.2f} | {new / old:.2f}"


def main(ref: str) -> None:
    here = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        other = Path(tmp) / "other"
        subprocess.run(["git", "-C", str(here), "worktree", "add", "--detach", str(other), ref], check=True,
                       capture_output=True)
        try:
            print(f"| method | features | threads | {ref} M steps/s | this M steps/s | this / {ref} | "
                  f"{ref} reference kernel | this reference kernel | this / {ref} |")
            print("|---|---|---|---|---|---|---|---|---|")
            for algorithm, features, episodes, threads in PLAN:
                old = steps_per_second(other / "src", algorithm, features, episodes, threads)
                new = steps_per_second(here / "src", algorithm, features, episodes, threads)
                print(f"| {algorithm} | {features} | {threads} | {ratio_cells(old[0], new[0])} | "
                      f"{ratio_cells(old[1], new[1])} |", flush=True)
        finally:
            subprocess.run(["git", "-C", str(here), "worktree", "remove", "--force", str(other)], check=False)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "HEAD~1")
