"""A diverged training is marked, not reported as a result (issue 39): its run records after which update its
parameters stopped being finite, and a sweep's table and report name it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import invoke

from rlcompare.deep.train import diverged_at

SWEEP = """
[sweep]
name = "diverge"
engine = "deep"
seeds = 2
[fixed]
env = "CartPole-v1"
eval_rounds = 2
hyperparameters.total_steps = 8192
hyperparameters.max_grad_norm = 1e30
[grid]
algorithm = ["pqn_q_lambda"]
hyperparameters.learning_rate = [0.00025, 1e12]
"""


def test_the_first_update_without_finite_parameters_is_named_per_seed() -> None:
    finite = np.ones((3, 2, 4), bool)  # (seeds, rounds, updates per round)
    finite[1, 1, 2:] = False
    finite[2, 0, 0] = False
    finite[2, 0, 1] = True  # a seed that recovers is still one that diverged, from its first non-finite update
    assert diverged_at((10, 11, 12), finite) == {"11": 7, "12": 1}


@pytest.mark.slow("trains a deep sweep, one configuration of which diverges")
def test_a_sweep_with_a_diverging_learning_rate_marks_it_in_its_runs_table_and_report(tmp_path: Path) -> None:
    sweep_file, out = tmp_path / "diverge.toml", tmp_path / "store"
    sweep_file.write_text(SWEEP)
    result = invoke("sweep", str(sweep_file), "--out", str(out))
    assert result.exit_code == 0, result.output
    diverged = {}
    for meta_file in sorted(out.glob("trials/*/*/meta.json")):
        config = json.loads((meta_file.parent / "config.json").read_text())
        diverged[config["hyperparameters"]["learning_rate"]] = json.loads(meta_file.read_text())["diverged"]
    assert diverged[0.00025] == {}
    assert list(diverged[1e12].values()) == [1]  # one seed per trial, its parameters NaN after the first update
    table = (out / "tables" / "configurations.csv").read_text().splitlines()
    assert table[0].endswith(",diverged seeds")
    assert sorted(line.rsplit(",", 1)[1] for line in table[1:]) == ["0", "2"]
    assert result.output.count("the training diverged in 2 of 2 seeds") == 1
    assert "the training diverged in 2 of 2 seeds" in (out / "report.html").read_text()
