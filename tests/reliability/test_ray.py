"""The Ray backend on a real cluster started here on loopback (:mod:`ray_cluster`): a head node and one more node,
the second killed in the middle of a sweep. Every trial must still finish exactly once, equal to the local
backend's, and no Ray process listens outside loopback."""

from __future__ import annotations

import contextlib
import ipaddress
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rlcompare.experiment.backends import LocalBackend
from rlcompare.experiment.sweep import parse_sweep
from rlcompare.experiment.sweep_store import MANIFEST_FILE, load_configurations, read_table, run_sweep
from rlcompare.tabular.state import Records

pytest.importorskip("ray")

from helpers import invoke
from ray_cluster import LOOPBACK, loopback_cluster, start_node, wait_for_nodes

pytestmark = pytest.mark.slow("starts a Ray cluster on loopback")

SWEEP = """
[sweep]
name = "ray"
root_seed = 3
seeds = 6

[fixed]
env = "Acrobot-v1"
episodes = 500
eval_every = 250
eval_episodes = 2

[grid]
algorithm = ["q_learning", "sarsa"]
"""


@pytest.fixture(scope="module")
def cluster():
    """A head node on loopback (one CPU, and one GPU declared to Ray, which no test uses), torn down with everything
    it started."""
    with loopback_cluster("--num-gpus=1") as started:
        yield started


def test_ray_sweep_loses_a_worker_a_node_and_its_driver_and_still_finishes_every_trial_exactly_once(
        cluster, tmp_path: Path) -> None:
    """Killed with SIGKILL in turn, each with trials in flight: one worker process (Ray runs its task again),
    the second node (Ray runs its tasks on the head), then the driver itself (the same command resumes, running
    only the trials not saved). Every trial is saved once, bit-identical to the local backend's."""
    address, env, temp, nodes = cluster
    sweep = parse_sweep(SWEEP)
    reference = tmp_path / "local"
    run_sweep(sweep, SWEEP, reference, LocalBackend(2))  # the result to match, and the kernels compiled for Ray
    nodes.append(start_node([f"--address={address}"], temp / "node.log", env))
    wait_for_nodes(address, 2, env, temp / "node.log")

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
    wait_for_nodes(address, 1, env, temp / "head.log")  # the head saw the node die
    assert _registered_addresses(address, env) == [LOOPBACK, LOOPBACK]  # the head and the dead node

    manifest = json.loads((out / MANIFEST_FILE).read_text())
    assert sorted(t["id"] for t in manifest["trials"]) == sorted(t.trial_id for t in sweep.trials())
    assert all(t["status"] == "done" for t in manifest["trials"])
    assert len(list(out.glob("trials/*/*/meta.json"))) == len(sweep.trials())
    rows = read_table(out).groupby(["config", "seed"]).size()
    assert len(rows) == len(sweep.trials())
    assert rows.eq(500).all()  # each trial's episodes once
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


@pytest.mark.parametrize(("command", "here"), [
    (["reproduce", "minatar", "--allow-undecidable", "--address"], "leave out --address to train here"),
    (["sweep", str(Path(__file__).parents[2] / "examples" / "sweep.toml"), "--backend", "ray", "--address"],
     "use --backend local"),
])
def test_a_cluster_that_cannot_be_reached_says_how_this_command_trains_here(command, here, tmp_path):
    """``reproduce atari --address`` suggested ``--backend local``, an option studies lack."""
    result = invoke(*command, "127.0.0.1:1", "--out", str(tmp_path / "out"), columns=400)
    assert result.exit_code == 2, result.output
    assert "no Ray cluster at '127.0.0.1:1'" in result.output
    assert result.output.rstrip().endswith(f"start one with 'ray start --head', or {here}")
    assert "Traceback" not in result.output


def test_ray_gives_a_networks_trial_a_gpu_of_its_own_and_a_tables_trial_one_cpu(cluster) -> None:
    """On the head, which declares a GPU to Ray, the options :func:`task_resources` gives are what Ray assigns: a deep
    trial one GPU, shown to it alone (``CUDA_VISIBLE_DEVICES``), and one CPU; a tabular trial one CPU and no GPU.
    Nothing here uses a GPU: Ray schedules the resources a node declares."""
    script = (
        "import json, os, ray\n"
        "from rlcompare.experiment.backends import task_resources\n"
        "ray.init(address=os.environ['ADDRESS'], logging_level='ERROR', log_to_driver=False)\n"
        "nodes = [n['Resources'] for n in ray.nodes() if n['Alive']]\n"
        "probe = ray.remote(lambda: (ray.get_runtime_context().get_assigned_resources(),\n"
        "                            os.environ.get('CUDA_VISIBLE_DEVICES')))\n"
        "asked = {e: task_resources({'engine': e}, nodes) for e in ('deep', 'tabular')}\n"
        "print(json.dumps({e: [a, ray.get(probe.options(**a).remote())] for e, a in asked.items()}))\n")
    address, env, _, _ = cluster
    answer = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=False,
                            env={**env, "ADDRESS": address}, timeout=180)
    assert answer.returncode == 0, answer.stderr[-3000:]
    found = json.loads(answer.stdout.strip().splitlines()[-1])
    assert found["deep"] == [{"num_cpus": 1, "num_gpus": 1}, [{"CPU": 1.0, "GPU": 1.0}, "0"]]
    assert found["tabular"][0] == {"num_cpus": 1, "num_gpus": 0}
    assert found["tabular"][1][0] == {"CPU": 1.0}
    assert found["tabular"][1][1] in (None, "")  # Ray shows a task that asked for none no GPU
