"""The Ray backend on a real cluster started here on loopback: a head node and one more node, the second
killed in the middle of a sweep. Every trial must still finish exactly once, equal to the local backend's."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from rlcompare.engine.kernel import Records
from rlcompare.experiment.backends import LocalBackend
from rlcompare.experiment.sweep import parse_sweep
from rlcompare.experiment.sweep_store import MANIFEST_FILE, load_configurations, read_table, run_sweep

pytest.importorskip("ray")

RAY = str(Path(sys.executable).parent / "ray")
SWEEP = """
[sweep]
name = "ray"
root_seed = 3
seeds = 6

[fixed]
env = "Acrobot-v1"
episodes = 1500
eval_every = 500
eval_episodes = 2

[grid]
algorithm = ["q_learning", "sarsa"]
"""
NODE = ["--node-ip-address=127.0.0.1", "--num-cpus=1", "--object-store-memory=80000000", "--disable-usage-stats",
        "--block"]
TEST_CLUSTER = {"RAY_health_check_period_ms": "1000", "RAY_health_check_timeout_ms": "1000",
                "RAY_health_check_failure_threshold": "3", "RAY_health_check_initial_delay_ms": "1000",
                "RAY_AUTH_MODE": "disabled"}
"""Node deaths noticed within seconds; no token authentication on loopback (a token left in ~/.ray by another
Ray session would otherwise lock ``ray status`` out)."""


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _start(args: list[str], log: Path, env: dict[str, str]) -> subprocess.Popen:
    """A ``ray start --block`` in its own process group, so that killing the group stops the whole node."""
    with log.open("ab") as output:
        return subprocess.Popen([RAY, "start", *args, *NODE], stdout=output, stderr=output, env=env,
                                start_new_session=True)


def _nodes(address: str, env: dict[str, str]) -> int:
    status = subprocess.run([RAY, "status", f"--address={address}"], capture_output=True, text=True, env=env,
                            check=False)
    if status.returncode != 0:
        return 0
    active = status.stdout.split("Active:")[1].split("Pending:")[0] if "Active:" in status.stdout else ""
    return active.count("node_")


def _wait_for_nodes(address: str, count: int, env: dict[str, str], log: Path, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while _nodes(address, env) != count:
        assert time.monotonic() < deadline, f"the cluster at {address} did not reach {count} nodes:\n" + (
            log.read_text()[-3000:] if log.exists() else "")
        time.sleep(0.5)


def _stop(process: subprocess.Popen) -> None:
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)  # whatever the node left in its group


@pytest.fixture
def cluster():
    """A head node on loopback (one CPU), torn down with everything it started."""
    temp = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))  # Ray's socket paths must stay short
    env = {**os.environ, **TEST_CLUSTER}
    address = f"127.0.0.1:{_free_port()}"
    head = _start(["--head", f"--port={address.split(':')[1]}", "--include-dashboard=false",
                   f"--temp-dir={temp}"], temp / "head.log", env)
    nodes = [head]
    try:
        _wait_for_nodes(address, 1, env, temp / "head.log")
        yield address, env, temp, nodes
    finally:
        for node in reversed(nodes):
            _stop(node)
        shutil.rmtree(temp, ignore_errors=True)


def test_ray_sweep_loses_a_node_and_still_finishes_every_trial_exactly_once(cluster, tmp_path: Path) -> None:
    address, env, temp, nodes = cluster
    sweep = parse_sweep(SWEEP)
    reference = tmp_path / "local"
    run_sweep(sweep, SWEEP, reference, LocalBackend(2))  # the result to match, and the kernels compiled for Ray
    nodes.append(_start([f"--address={address}"], temp / "node.log", env))
    _wait_for_nodes(address, 2, env, temp / "node.log")

    sweep_file, out = tmp_path / "ray.toml", tmp_path / "ray"
    sweep_file.write_text(SWEEP)
    log = tmp_path / "sweep.log"
    with log.open("wb") as output:
        driver = subprocess.Popen([sys.executable, "-m", "rlcompare.cli", "sweep", str(sweep_file), "--out", str(out),
                                   "--backend", "ray", "--address", address, "--no-report"],
                                  stdout=output, stderr=output, env=env)
    deadline = time.monotonic() + 180
    while _done(out) < 3:
        assert driver.poll() is None, log.read_text()
        assert time.monotonic() < deadline, log.read_text()
        time.sleep(0.1)
    done_at_kill = _done(out)
    os.killpg(nodes[1].pid, signal.SIGKILL)  # the second node, with a trial in flight
    nodes[1].wait()
    assert driver.wait(timeout=300) == 0, log.read_text()
    assert done_at_kill < len(sweep.trials())
    _wait_for_nodes(address, 1, env, temp / "head.log")  # the head saw the node die

    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert sorted(t["id"] for t in manifest["trials"]) == sorted(t.trial_id for t in sweep.trials())
    assert all(t["status"] == "done" for t in manifest["trials"])
    assert len(list(out.glob("trials/*/*/meta.json"))) == len(sweep.trials())
    rows = read_table(out).groupby(["config", "seed"]).size()
    assert len(rows) == len(sweep.trials())
    assert rows.eq(1500).all()  # each trial's episodes once
    ours, theirs = load_configurations(out)[0], load_configurations(reference)[0]
    assert ours.keys() == theirs.keys()
    for key in ours:  # bit-identical to the local backend
        for name in Records._fields:
            np.testing.assert_array_equal(getattr(ours[key].records, name), getattr(theirs[key].records, name))


def _done(out: Path) -> int:
    return len(list(out.glob("trials/*/*/meta.json")))
