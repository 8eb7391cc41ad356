"""``rlcompare bench kernels``: steps per second of every method's kernel on 1 and all threads, against the
method's reference kernel (:mod:`rlcompare.bench.reference`) and a plain Gymnasium loop, measured in one run."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from rlcompare.algorithms.registry import METHODS
from rlcompare.bench.harness import (
    Measurement,
    gymnasium_steps_per_second,
    kernel_and_reference,
    kernel_steps_per_second,
    thread_counts,
    threads_text,
)
from rlcompare.bench.reference import REFERENCES
from rlcompare.bench.tables import BenchTable, Measured, Say, Stage

ONE_STEP = tuple(name for name, m in METHODS.items() if m.one_step)
MULTI_STEP = tuple(name for name, m in METHODS.items() if m.family not in ("baseline", "one-step"))
"""The other learners: n-step, traces and policy gradient, benchmarked on shorter runs."""


def run_benchmark(report: Callable[[Measurement], None] = lambda m: None) -> list[Measurement]:
    """Every measurement, reported as it is taken: the Gymnasium loop, the one-step methods, then the other
    learners (shorter runs), and two on tiles. A method with a reference kernel (:data:`REFERENCES`) is measured
    in turn with it, on the same seeds and threads."""
    plan = [(algorithm, "grid", 2000) for algorithm in ONE_STEP]
    plan += [(algorithm, "grid", 300) for algorithm in MULTI_STEP]
    plan += [(algorithm, "tiles", 300) for algorithm in ("sarsa", "sarsa_lambda")]
    measurements = [gymnasium_steps_per_second(steps=30_000)]
    report(measurements[-1])
    for algorithm, features, episodes in plan:
        for n in thread_counts():
            if features == "grid" and algorithm in REFERENCES:
                ours, plain = kernel_and_reference(algorithm, n, episodes=episodes)
                measurements.append(replace(ours, reference=plain))
            else:
                measurements.append(kernel_steps_per_second(algorithm, n, features=features, episodes=episodes))
            report(measurements[-1])
    return measurements


def kernel_line(m: Measurement) -> str:
    """One of :func:`run_benchmark`'s measurements as it is taken."""
    return (f"{m.label}, {threads_text(m.threads)}: {m.steps_per_second:,.0f} steps/s"
            + ("" if m.vs_reference is None else f", {m.vs_reference:.2f}x its reference kernel"))


def kernel_table(measurements: list[Measurement]) -> BenchTable:
    """:func:`run_benchmark`'s measurements, each against its method's reference kernel (same seeds, same threads),
    the Gymnasium loop (the first) and its own 1 thread."""
    reference = measurements[0].steps_per_second
    single = {m.label: m.steps_per_second for m in measurements if m.threads == 1}
    rows: list[tuple[str, ...]] = [
        (m.label, str(m.threads), f"{m.steps_per_second:,.0f}",
         "" if m.reference is None else f"{m.reference.steps_per_second:,.0f}",
         "" if m.vs_reference is None else f"{m.vs_reference:.2f}x",
         f"{m.steps_per_second / reference:,.0f}x", f"{m.steps_per_second / single[m.label]:.2f}x")
        for m in measurements]
    return BenchTable("Every algorithm on MountainCar-v0, 20 bins (one step: act, step, update)",
                      ("what", "threads", "steps/s", "reference kernel steps/s", "vs reference kernel",
                       "vs Gymnasium", "vs 1 thread"), rows,
                      ("reference kernel: the method written plainly by hand for tabular Mountain Car alone "
                       "(rlcompare.bench.reference.REFERENCES), trained on the same seeds and threads in turn",))


def kernel_rows(measurements: list[Measurement]) -> list[dict[str, object]]:
    """:func:`run_benchmark`'s measurements as the JSON file keeps them: each kernel row with its ratios."""
    loop = measurements[0].steps_per_second
    single = {m.label: m.steps_per_second for m in measurements if m.threads == 1}
    return [{**m.as_dict(), "reference": None if m.reference is None else m.reference.as_dict(),
             "vs_reference": m.vs_reference, "vs_gymnasium": m.steps_per_second / loop,
             "vs_one_thread": m.steps_per_second / single[m.label]} for m in measurements[1:]]


def measure_kernels(say: Say) -> Measured:
    """:func:`run_benchmark`, each measurement said as it is taken: its table, the loop and the kernel rows."""
    measured = run_benchmark(report=lambda m: say(kernel_line(m)))
    return Measured(kernel_table(measured), {"gymnasium_loop": measured[0].as_dict(),
                                             "kernels": kernel_rows(measured)})


KERNEL_STAGE = Stage("every algorithm on MountainCar-v0, on 1 and all threads, after a plain Gymnasium loop; each "
                      "method with a reference kernel in turn with it", measure_kernels)
