"""Where a sweep's trials run: on this machine's cores, or as tasks on a Ray cluster.

Both backends first ``connect()`` (so that a cluster that cannot be reached is reported before the store
is touched), then take the trials still to run and call ``on_done(trial, results)`` in the calling process as
each one finishes, in whatever order they finish; the caller writes them to the store, so a trial is saved
by one process only, once (the local backend calls it from its worker threads, so that trials are saved in
parallel too; the Ray backend from the driver, as results stream back). A trial's result depends on its
configuration and seed alone (each run owns its random streams), so every backend gives the same results
bit for bit, whatever the number of workers.

- ``local``: a pool of threads. Each trial is one run, whose compiled kernel releases the GIL, so threads
  train in parallel without the cost of starting processes (and of loading the compiled kernels in each).
- ``ray``: one Ray task per trial, retried by Ray on another node when a node is lost, and streamed back with
  ``ray.wait`` as each finishes. Each task asks for what it uses (:func:`task_resources`): a tabular trial one CPU;
  a network's trial one GPU where the cluster has GPUs (Ray then shows it that GPU alone), else the cores of the
  smallest node, which XLA's thread pool spans. Ray is an optional dependency
  (``pip install 'rlcompare[ray]'``), imported only here, and only when this backend runs. Every node needs
  rlcompare installed in the same version (a shared environment, or a Ray ``runtime_env``).
"""

from __future__ import annotations

import importlib.util
import os
import socket
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Any, Protocol

from rlcompare.experiment import engines
from rlcompare.experiment.interrupts import trainings
from rlcompare.experiment.runner import run
from rlcompare.experiment.sweep import Trial, config_dict

BACKENDS = ("local", "ray")
OnDone = Callable[[Trial, Any], None]
"""Called with a trial and its results (its engine's: a deep sweep's :class:`~rlcompare.deep.results.DeepResults`)."""


class BackendError(RuntimeError):
    """A backend that cannot start: Ray missing, or no cluster at the address."""


class Backend(Protocol):
    """Where a sweep's trials run: joined first, then given the trials."""

    def connect(self) -> None:
        """Join the machines the trials run on, or fail with a :class:`BackendError` saying why."""
        ...

    def run(self, trials: Iterable[Trial], on_done: OnDone) -> None:
        """Run every trial, calling ``on_done(trial, results)`` as each one finishes."""
        ...


def task_resources(config: dict[str, Any], nodes: list[dict[str, float]]) -> dict[str, float]:
    """What the Ray task of a trial (``config``, as :func:`~rlcompare.experiment.sweep.config_dict` gives it) asks
    of a cluster whose alive nodes hold ``nodes`` (Ray's resources of each): ``num_cpus`` and ``num_gpus``.

    A tabular trial: one CPU (a sweep's trial is one seed, trained on one thread). A deep trial: where a node has a
    GPU, one GPU and one CPU, so that tasks never share a GPU and each JAX process sees only its own (Ray sets
    ``CUDA_VISIBLE_DEVICES``; JAX takes 75% of the memory it sees); on CPUs only, the cores of the smallest node,
    since XLA's thread pool spans every core of the node it runs on: two such tasks on one node would each run at
    half speed with twice the memory."""
    if config.get("engine") != "deep":
        return {"num_cpus": 1, "num_gpus": 0}
    if any(node.get("GPU", 0) >= 1 for node in nodes):
        return {"num_cpus": 1, "num_gpus": 1}
    return {"num_cpus": min((node.get("CPU", 1) for node in nodes), default=1), "num_gpus": 0}


def run_trial(config: dict[str, Any]) -> Any:
    """Train one trial from its configuration (a plain dict, cheap to ship to a remote worker) on the engine it
    names (:mod:`rlcompare.experiment.engines`), imported only then."""
    return run(engines.config_from_dict(config))


