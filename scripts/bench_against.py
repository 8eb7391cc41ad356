"""Steps per second of this checkout against another commit, measured in one run, alternating processes.

    .venv/bin/python scripts/bench_against.py 38f0cad

Checks the commit out into a temporary worktree, then for each method measures both versions in turn (8 seeds,
ε = 0.5, median of 3, after a warm-up that compiles or loads the loop) with ``kernel_steps_per_second``, which both
versions have, and prints a Markdown table with the ratio.
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
import json, sys
from rlcompare.bench.tabular import kernel_steps_per_second
alg, features, episodes, threads = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
kernel_steps_per_second(alg, threads, features=features, runs=2, episodes=3, repeats=1)
m = kernel_steps_per_second(alg, threads, features=features, runs=8, episodes=episodes, repeats=3)
print(json.dumps(m.steps / m.seconds))
"""


def steps_per_second(src: Path, algorithm: str, features: str, episodes: int, threads: int) -> float:
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_NUM_THREADS=str(max(threads, 2)))
    done = subprocess.run([sys.executable, "-W", "ignore", "-c", MEASURE, algorithm, features, str(episodes),
                           str(threads)], env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(ref: str) -> None:
    here = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        other = Path(tmp) / "other"
        subprocess.run(["git", "-C", str(here), "worktree", "add", "--detach", str(other), ref], check=True,
                       capture_output=True)
        try:
            print(f"| method | features | threads | {ref} M steps/s | this M steps/s | this / {ref} |")
            print("|---|---|---|---|---|---|")
            for algorithm, features, episodes, threads in PLAN:
                old = steps_per_second(other / "src", algorithm, features, episodes, threads)
                new = steps_per_second(here / "src", algorithm, features, episodes, threads)
                print(f"| {algorithm} | {features} | {threads} | {old / 1e6:.2f} | {new / 1e6:.2f} | {new / old:.2f} |",
                      flush=True)
        finally:
            subprocess.run(["git", "-C", str(here), "worktree", "remove", "--force", str(other)], check=False)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "HEAD~1")
