"""``rlcompare bench study``: a study's configurations trained as ``rlcompare reproduce`` trains them (the paper's: 9
configurations x 10 seeds x 5000 episodes, evaluation included), on 1 and on all threads in turn."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import replace

from rlcompare.bench.harness import Measurement, numba_threads, thread_counts, threads_text
from rlcompare.bench.tables import BenchTable, Measured, Say, Stage
from rlcompare.experiment.runner import run
from rlcompare.tabular.config import ExperimentConfig


def study_threads(configs: list[ExperimentConfig], repeats: int = 3,
                  report: Callable[[Measurement], None] = lambda m: None) -> list[Measurement]:
    """Training every configuration of a study (evaluation rounds included) on 1 and on all threads, measured in
    turn ``repeats`` times; each the median of its own. Steps are training and evaluation steps."""
    threads = thread_counts()
    for config in configs:  # compile or load every loop before the clock starts
        run(replace(config, seeds=config.seeds[:1], episodes=1))
    timings: dict[int, list[tuple[int, float, float]]] = {n: [] for n in threads}
    for _ in range(repeats):
        for n in threads:
            with numba_threads(n):
                steps, started, cpu = 0, time.perf_counter(), time.process_time()
                for config in configs:
                    timing = run(config).meta["timings"]
                    steps += timing["training_steps"] + timing["evaluation_steps"]
                timings[n].append((steps, time.perf_counter() - started, time.process_time() - cpu))
    label = (f"{len(configs)} configurations x {len(configs[0].seeds)} seeds x {configs[0].episodes} episodes, "
             "evaluation included")
    measurements = [Measurement(label, n, timings[n][0][0], statistics.median(t[1] for t in timings[n]),
                                cpu_seconds=statistics.median(t[2] for t in timings[n])) for n in threads]
    for measurement in measurements:
        report(measurement)
    return measurements


def study_line(m: Measurement) -> str:
    """One of :func:`study_threads`'s measurements as it is taken."""
    return f"{threads_text(m.threads)}: {m.seconds:.2f} s, {m.steps_per_second:,.0f} steps/s"


def study_table(measurements: list[Measurement]) -> BenchTable:
    """:func:`study_threads`'s measurements, each against 1 thread."""
    single = measurements[0].steps_per_second
    rows: list[tuple[str, ...]] = [
        (str(m.threads), f"{m.steps:,}", f"{m.seconds:.2f}", f"{m.steps_per_second:,.0f}",
         f"{m.steps_per_second / single:.2f}x", f"{(m.cpu_seconds or 0.0) / m.seconds:.2f}") for m in measurements]
    return BenchTable(f"The paper's study on threads: {measurements[0].label}",
                      ("threads", "steps", "seconds", "steps/s", "vs 1 thread", "cores used"), rows,
                      ("cores used: processor time over wall time (medians); below the threads, other work on the "
                       "machine had the rest",))


def study_stage(configs: list[ExperimentConfig]) -> Stage:
    """:func:`study_threads` on ``configs`` (the paper's study as ``reproduce`` trains it, which the command line
    gives), each measurement said as it is taken: its table and its measurements."""
    def measure(say: Say) -> Measured:
        threads = study_threads(configs, report=lambda m: say(study_line(m)))
        return Measured(study_table(threads), {"study": [m.as_dict() for m in threads]})

    return Stage("the paper's study on 1 and all threads, in turn", measure)
