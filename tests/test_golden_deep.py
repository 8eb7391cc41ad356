"""Golden outputs of the deep engine: a spread of tiny configurations whose records and parameters must stay equal
across refactors, at the fixed vmap width (``docs/deep.md``: a seed's numbers depend on the width, not on the
seeds beside it).

``tests/golden/deep.json`` holds, per configuration, the SHA-256 of every training and evaluation record (returns,
lengths, endings, the steps they ended at) and, per parameter array, its sum and sum of squares. The records are
compared exactly; the parameters to a relative 1e-9, so that a different summation order in numpy's reductions of
the same arrays cannot fail the test while any change to training does. Rewrite with
``RLCOMPARE_WRITE_GOLDEN=1 pytest tests/test_golden_deep.py`` and say why in the commit.
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


def fingerprint(results: DeepResults) -> dict:
    """The digest of every record, and each parameter array's sum and sum of squares."""
    sha = hashlib.sha256()
    for frame in (results.episodes, results.evaluations):
        for name in frame.columns:
            sha.update(name.encode())
            sha.update(np.ascontiguousarray(frame[name].to_numpy()).tobytes())
    params = {name: [float(np.sum(array, dtype=np.float64)), float(np.sum(np.square(array, dtype=np.float64)))]
              for name, array in sorted(results.params.items())}
    return {"records": sha.hexdigest(), "params": params}


def test_deep_golden_outputs_are_unchanged():
    found = {name: fingerprint(deep_run(config)) for name, config in CONFIGS.items()}
    if os.environ.get("RLCOMPARE_WRITE_GOLDEN"):
        GOLDEN.write_text(json.dumps(found, indent=1, sort_keys=True) + "\n")
        pytest.skip("deep golden outputs rewritten")
    expected = json.loads(GOLDEN.read_text())
    assert sorted(found) == sorted(expected)
    changed = sorted(name for name in expected if found[name]["records"] != expected[name]["records"])
    assert not changed, f"records changed for {changed}"
    for name, fingerprints in expected.items():
        assert sorted(found[name]["params"]) == sorted(fingerprints["params"]), name
        for leaf, values in fingerprints["params"].items():
            np.testing.assert_allclose(found[name]["params"][leaf], values, rtol=1e-9, err_msg=f"{name} {leaf}")