@dataclass(frozen=True)
class LocalBackend:
    """Trials on ``workers`` threads of this machine."""

    workers: int = os.cpu_count() or 1

    def connect(self) -> None:
        """Nothing to join: this machine's threads are always there."""

    def run(self, trials: Iterable[Trial], on_done: OnDone) -> None:
        """Run every trial, at most ``workers`` at once; on an interrupt, stop submitting, save what is
        finished, and let the trials in flight end (a compiled run cannot be stopped midway)."""
        pending = iter(trials)
        with ThreadPoolExecutor(self.workers, thread_name_prefix="trial") as pool:
            running: dict[Future[None], Trial] = {}
            with trainings(lambda: {future: f"{trial.config.name} seed {trial.seed}"
                                    for future, trial in running.items()}):
                self._fill(pool, running, pending, on_done)
                while running:
                    finished, _ = wait(running, return_when=FIRST_COMPLETED)
                    for future in finished:
                        running.pop(future)
                        future.result()  # a trial that failed stops the sweep with its error
                    self._fill(pool, running, pending, on_done)

    def _fill(self, pool: ThreadPoolExecutor, running: dict[Future[None], Trial], pending: Iterator[Trial],
              on_done: OnDone) -> None:
        while len(running) < self.workers:
            trial = next(pending, None)
            if trial is None:
                return
            running[pool.submit(_run_and_save, trial, on_done)] = trial


def _run_and_save(trial: Trial, on_done: OnDone) -> None:
    on_done(trial, run_trial(config_dict(trial.config)))


@dataclass(frozen=True)
class RayBackend:
    """Trials as Ray tasks on the cluster at ``address`` (``auto``: the one started on this machine with
    ``ray start``; ``HOST:PORT``: any other; None: a new local Ray instance)."""

    address: str | None = "auto"
    max_retries: int = 3
    """Times Ray runs a task again when its worker or node dies."""
    num_cpus: int | None = None
    """CPUs of the new local Ray instance started where ``address`` is None; None: every core."""
    here: str = "use --backend local"
    """How the command that made this backend trains on this machine instead, for a refusal to say."""

    def connect(self) -> None:
        """Join the cluster, or fail with a :class:`BackendError` saying why."""
        ray = _import_ray()
        if ray.is_initialized():
            return
        _check_reachable(self.address, self.here)
        try:
            ray.init(address=self.address, num_cpus=self.num_cpus, logging_level="ERROR", log_to_driver=False,
                     configure_logging=False)
        except Exception as error:  # no cluster there, a refused token, a version mismatch
            raise BackendError(f"cannot use the Ray cluster at {self.address!r} ({error}); start one with "
                               f"'ray start --head', or {self.here}") from None

    def cpus(self) -> int:
        """CPUs of the cluster, once connected."""
        return int(_import_ray().cluster_resources().get("CPU", 1))

    def run(self, trials: Iterable[Trial], on_done: OnDone) -> None:
        self.connect()
        ray = _import_ray()
        remote = ray.remote(max_retries=self.max_retries)(run_trial)
        nodes = [node["Resources"] for node in ray.nodes() if node["Alive"]]
        running = {}
        for trial in trials:
            config = config_dict(trial.config)
            running[remote.options(**task_resources(config, nodes)).remote(config)] = trial
        try:
            while running:
                finished, _ = ray.wait(list(running), num_returns=1)
                for ref in finished:
                    on_done(running.pop(ref), ray.get(ref))
        except BaseException:
            for ref in running:
                ray.cancel(ref, force=True)
            raise


def _check_reachable(address: str | None, here: str) -> None:
    """Fail at once on a HOST:PORT where nothing listens (Ray itself would retry for a minute or more), saying how
    to train ``here`` instead."""
    if not address or address == "auto" or "://" in address:
        return
    host, _, port = address.rpartition(":")
    try:
        with socket.create_connection((host or "127.0.0.1", int(port)), timeout=2):
            pass
    except (OSError, ValueError) as error:
        raise BackendError(f"no Ray cluster at {address!r} ({error}); start one with 'ray start --head', or "
                           f"{here}") from None


def ray_installed() -> bool:
    """Whether Ray can be imported (the optional dependency of the Ray backend), without importing it."""
    return importlib.util.find_spec("ray") is not None


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise BackendError("the Ray backend needs Ray: pip install 'rlcompare[ray]'") from None
    return ray


def make_backend(name: str, *, workers: int | None = None, address: str | None = "auto") -> LocalBackend | RayBackend:
    if name == "local":
        return LocalBackend(workers or os.cpu_count() or 1)
    if name == "ray":
        return RayBackend(address)
    raise BackendError(f"backend: got {name!r}; allowed: {', '.join(BACKENDS)}")
