"""The Ray backend on a real cluster started here on loopback: a head node and one more node, the second
killed in the middle of a sweep. Every trial must still finish exactly once, equal to the local backend's.

The cluster stays on this machine: no Ray process listens outside 127.0.0.0/8, every node registers as
127.0.0.1 and nothing is sent elsewhere. Ray binds its servers (GCS, raylet and object manager, runtime-env
agent, workers, the driver) to 127.0.0.1 only when the node's address is 127.0.0.1, and otherwise to all
interfaces. But ``ray start`` and ``ray.init`` replace 127.0.0.1, given as ``--node-ip-address`` or in
``--address``, by the address of the route to 8.8.8.8 (``services.resolve_ip_for_localhost``), unless
``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0`` (:data:`TEST_CLUSTER`), which in turn refuses to start a second
node; :data:`RAY_START` starts it all the same, on 127.0.0.1.
"""

from __future__ import annotations

import contextlib
import ipaddress
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

from rlcompare.experiment.backends import LocalBackend
from rlcompare.experiment.sweep import parse_sweep
from rlcompare.experiment.sweep_store import MANIFEST_FILE, load_configurations, read_table, run_sweep
from rlcompare.tabular.state import Records

pytest.importorskip("ray")

pytestmark = pytest.mark.slow("starts a Ray cluster on loopback")

RAY = str(Path(sys.executable).parent / "ray")
LOOPBACK = "127.0.0.1"
RAY_START = f"""
import sys

import ray._private.ray_constants as constants
import ray._private.services as services
from ray.scripts.scripts import main

constants.ENABLE_RAY_CLUSTER = True  # a node joining the head, which RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0 refuses
services.node_ip_address_from_perspective = lambda address=None: {LOOPBACK!r}  # and this machine is still 127.0.0.1
sys.argv = ["ray", "start", *sys.argv[1:]]
sys.exit(main())
"""
"""``ray start``, for the head and the second node, where the machine's address is 127.0.0.1."""
DEAD_PROXY = f"http://{LOOPBACK}:9"
"""Where Ray's HTTP requests go instead (the discard port, closed): the head's usage-stats module asks cloud
metadata services (169.254.169.254, metadata.google.internal) for the provider and reports to
usage-stats.ray.io that usage stats are disabled, whatever ``--disable-usage-stats`` says."""
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
NODE = [f"--node-ip-address={LOOPBACK}", "--num-cpus=1", "--object-store-memory=80000000", "--disable-usage-stats",
        "--min-worker-port=0", "--max-worker-port=0", "--block"]
"""Workers listen on ports of their own choosing (on 127.0.0.1), not on ports the raylet first tries on
0.0.0.0."""
TEST_CLUSTER = {"RAY_health_check_period_ms": "1000", "RAY_health_check_timeout_ms": "1000",
                "RAY_health_check_failure_threshold": "3", "RAY_health_check_initial_delay_ms": "1000",
                "RAY_AUTH_MODE": "disabled", "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_ADDRESS": "",
                "RAY_USAGE_STATS_ENABLED": "0", "http_proxy": DEAD_PROXY, "https_proxy": DEAD_PROXY,
                "all_proxy": DEAD_PROXY, "no_proxy": f"{LOOPBACK},localhost,::1"}
