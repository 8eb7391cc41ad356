"""The benchmark measures what it says: the training steps of the configuration it names, and reference kernels
that train as rlcompare does (no timing is asserted); and ``rlcompare bench`` runs what each of its commands names,
no more, printing and writing its own file, which ``rlcompare report`` shows again."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import invoke

from rlcompare import ExperimentConfig, run
from rlcompare.bench import kernels, ports, study, sweeps
from rlcompare.bench.harness import (
    Measurement,
    gymnasium_steps_per_second,
    kernel_and_reference,
    kernel_steps_per_second,
)
from rlcompare.bench.ports import PortMeasurement
from rlcompare.bench.reference import REFERENCES
from rlcompare.bench.tables import BENCH_FILES, BenchTable
from rlcompare.envs.features import make_features
from rlcompare.tabular.state import initial_state
from rlcompare.tabular.train import epsilon_schedule


def test_kernel_measurement_counts_the_training_steps_of_the_configuration_it_names() -> None:
    measured = kernel_steps_per_second("sarsa", 1, runs=2, episodes=30, repeats=1)
    same = run(ExperimentConfig(algorithm="sarsa", schedule="constant", epsilon=0.5, seeds=(0, 1), episodes=30,
                                eval_every=0, stages=(("final", 1.0),)))
    assert measured.steps == same.records.lengths.sum()
    assert measured.label == "sarsa (grid)"
    assert measured.seconds > 0


def test_port_benchmark_measures_the_gymnasium_loop_the_port_and_the_adapter_on_one_environment() -> None:
    loop = gymnasium_steps_per_second("CartPole-v1", steps=300)
    assert (loop.label, loop.steps) == ("CartPole-v1, Gymnasium loop", 300)
    port = kernel_steps_per_second("q_learning", 1, env="Taxi-v4", runs=2, episodes=5, repeats=1)
    adapter = kernel_steps_per_second("q_learning", 1, env="Taxi-v4", runs=2, episodes=5, repeats=1, adapter=True)
    assert (port.label, adapter.label) == ("Taxi-v4, compiled port", "Taxi-v4, Gymnasium adapter")
    assert port.steps == adapter.steps  # the same episodes, stepped two ways


@pytest.mark.parametrize("algorithm", sorted(REFERENCES))
def test_each_reference_kernel_trains_as_rlcompare_does_from_the_same_random_streams(algorithm: str) -> None:
    """The plain kernels the benchmark divides by do the same training: drawing from the same streams in the same
    order, they give every episode's return and length and the final table equal to rlcompare's, bit for bit, as
    ε decays from 1 to 0 (any other update, order of draws or time-limit rule would part them within episodes)."""
    config = ExperimentConfig(algorithm=algorithm, seeds=(0, 5), episodes=30, eval_every=0, stages=(("final", 1.0),))
    ours = run(config)
    kernel, extra = REFERENCES[algorithm]
    grid = make_features(config.environment, "grid", config.bins, config.tilings, config.tiles, config.hash_size)
    state = initial_state(list(config.seeds), grid.n_features, config.environment.n_actions)
    returns, lengths = np.zeros((2, config.episodes)), np.zeros((2, config.episodes), np.int64)
    kernel(state.rng, epsilon_schedule(config), grid, state.w, state.w2, config.alpha, config.gamma, config.max_steps,
           returns, lengths, *(getattr(config, name) for name in extra))
    table = (state.w + state.w2) / 2 if algorithm == "double_q_learning" else state.w
    assert np.array_equal(returns, ours.records.returns)
    assert np.array_equal(lengths, ours.records.lengths)
    assert np.array_equal(table, ours.records.snapshots[:, 0])
    assert lengths.sum() > 10_000  # long enough for ties, exploration and the time limit to have happened


def test_kernel_and_reference_are_measured_on_the_same_steps() -> None:
    ours, plain = kernel_and_reference("q_learning", 1, runs=2, episodes=5, repeats=1)
    assert ours.steps == plain.steps > 0
    assert (ours.label, plain.label) == ("q_learning (grid)", "q_learning, reference kernel")


# --- the command: each benchmark's measurements replaced by a few made-up ones, to see what runs and is written

LOOP = Measurement("MountainCar-v0, Gymnasium loop", 1, 1000, 1.0)
SARSA = Measurement("sarsa (grid)", 1, 5000, 0.05, Measurement("sarsa, reference kernel", 1, 5000, 0.1))
STUDY = [Measurement("9 configurations x 10 seeds x 5000 episodes, evaluation included", n, 10**7, 10.0 / n,
                     cpu_seconds=10.0) for n in (1, 2)]
TAXI = PortMeasurement("Taxi-v4", Measurement("Taxi-v4, Gymnasium loop", 1, 2000, 1.0),
                       [Measurement("Taxi-v4, compiled port", n, 10**6, 0.5 / n) for n in (1, 2)],
                       Measurement("Taxi-v4, Gymnasium adapter", 2, 2000, 0.5))
TITLES = {"kernels": "Every algorithm on MountainCar-v0", "study": "The paper's study on threads",
          "envs": "Q-Learning, ε = 0.5, on each port", "sweeps": "made-up sweeps", "deep": "made-up Mountain Car",
          "minatar": "made-up Breakout", "score": "made-up CartPole"}
SECTIONS = {"kernels": {"gymnasium_loop", "kernels"}, "study": {"study"}, "envs": {"ports"}, "sweeps": set()}


def made_up(name: str) -> BenchTable:
    """A table of the benchmarks that are not replaced by their measurements, wider than its title."""
    return BenchTable(TITLES[name], ("what", "steps/s"), [(f"{TITLES[name]}, one row", "1")])


def taking(called: list[str], name: str, result: object, each: tuple[object, ...] = ()):
    """A stand-in for a benchmark's measuring function: it notes its name, reports ``each`` and returns ``result``."""
    def measure(*args: object, report=lambda m: None, **kwargs: object) -> object:
        called.append(name)
        for measurement in each:
            report(measurement)
        return result
    return measure


