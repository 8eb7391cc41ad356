"""Golden outputs of the deep engine: a spread of tiny configurations whose records and parameters must stay equal
across refactors, at the fixed vmap width (``docs/deep.md``: a seed's numbers depend on the width, not on the
seeds beside it).

``tests/golden/deep.json`` holds, per configuration, the SHA-256 of every training and evaluation record (returns,
lengths, endings, the steps they ended at) and the SHA-256 of the final parameters (every seed's array, by its path
in the parameter tree, with its dtype and shape), both compared exactly: XLA on CPU gives the same bits run after
run. A change meant to change results rewrites the file with ``RLCOMPARE_WRITE_GOLDEN=1 pytest
tests/test_golden_deep.py`` and says why in its commit.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("jax")

from rlcompare.deep.run import DeepConfig, DeepResults
from rlcompare.deep.run import run as deep_run

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


def fingerprint(results: DeepResults) -> dict[str, str]:
    """The SHA-256 of every record column, and of every parameter array with its path, dtype and shape."""
    records = hashlib.sha256()
    for frame in (results.episodes, results.evaluations):
        for name in frame.columns:
            records.update(name.encode())
            records.update(np.ascontiguousarray(frame[name].to_numpy()).tobytes())
    params = hashlib.sha256()
    for name, array in sorted(results.params.items()):
        params.update(f"{name} {array.dtype} {array.shape}".encode())
        params.update(np.ascontiguousarray(array).tobytes())
    return {"records": records.hexdigest(), "params": params.hexdigest()}


def test_deep_golden_outputs_are_unchanged():
    found = {name: fingerprint(deep_run(config)) for name, config in CONFIGS.items()}
    if os.environ.get("RLCOMPARE_WRITE_GOLDEN"):
        GOLDEN.write_text(json.dumps(found, indent=1, sort_keys=True) + "\n")
        pytest.skip("deep golden outputs rewritten")
    expected = json.loads(GOLDEN.read_text())
    assert sorted(found) == sorted(expected)
    changed = sorted(f"{name} {part}" for name in expected for part in ("records", "params")
                     if found[name][part] != expected[name][part])
    assert not changed, f"deep results changed: {changed}"