"""Node deaths noticed within seconds; no token authentication on loopback (a token left in ~/.ray by another
Ray session would otherwise lock ``ray status`` out); every Ray process (the nodes, their agents and workers,
the driver, ``ray status``) takes 127.0.0.1 for this machine's address and keeps 127.0.0.1 in ``--address``;
no cluster but the one given; no usage stats; HTTP only on loopback."""


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _start(args: list[str], log: Path, env: dict[str, str]) -> subprocess.Popen:
    """A ``ray start --block`` in its own process group, so that killing the group stops the whole node."""
    with log.open("ab") as output:
        return subprocess.Popen([sys.executable, "-c", RAY_START, *args, *NODE], stdout=output, stderr=output,
                                env=env, start_new_session=True)


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
    """Stop a node's whole process group: SIGTERM, then SIGKILL. ``ray start --block`` was still running 30 s
    after a SIGTERM to its group, so the grace is short."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=2)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)  # whatever the node left in its group


@pytest.fixture
def cluster():
    """A head node on loopback (one CPU), torn down with everything it started."""
    with loopback_cluster() as started:
        yield started


@contextlib.contextmanager
def loopback_cluster():
    """A head node on loopback (one CPU): ``(address, env, Ray's directory, nodes)``; nodes added to ``nodes`` are
    stopped with it."""
    temp = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))  # Ray's socket paths must stay short
    env = {**os.environ, **TEST_CLUSTER}
    address = f"{LOOPBACK}:{_free_port()}"
    head = _start(["--head", f"--port={address.split(':')[1]}", "--include-dashboard=false",
                   f"--dashboard-host={LOOPBACK}", f"--temp-dir={temp}"], temp / "head.log", env)
    nodes = [head]
    try:
        _wait_for_nodes(address, 1, env, temp / "head.log")
        yield address, env, temp, nodes
    finally:
        for node in reversed(nodes):
            _stop(node)
        shutil.rmtree(temp, ignore_errors=True)


def test_ray_sweep_loses_a_worker_a_node_and_its_driver_and_still_finishes_every_trial_exactly_once(
        cluster, tmp_path: Path) -> None:
    """Killed with SIGKILL in turn, each with trials in flight: one worker process (Ray runs its task again),
    the second node (Ray runs its tasks on the head), then the driver itself (the same command resumes, running
    only the trials not saved). Every trial is saved once, bit-identical to the local backend's."""
    address, env, temp, nodes = cluster
    sweep = parse_sweep(SWEEP)
    reference = tmp_path / "local"
    run_sweep(sweep, SWEEP, reference, LocalBackend(2))  # the result to match, and the kernels compiled for Ray
    nodes.append(_start([f"--address={address}"], temp / "node.log", env))
    _wait_for_nodes(address, 2, env, temp / "node.log")

    sweep_file, out = tmp_path / "ray.toml", tmp_path / "ray"
    sweep_file.write_text(SWEEP)
    command = [sys.executable, "-m", "rlcompare.cli", "sweep", str(sweep_file), "--out", str(out), "--backend", "ray",
               "--address", address, "--no-report"]
    log = tmp_path / "sweep.log"
    with log.open("wb") as output:
        driver = subprocess.Popen(command, stdout=output, stderr=output, env=env, start_new_session=True)

    def wait_for(trials: int) -> None:
        deadline = time.monotonic() + 180
        while _done(out) < trials:
            assert driver.poll() is None, log.read_text()
            assert time.monotonic() < deadline, log.read_text()
            time.sleep(0.05)

    wait_for(1)
    ray_processes = _processes([node.pid for node in nodes], driver.pid)
    assert _listening_outside_loopback(ray_processes) == []
    deadline = time.monotonic() + 60
    while not (workers := _running_trials(_processes([nodes[0].pid]))):  # between two of its trials: wait
        assert driver.poll() is None, log.read_text()
        assert time.monotonic() < deadline, "no worker of the head node ran a trial"
        time.sleep(0.01)
    os.kill(workers[0], signal.SIGKILL)  # one worker, mid-trial
    wait_for(_done(out) + 2)
    os.killpg(nodes[1].pid, signal.SIGKILL)  # the second node, with a trial in flight
    nodes[1].wait()
    wait_for(_done(out) + 2)
    os.killpg(driver.pid, signal.SIGKILL)  # the driver, with trials in flight
    driver.wait()
    saved = _done(out)
    assert saved < len(sweep.trials())
    resumed = subprocess.run(command, capture_output=True, text=True, env={**env, "COLUMNS": "300"}, timeout=300,
                             check=False)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert f"{len(sweep.trials()) - saved} trials run, {saved} already finished" in resumed.stdout
    _wait_for_nodes(address, 1, env, temp / "head.log")  # the head saw the node die
    assert _registered_addresses(address, env) == [LOOPBACK, LOOPBACK]  # the head and the dead node

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


def _running_trials(processes: set[int]) -> list[int]:
    """Those of ``processes`` that are Ray workers running a trial (Ray titles a worker by its task)."""
    running = []
    for pid in processes:
        with contextlib.suppress(OSError):
            if Path(f"/proc/{pid}/cmdline").read_bytes().startswith(b"ray::run_trial"):
                running.append(pid)
    return running


def _registered_addresses(address: str, env: dict[str, str]) -> list[str]:
    """``NodeManagerAddress`` of every node the cluster knows, dead or alive, from ``ray.nodes()``."""
    script = (f"import json, ray; ray.init(address={address!r}, logging_level='ERROR', log_to_driver=False); "
              "print(json.dumps(sorted(n['NodeManagerAddress'] for n in ray.nodes())))")
    answer = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, check=False,
                            timeout=120)
    assert answer.returncode == 0, answer.stderr[-3000:]
    return json.loads(answer.stdout.strip().splitlines()[-1])


def _processes(groups: list[int], *roots: int) -> set[int]:
    """The processes in the process groups ``groups`` (each node's ``ray start`` and everything it started),
    ``roots``, and their descendants."""
    parents, found = {}, set(roots)
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        with contextlib.suppress(OSError):
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            parents[int(entry.name)] = int(fields[1])
            if int(fields[2]) in groups:
                found.add(int(entry.name))
    while children := {pid for pid, parent in parents.items() if parent in found} - found:
        found |= children
    return found


def _socket_inodes(pids: set[int]) -> dict[str, int]:
    """The inodes of the sockets the processes ``pids`` hold, each to one of its holders."""
    inodes = {}
    for pid in pids:
        with contextlib.suppress(OSError):
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                with contextlib.suppress(OSError):
                    target = os.readlink(fd)
                    if target.startswith("socket:["):
                        inodes[target[8:-1]] = pid
    return inodes


def _address(hex_address: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """An address as ``/proc/net/tcp`` writes it: hexadecimal 32-bit words in the machine's byte order."""
    raw = bytes.fromhex(hex_address)
    if sys.byteorder == "little":
        raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    return ipaddress.ip_address(raw)


def _is_loopback(address: ipaddress.IPv4Address | ipaddress.IPv6Address) -> bool:
    mapped = getattr(address, "ipv4_mapped", None)
    return (mapped or address).is_loopback


def _listening_outside_loopback(pids: set[int]) -> list[str]:
    """``address:port (pid)`` of each TCP socket listening, or UDP socket bound and unconnected, outside
    127.0.0.0/8 and ::1 (``0.0.0.0`` and ``::`` included) and held by one of ``pids``."""
    owners, found = _socket_inodes(pids), []
    for table, listening in (("tcp", "0A"), ("tcp6", "0A"), ("udp", "07"), ("udp6", "07")):
        with contextlib.suppress(FileNotFoundError):
            for line in Path(f"/proc/net/{table}").read_text().splitlines()[1:]:
                fields = line.split()
                local, remote, state, inode = fields[1], fields[2], fields[3], fields[9]
                if inode in owners and state == listening and int(remote.split(":")[0], 16) == 0:
                    host, port = local.split(":")
                    if not _is_loopback(address := _address(host)):
                        shown = f"[{address}]" if address.version == 6 else str(address)
                        found.append(f"{shown}:{int(port, 16)} ({table}, pid {owners[inode]})")
    return found