@pytest.fixture
def measured(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """What each tabular benchmark measured, in order, by the name of its table in :data:`TITLES`."""
    called: list[str] = []
    monkeypatch.setattr(kernels, "run_benchmark", taking(called, "kernels", [LOOP, SARSA], (LOOP, SARSA)))
    monkeypatch.setattr(study, "study_threads", taking(called, "study", STUDY, tuple(STUDY)))
    monkeypatch.setattr(ports, "run_port_benchmark", taking(called, "envs", [TAXI], (TAXI,)))
    monkeypatch.setattr(sweeps, "sweep_benchmark",
                        taking(called, "sweeps", made_up("sweeps")))
    return called


def written(directory: Path) -> list[str]:
    return sorted(name for name in BENCH_FILES if (directory / name).exists())


@pytest.mark.parametrize("command", ["kernels", "study", "envs", "sweeps"])
def test_each_subcommand_measures_only_its_own_and_writes_its_own_file(command: str, measured: list[str],
                                                                       tmp_path: Path) -> None:
    result = invoke("bench", command, "--out", str(tmp_path))
    assert result.exit_code == 0, result.output
    assert measured == [command]
    assert written(tmp_path) == [f"{command}.json"]
    document = json.loads((tmp_path / f"{command}.json").read_text())
    assert [table["title"][:len(TITLES[command])] for table in document["tables"]] == [TITLES[command]]
    assert set(document) - {"created", "machine", "versions", "tables"} == SECTIONS[command]
    assert TITLES[command] in result.output
    assert f"Written: {tmp_path / f'{command}.json'}" in result.output


def test_bench_alone_measures_the_kernels_the_study_and_the_ports_into_bench_json(measured: list[str],
                                                                                 tmp_path: Path) -> None:
    result = invoke("bench", "--out", str(tmp_path / "bench"))
    assert result.exit_code == 0, result.output
    assert measured == ["kernels", "study", "envs"]
    assert written(tmp_path / "bench") == ["bench.json"]
    document = json.loads((tmp_path / "bench" / "bench.json").read_text())
    assert [table["title"].split(":")[0] for table in document["tables"]] == [
        "Every algorithm on MountainCar-v0, 20 bins (one step", "The paper's study on threads",
        "Q-Learning, ε = 0.5, on each port"]
    (row,) = document["kernels"]
    assert (row["label"], row["vs_reference"], row["vs_gymnasium"]) == ("sarsa (grid)", 2.0, 100.0)
    assert row["reference"]["steps_per_second"] == 50_000
    assert document["tables"][0]["rows"][1][:5] == ["sarsa (grid)", "1", "100,000", "50,000", "2.00x"]
    assert [m["threads"] for m in document["study"]] == [1, 2]
    assert document["ports"][0]["env"] == "Taxi-v4"
    assert [m["steps_per_second"] for m in document["ports"][0]["port"]] == [2_000_000, 4_000_000]
    said = result.output  # each measurement as it is taken, then its table
    assert "sarsa (grid), 1 thread: 100,000 steps/s, 2.00x its reference kernel" in said
    assert "2 threads: 5.00 s, 2,000,000 steps/s" in said
    assert "Taxi-v4: Gymnasium loop 2,000, port 4,000,000, adapter 4,000 steps/s" in said
    for cell in ("100,000", "50,000", "2.00x", "100x", "1.00x"):  # steps/s, the reference's, against it, against
        assert cell in said                                       # Gymnasium's loop, against 1 thread


@pytest.mark.slow("measures the kernels' speed")
def test_report_shows_every_file_bench_wrote_as_it_printed_it(measured: list[str], tmp_path: Path) -> None:
    for command in ("kernels", "sweeps"):
        assert invoke("bench", command, "--out", str(tmp_path)).exit_code == 0
    again = invoke("bench", "kernels", "--out", str(tmp_path))
    assert again.exit_code == 0, again.output  # its own file, rewritten
    shown = invoke("report", str(tmp_path))
    assert shown.exit_code == 0, shown.output
    kernel_part, sweep_part = shown.output.split("\nsweeps.json: measured ")
    document = json.loads((tmp_path / "kernels.json").read_text())
    assert kernel_part.startswith(f"kernels.json: measured {document['created'][:10]}")
    assert kernel_part.split("\n", 1)[1] + "\n" == again.output[again.output.index("Every algorithm"):
                                                                 again.output.index("Written:")]
    assert TITLES["sweeps"] in sweep_part
    (tmp_path / "kernels.json").write_text(json.dumps({**document, "tables": [{"title": "x"}]}))
    tampered = invoke("report", str(tmp_path))
    assert tampered.exit_code == 2
    assert tampered.output.strip() == f"Error: {tmp_path / 'kernels.json'}: not a benchmark rlcompare wrote " \
                                      "(no 'columns')"


@pytest.mark.parametrize(("args", "tables"), [((), ["deep", "minatar"]),
                                              (("--to-score",), ["deep", "minatar", "score"])])
def test_bench_deep_measures_the_deep_engine_and_the_time_to_score_only_when_asked(
        args: tuple[str, ...], tables: list[str], measured: list[str], monkeypatch: pytest.MonkeyPatch,
        tmp_path: Path) -> None:
    deep = pytest.importorskip("rlcompare.bench.deep")
    minatar = pytest.importorskip("rlcompare.bench.minatar")
    for module, name, function in ((deep, "deep", "deep_table"), (minatar, "minatar", "minatar_table"),
                                   (deep, "score", "score_table")):
        monkeypatch.setattr(module, function, taking(measured, name, made_up(name)))
    result = invoke("bench", "deep", *args, "--out", str(tmp_path))
    assert result.exit_code == 0, result.output
    assert measured == tables
    assert written(tmp_path) == ["deep.json"]
    document = json.loads((tmp_path / "deep.json").read_text())
    assert [table["title"] for table in document["tables"]] == [TITLES[name] for name in tables]


def test_out_before_the_subcommands_name_is_refused(measured: list[str], tmp_path: Path) -> None:
    result = invoke("bench", "--out", str(tmp_path), "kernels")
    assert result.exit_code == 2
    assert "put it after the name: rlcompare bench kernels --out" in result.output
    assert measured == []
    assert written(tmp_path) == []


def test_bench_sweeps_on_a_cluster_that_is_not_there_ends_with_one_line() -> None:
    result = invoke("bench", "sweeps", "--address", "127.0.0.1:1")
    assert result.exit_code == 2
    assert "no Ray cluster at '127.0.0.1:1'" in result.output
    assert "Traceback" not in result.output
