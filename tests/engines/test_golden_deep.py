"""Golden outputs of the deep engine: a spread of tiny configurations whose records and parameters must stay equal
across refactors, at the fixed vmap width (``docs/deep.md``: a seed's numbers depend on the width, not on the
seeds beside it).

``tests/engines/golden/deep.json`` holds, per configuration, the SHA-256 of every training and evaluation record
(returns, lengths, endings, the steps they ended at), compared exactly, and of the final parameters (every seed's
array, by its path in the parameter tree) eight random projections, compared to within :data:`PARAMS_RTOL` of the
array's norm. The records are the same bits on every x86-64 CPU; the float32 parameters are not: XLA:CPU vectorises
for the machine it runs on and sums in another order on another CPU (measured on these configurations: 5e-7 of an
array's largest value between ``--xla_cpu_max_isa=AVX2`` and AVX-512 on one machine, and the sum of one array 2e-5
of its norm apart between two machines), while a change to the method moves them by a percent or more. A change
meant to change results rewrites the file with ``RLCOMPARE_WRITE_GOLDEN=1 pytest
tests/engines/test_golden_deep.py`` and says why in its commit.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("jax")

from rlcompare.deep.config import DeepConfig
from rlcompare.deep.results import DeepResults
from rlcompare.experiment.runner import run as deep_run

GOLDEN = Path(__file__).parent / "golden" / "deep.json"
TINY = {"seeds": (0, 3), "vmap_width": 2, "eval_rounds": 2, "eval_episodes": 2}
CONFIGS = {
    "pqn_q_lambda-cartpole": DeepConfig(algorithm="pqn_q_lambda", env="CartPole-v1",
                                        hyperparameters={"total_steps": 4096}, **TINY),
    "pqn_sarsa_lambda-acrobot": DeepConfig(algorithm="pqn_sarsa_lambda", env="Acrobot-v1",
                                           hyperparameters={"total_steps": 4096}, **TINY),
    "dqn-cartpole": DeepConfig(algorithm="dqn", env="CartPole-v1",
                               hyperparameters={"total_steps": 2048, "learning_starts": 512}, **TINY),
    "ppo-mountaincar": DeepConfig(algorithm="ppo", env="MountainCar-v0", hyperparameters={"total_steps": 2048},
                                  **TINY),
}


PARAMS_RTOL = 1e-3
"""How far a parameter projection may move, as a fraction of the array's norm (the projections' own scale)."""
PROJECTIONS = 8


def projections(array: np.ndarray) -> list[float]:
    """``G @ array`` for a fixed Gaussian ``G`` of :data:`PROJECTIONS` rows, then the array's norm, in float64."""
    flat = array.astype(np.float64).ravel()
    gaussian = np.random.default_rng(0).standard_normal((PROJECTIONS, flat.size))
    return [*(gaussian @ flat).tolist(), float(np.linalg.norm(flat))]


def fingerprint(results: DeepResults) -> dict:
    """The SHA-256 of every record column, and the projections of every parameter array by its path."""
    records = hashlib.sha256()
    for frame in (results.episodes, results.evaluations):
        for name in frame.columns:
            records.update(name.encode())
            records.update(np.ascontiguousarray(frame[name].to_numpy()).tobytes())
    params = {f"{name} {array.dtype} {array.shape}": projections(array) for name, array in results.params.items()}
    return {"records": records.hexdigest(), "params": dict(sorted(params.items()))}


def params_moved(found: dict[str, list[float]], expected: dict[str, list[float]]) -> list[str]:
    """The arrays missing, added or moved beyond :data:`PARAMS_RTOL` of their norm."""
    if sorted(found) != sorted(expected):
        return sorted(set(found) ^ set(expected))
    return [name for name in expected
            if not np.allclose(found[name], expected[name], rtol=0.0, atol=PARAMS_RTOL * expected[name][-1])]


def test_params_projections_tell_float32_rounding_from_a_change():
    rng = np.random.default_rng(1)
    array = rng.standard_normal((64, 64)).astype(np.float32)
    rounded = array * (1 + 1e-5 * rng.standard_normal(array.shape)).astype(np.float32)
    changed = array * (1 + 1e-2 * rng.standard_normal(array.shape)).astype(np.float32)
    expected = {"w": projections(array)}
    assert not params_moved({"w": projections(rounded)}, expected)
    assert params_moved({"w": projections(changed)}, expected) == ["w"]


@pytest.mark.slow("trains the deep engine's golden configurations")
def test_deep_golden_outputs_are_unchanged():
    found = {name: fingerprint(deep_run(config)) for name, config in CONFIGS.items()}
    if os.environ.get("RLCOMPARE_WRITE_GOLDEN"):
        GOLDEN.write_text(json.dumps(found, indent=1, sort_keys=True) + "\n")
        pytest.skip("deep golden outputs rewritten")
    expected = json.loads(GOLDEN.read_text())
    assert sorted(found) == sorted(expected)
    changed = [f"{name} records" for name in expected if found[name]["records"] != expected[name]["records"]]
    changed += [f"{name} params: {', '.join(moved)}" for name in expected
                if (moved := params_moved(found[name]["params"], expected[name]["params"]))]
    assert not changed, f"deep results changed: {changed}"
