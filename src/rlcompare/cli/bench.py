"""``rlcompare bench``: one subcommand per benchmark of :mod:`rlcompare.bench.suites` (kernels, envs, study, chess,
selfplay, atari, sweeps, deep), each printing its tables as they are measured and writing them to its own JSON file
in OUT; ``bench`` alone measures the kernels, the paper's study and the ports into bench.json."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rlcompare.cli.app_help import SUMMARIES, PlainCommand, PlainGroup
from rlcompare.cli.console import (
    check_out,
    console,
    fail,
    measurement_lines,
    one_line_errors,
    out_path,
    print_bench,
)
from rlcompare.experiment import store

if TYPE_CHECKING:
    from rlcompare.bench.tables import Suite
    from rlcompare.tabular.config import ExperimentConfig

Out = Annotated[str | None, typer.Option(
    help="Directory of the JSON file of every row measured, rewritten by each run: bench.json for bench alone, "
         "else the subcommand's (kernels.json, envs.json, study.json, sweeps.json, deep.json); a new directory or "
         "one rlcompare wrote. Default: runs/bench.", show_default=False)]


def paper_study() -> list[ExperimentConfig]:
    """The paper's study as ``reproduce`` trains it: 9 configurations x 10 seeds x 5000 episodes."""
    from rlcompare.studies.paper.study import paper_configs

    return paper_configs(tuple(range(10)), 5000)


def measure(suite: Suite, out: str | None) -> None:
    """Each stage of ``suite`` in turn, its measurements said as they are taken; then its table printed, and every
    table and section so far written to the suite's file in ``out`` (what is measured stays, whatever follows)."""
    from rlcompare.bench.tables import BenchTable, bench_document

    out_dir = out_path(out, Path("runs/bench"))
    check_out(out_dir, store.BENCH, False)
    tables: list[BenchTable] = []
    sections: dict[str, object] = {}
    for stage in suite.stages:
        with measurement_lines(stage.what) as say:
            measured = stage.measure(say)
        print_bench(measured.table)
        tables.append(measured.table)
        sections.update(measured.sections)
        with store.output_directory(out_dir, store.BENCH) as directory:
            store.write_json_atomic(directory / suite.file, bench_document(tables, **sections))
    console.print(f"Written: {out_dir / suite.file}", highlight=False)


@one_line_errors
def kernels(out: Out = None) -> None:
    """Every method's kernel on 1 and all threads, against its reference kernel and a plain Gymnasium loop."""
    from rlcompare.bench import suites

    measure(suites.kernels(), out)


@one_line_errors
def chess(out: Out = None) -> None:
    """Q-Learning on the chess endgames (KRK, KQK) on 1 and all threads, beside a plain kernel for them alone."""
    from rlcompare.bench import suites

    measure(suites.chess(), out)


@one_line_errors
def selfplay(out: Out = None) -> None:
    """Self-play on Gardner's minichess: the chess study's training beside pgx's game alone (the 'deep' extra)."""
    from rlcompare.bench import suites

    measure(suites.selfplay(), out)


@one_line_errors
def atari(out: Out = None) -> None:
    """Atari's Breakout: the emulator alone and through the callback, each learner, SB3 (the 'atari' extra)."""
    from rlcompare.bench import suites

    try:
        suite = suites.atari()
    except ImportError as error:  # the atari extra, or the deep engine's DeepUnavailable, says how to install it
        fail(str(error))
    measure(suite, out)


@one_line_errors
def envs(out: Out = None) -> None:
    """Q-Learning on every ported environment: Gymnasium's loop, the port on 1 and all threads, the adapter."""
    from rlcompare.bench import suites

    measure(suites.envs(), out)


@one_line_errors
def study(out: Out = None) -> None:
    """The paper's study as reproduce trains it (9 configurations x 10 seeds x 5000 episodes), 1 and all threads."""
    from rlcompare.bench import suites

    measure(suites.study(paper_study()), out)


@one_line_errors
def sweeps(
    address: Annotated[str | None, typer.Option(help="The Ray cluster: HOST:PORT, or 'auto' (the cluster 'ray "
                                                     "start' began here). Default: a new local Ray instance with 2 "
                                                     "CPUs.", show_default=False)] = None,
    out: Out = None,
) -> None:
    """Trials per second of a sweep of short trials on the local backend (1 and 2 workers) and on Ray."""
    from rlcompare.bench import suites

    measure(suites.sweeps(address), out)


@one_line_errors
def deep(
    to_score: Annotated[bool, typer.Option("--to-score", help="Also the wall time to a greedy return of 475 on "
                                                             "CartPole, ours beside Stable-Baselines3 (several "
                                                             "minutes).")] = False,
    out: Out = None,
) -> None:
    """The deep engine's steps per second, beside Stable-Baselines3 where the 'bench' extra is installed."""
    from rlcompare.bench import suites

    try:
        suite = suites.deep(to_score)
    except ImportError as error:  # the deep engine's DeepUnavailable says how to install the extra
        fail(str(error))
    measure(suite, out)


@one_line_errors
def everything(ctx: typer.Context, out: Out = None) -> None:
    """Without a subcommand, the kernels, then the paper's study, then the ports, into bench.json; options before
    a subcommand's name are refused, since they are bench's own."""
    from rlcompare.bench import suites

    if ctx.invoked_subcommand is None:
        measure(suites.default(paper_study()), out)
    elif out is not None:
        fail(f"--out before the subcommand's name is bench's own; put it after the name: rlcompare bench "
             f"{ctx.invoked_subcommand} --out ...")


def bench_app() -> typer.Typer:
    """The ``bench`` group: ``bench`` alone runs the kernels, the study and the ports; a subcommand, its own."""
    app = typer.Typer(help="Steps per second of the kernels on 1 and all threads against a plain reference kernel "
                           "of each method and a plain Gymnasium loop, of the paper's study and of every ported "
                           "environment, into bench.json; or, with a subcommand's name, that benchmark alone, into "
                           "its own file.", short_help=SUMMARIES["bench"], rich_markup_mode="rich", cls=PlainGroup)
    app.callback(invoke_without_command=True)(everything)
    for command in (kernels, envs, study, chess, selfplay, atari, sweeps, deep):
        app.command(cls=PlainCommand)(command)
    return app
