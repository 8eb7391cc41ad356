"""What a trial's Ray task asks of a cluster (:func:`rlcompare.experiment.backends.task_resources`), and that the
Ray backend asks it for every task."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from rlcompare.experiment import backends
from rlcompare.experiment.backends import RayBackend, task_resources

CPU_NODES = [{"CPU": 16.0, "memory": 1e11}, {"CPU": 4.0}]
GPU_NODES = [{"CPU": 16.0}, {"CPU": 8.0, "GPU": 2.0}]


@pytest.mark.parametrize(("engine", "nodes", "asked"), [
    ("tabular", CPU_NODES, {"num_cpus": 1, "num_gpus": 0}),
    ("tabular", GPU_NODES, {"num_cpus": 1, "num_gpus": 0}),  # a table never needs a GPU
    ("deep", CPU_NODES, {"num_cpus": 4.0, "num_gpus": 0}),  # XLA spans the node: the smallest node's cores
    ("deep", GPU_NODES, {"num_cpus": 1, "num_gpus": 1}),  # a GPU of its own
    ("deep", [{"CPU": 2.0, "GPU": 0.5}], {"num_cpus": 2.0, "num_gpus": 0}),  # half a GPU is none to ask for whole
    ("deep", [], {"num_cpus": 1, "num_gpus": 0}),
])
def test_a_trial_asks_for_what_it_uses(engine: str, nodes: list[dict[str, float]], asked: dict[str, float]) -> None:
    assert task_resources({"engine": engine}, nodes) == asked


def test_the_ray_backend_asks_each_task_for_its_trials_resources(monkeypatch: pytest.MonkeyPatch) -> None:
    """A stand-in for Ray records the options of every task the backend submits."""
    submitted: list[dict[str, Any]] = []

    class Remote:
        def options(self, **options: Any) -> Any:
            return SimpleNamespace(remote=lambda config: submitted.append({**options, "engine": config["engine"]})
                                   or len(submitted))

    fake = SimpleNamespace(is_initialized=lambda: True, remote=lambda **_: lambda function: Remote(),
                           nodes=lambda: [{"Alive": True, "Resources": {"CPU": 8.0, "GPU": 1.0}},
                                          {"Alive": False, "Resources": {"CPU": 64.0}}],
                           wait=lambda refs, num_returns: (refs[:1], refs[1:]), get=lambda ref: ref)
    monkeypatch.setattr(backends, "_import_ray", lambda: fake)
    trials = [SimpleNamespace(config=SimpleNamespace(to_dict=lambda e=e: {"engine": e})) for e in ("deep", "tabular")]
    done: list[Any] = []
    RayBackend(address=None).run(trials, lambda trial, results: done.append(results))  # type: ignore[arg-type]
    assert submitted == [{"num_cpus": 1, "num_gpus": 1, "engine": "deep"},
                         {"num_cpus": 1, "num_gpus": 0, "engine": "tabular"}]
    assert sorted(done) == [1, 2]
