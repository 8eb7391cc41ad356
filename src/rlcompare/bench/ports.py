"""``rlcompare bench envs``: Q-Learning with ε = 0.5 on every ported environment, three ways: Gymnasium's loop, the
compiled port on 1 and all threads, and the kernels stepping Gymnasium through the adapter."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from rlcompare.bench.harness import (
    Measurement,
    all_threads,
    gymnasium_steps_per_second,
    kernel_steps_per_second,
    thread_counts,
)
from rlcompare.bench.tables import BenchTable, Measured, Say, Stage
from rlcompare.envs.registry import PORTS, TABLE_ENVIRONMENTS, environment

PORT_EPISODES = {name: environment(name).bench_episodes for name in (*PORTS, *TABLE_ENVIRONMENTS)
                 if environment(name).bench_episodes}
"""Episodes per seed of Q-Learning with ε = 0.5 that make about a million steps on each port (its entry's)."""


@dataclass(frozen=True)
class PortMeasurement:
    """One environment three ways: Gymnasium's loop, the compiled port on 1 and all threads, the adapter."""

    env: str
    gymnasium: Measurement
    port: list[Measurement]
    adapter: Measurement

    def as_dict(self) -> dict[str, object]:
        return {"env": self.env, "gymnasium": self.gymnasium.as_dict(), "port": [x.as_dict() for x in self.port],
                "adapter": self.adapter.as_dict()}


def run_port_benchmark(envs: tuple[str, ...] = tuple(PORT_EPISODES),
                       report: Callable[[PortMeasurement], None] = lambda m: None) -> list[PortMeasurement]:
    """Q-Learning with ε = 0.5 on each ported environment: the Gymnasium loop, the port, and the adapter
    (the same kernels stepping Gymnasium, 2 seeds)."""
    measurements = []
    for env in envs:
        gymnasium = gymnasium_steps_per_second(env, steps=20_000)
        port = [kernel_steps_per_second("q_learning", n, env=env, episodes=PORT_EPISODES[env])
                for n in thread_counts()]
        adapter = kernel_steps_per_second("q_learning", all_threads(), env=env, adapter=True, runs=2,
                                          episodes=max(1, PORT_EPISODES[env] // 50), repeats=1)
        measurements.append(PortMeasurement(env, gymnasium, port, adapter))
        report(measurements[-1])
    return measurements


def port_line(m: PortMeasurement) -> str:
    """One of :func:`run_port_benchmark`'s measurements as it is taken."""
    return (f"{m.env}: Gymnasium loop {m.gymnasium.steps_per_second:,.0f}, port "
            f"{max(x.steps_per_second for x in m.port):,.0f}, adapter {m.adapter.steps_per_second:,.0f} steps/s")


def port_table(measurements: list[PortMeasurement]) -> BenchTable:
    """:func:`run_port_benchmark`'s measurements, each against Gymnasium's loop on the same environment."""
    rows: list[tuple[str, ...]] = []
    for m in measurements:
        loop = m.gymnasium.steps_per_second
        cells = [f"{x.steps_per_second:,.0f} ({x.steps_per_second / loop:,.0f}x)" for x in m.port]
        rows.append((m.env, f"{loop:,.0f}", *cells,
                     f"{m.adapter.steps_per_second:,.0f} ({m.adapter.steps_per_second / loop:.2f}x)"))
    return BenchTable("Q-Learning, ε = 0.5, on each port: steps/s, and the ratio to Gymnasium's loop on the same "
                      "environment", ("environment", "Gymnasium loop", "port, 1 thread", "port, all threads",
                                      "adapter"), rows)


def measure_ports(say: Say) -> Measured:
    """:func:`run_port_benchmark` on every port, each said as it is measured: its table and its measurements."""
    ports = run_port_benchmark(report=lambda m: say(port_line(m)))
    return Measured(port_table(ports), {"ports": [m.as_dict() for m in ports]})


PORT_STAGE = Stage("each ported environment: Gymnasium's loop, the port, the adapter", measure_ports)
