"""A Ray cluster started here on loopback for the tests, a head node and nodes that join it.

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
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

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


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def start_node(args: list[str], log: Path, env: dict[str, str]) -> subprocess.Popen:
    """A ``ray start --block`` in its own process group, so that killing the group stops the whole node."""
    with log.open("ab") as output:
        return subprocess.Popen([sys.executable, "-c", RAY_START, *args, *NODE], stdout=output, stderr=output,
                                env=env, start_new_session=True)


def node_count(address: str, env: dict[str, str]) -> int:
    status = subprocess.run([RAY, "status", f"--address={address}"], capture_output=True, text=True, env=env,
                            check=False)
    if status.returncode != 0:
        return 0
    active = status.stdout.split("Active:")[1].split("Pending:")[0] if "Active:" in status.stdout else ""
    return active.count("node_")


def wait_for_nodes(address: str, count: int, env: dict[str, str], log: Path, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while node_count(address, env) != count:
        assert time.monotonic() < deadline, f"the cluster at {address} did not reach {count} nodes:\n" + (
            log.read_text()[-3000:] if log.exists() else "")
        time.sleep(0.5)


def stop_node(process: subprocess.Popen) -> None:
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


@contextlib.contextmanager
def loopback_cluster(*head: str) -> Iterator[tuple[str, dict[str, str], Path, list[subprocess.Popen]]]:
    """A head node on loopback (one CPU, and the resources ``head`` declares: ``--num-gpus=1``, say):
    ``(address, env, Ray's directory, nodes)``; nodes added to ``nodes`` are stopped with it."""
    temp = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))  # Ray's socket paths must stay short
    env = {**os.environ, **TEST_CLUSTER}
    address = f"{LOOPBACK}:{free_port()}"
    head = start_node(["--head", f"--port={address.split(':')[1]}", "--include-dashboard=false",
                   f"--dashboard-host={LOOPBACK}", f"--temp-dir={temp}", *head], temp / "head.log", env)
    nodes = [head]
    try:
        wait_for_nodes(address, 1, env, temp / "head.log")
        yield address, env, temp, nodes
    finally:
        for node in reversed(nodes):
            stop_node(node)
        shutil.rmtree(temp, ignore_errors=True)
