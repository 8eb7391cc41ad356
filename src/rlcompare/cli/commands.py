"""The ``rlcompare`` app with every command: parse, call one library function, print.

Its top-level help is :mod:`rlcompare.cli.app_help`'s, which answers ``rlcompare --help`` without importing this
module.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, ParamSpec

import typer
from rich.text import Text

from rlcompare.cli.app_help import SUMMARIES, PlainCommand, new_app
from rlcompare.cli.bench import bench_app
from rlcompare.cli.config_options import ALGORITHM_HELP, config_options
from rlcompare.cli.console import (
    ConsoleUI,
    announce_compiling,
    bad_option,
    check_out,
    console,
    done_line,
    fail,
    one_line_errors,
    out_path,
    plural,
    print_error,
    print_frame,
    print_report,
    progress_bars,
)
from rlcompare.cli.reports import bench_report, run_report, sweep_report
from rlcompare.cli.reproduce import FORCE_HELP, reproduce_app
from rlcompare.cli.uci import uci
from rlcompare.experiment import store
from rlcompare.studies.registry import STUDIES
from rlcompare.tabular.config import ExperimentConfig

__all__ = ["ALGORITHM_HELP", "app"]

P = ParamSpec("P")
app = new_app()
app.add_typer(bench_app(), name="bench", short_help=SUMMARIES["bench"])
app.add_typer(reproduce_app(), name="reproduce", short_help=SUMMARIES["reproduce"])
Force = Annotated[bool, typer.Option("--force", help=FORCE_HELP)]


def command(name: str) -> Callable[[Callable[P, None]], Callable[P, None]]:
    """Register a function as the command ``name``: its summary, plain help, errors in one line."""

    def register(function: Callable[P, None]) -> Callable[P, None]:
        return app.command(name, short_help=SUMMARIES[name], cls=PlainCommand)(one_line_errors(function))

    return register


def progress_label(config: ExperimentConfig) -> str:
    """A configuration's name, and how its environment is stepped when that is at Python speed."""
    if config.environment.is_ported:
        return config.name
    return f"{config.name} ({config.env} through Gymnasium's API: Python speed)"


@command("run")
@config_options
def run(
    config: ExperimentConfig,
    out: Annotated[str | None, typer.Option(help="Run directory to write (new, empty, or a run directory "
                                                 "rlcompare wrote). Default: runs/run.", show_default=False)] = None,
    force: Force = False,
) -> None:
    """Train one configuration over many seeds and write its run directory."""
    from rlcompare.experiment.runner import damage_of, refuse_replacing
    from rlcompare.experiment.runner import run as run_experiment
    from rlcompare.studies.paper.study import summary

    out_dir = out_path(out, Path("runs/run"))
    check_out(out_dir, store.RUN, force)
    if not config.environment.is_ported:
        console.print(progress_label(config))
    announce_compiling()
    with store.output_directory(out_dir, store.RUN, force=force), progress_bars() as progress:
        if not force:
            refuse_replacing(out_dir, {"": config})
        damaged = damage_of(out_dir, config)
        if damaged:
            console.print(Text(f"A damaged run, trained again: {damaged}", style="yellow"), highlight=False)
        task = progress.add_task(progress_label(config), total=config.episodes)
        results = run_experiment(config, out=out_dir, progress=lambda n: progress.advance(task, n))
    console.print(done_line(config.name, results, reused=False), highlight=False)
    print_frame(*summary([results], paper=False))
    console.print(f"Run directory: {out_dir}")


@command("sweep")
def sweep(
    sweep_file: Annotated[Path, typer.Argument(
        metavar="SWEEP_FILE", help="A sweep file (TOML); see examples/sweep.toml, or examples/sweep-deep.toml for "
                                   "deep configurations.")],
    out: Annotated[str | None, typer.Option(
        help="The sweep's store (new, empty, or a sweep store rlcompare wrote). Default: runs/sweeps/NAME.",
        show_default=False)] = None,
    backend: Annotated[str, typer.Option(help="local (this machine's cores) or ray (a Ray cluster).")] = "local",
    workers: Annotated[int | None, typer.Option(help="Local backend: trials at once. Default: every core.")] = None,
    address: Annotated[str, typer.Option(help="Ray backend: 'auto' (the cluster 'ray start' began here) or "
                                              "HOST:PORT.")] = "auto",
    group_by: Annotated[list[str] | None, typer.Option(
        help="Also write the report's table grouped by this swept key; repeat the option.")] = None,
    report_: Annotated[bool, typer.Option("--report/--no-report", help="Build report.html at the end.")] = True,
    force: Force = False,
    show_plan: Annotated[bool, typer.Option("--plan", help="Print every configuration with its seeds and the "
                                                           "episodes or steps each trial runs, and exit without "
                                                           "training or writing anything.")] = False,
) -> None:
    """Run every configuration of a sweep over its seeds; finished trials in OUT are kept, the rest run."""
    from rlcompare.experiment.backends import BACKENDS
    from rlcompare.experiment.sweep import SweepError, load_sweep
    from rlcompare.experiment.sweep_store import run_sweep
    from rlcompare.studies.interface import run_trials

    try:
        plan = load_sweep(sweep_file)
    except SweepError as error:
        print_error(f"{error.source}: every problem of the sweep file", tuple(error.problems))
        raise typer.Exit(2) from None
    if backend not in BACKENDS:
        raise typer.BadParameter(f"got {backend!r}; allowed: {', '.join(BACKENDS)}", param_hint="'--backend'")
    if workers is not None and workers < 1:
        raise typer.BadParameter(f"got {workers}; allowed: an integer >= 1", param_hint="'--workers'")
    unknown = [key for key in group_by or [] if key not in plan.swept]
    if unknown:
        raise typer.BadParameter(f"got {unknown[0]!r}; allowed: a swept key ({', '.join(plan.swept) or 'none'})",
                                 param_hint="'--group-by'")
    out_dir = out_path(out, Path("runs") / "sweeps" / plan.name)
    check_out(out_dir, store.SWEEP, force)
    if show_plan:
        from rlcompare import pace
        from rlcompare.studies.plans import sweep_plan

        for line in sweep_plan(plan).lines(pace.stored()):
            console.print(line, highlight=False, soft_wrap=True)
        return
    finished, ran = run_trials(
        plan, backend, workers, address, f"on the {backend} backend; store {out_dir}", ConsoleUI(),
        lambda executor, progress: run_sweep(plan, sweep_file.read_text(), out_dir, executor, progress=progress,
                                             force=force))
    console.print(f"{ran} trials run, {finished} already finished")
    if report_:
        sweep_report(out_dir, tuple(group_by or ()))


@command("report")
def report(
    study_dir: Annotated[Path, typer.Argument(
        metavar="STUDY_DIR", help="A study directory written by reproduce, a sweep's store, one run directory "
                                  "(written by run, or one configuration of a study), or bench's directory.")],
    videos: Annotated[bool, typer.Option(help="Render videos of the greedy agents (studies that draw them).")
                      ] = True,
    group_by: Annotated[list[str] | None, typer.Option(
        help="A sweep: also write its table grouped by this swept key; repeat the option.")] = None,
) -> None:
    """Rebuild the tables, verdicts, figures, videos and report.html of a study or a sweep, without training. Given
    one run directory: its results over seeds (and the study it belongs to, if any)."""
    from rlcompare.cli.reproduce import load_runner

    allowed = ("a study directory written by 'rlcompare reproduce', a sweep's store, a run directory, or the "
               "directory 'rlcompare bench' wrote")
    if not study_dir.is_dir():
        raise typer.BadParameter(f"{study_dir} is not a directory; allowed: {allowed}", param_hint="'STUDY_DIR'")
    owner = store.owner_of(study_dir)
    if owner == store.SWEEP:
        sweep_report(study_dir, tuple(group_by or ()))
    elif owner == store.RUN:
        run_report(study_dir)
    elif owner == store.BENCH:
        bench_report(study_dir)
    elif owner is not None and owner.kind == "study" and owner.name in STUDIES:
        print_report(load_runner(STUDIES[owner.name]).report(study_dir, ConsoleUI(), videos=videos))
    else:
        what = f"holds {owner}" if owner is not None else "was not written by rlcompare (it holds no .rlcompare.json)"
        raise typer.BadParameter(f"{study_dir} {what}; allowed: {allowed}", param_hint="'STUDY_DIR'")


@command("compare")
def compare(
    paths: Annotated[list[Path], typer.Argument(
        metavar="PATH...", help="Directories to search for Stable-Baselines3 Monitor files (*.monitor.csv), RL Zoo "
                                "evaluations (evaluations.npz) and TensorBoard event files, or those files, or tidy "
                                "tables (.csv, .parquet) of method, env, seed, step, value.")],
    group: Annotated[str, typer.Option(help="How a file's path, below the directory given (or the common one of "
                                            "several), names its method, environment and seed: {method}, {env} and "
                                            "{seed} once each, * for any name.")] = "{method}/{env}/{seed}/*",
    tag: Annotated[str | None, typer.Option(help="The scalar of TensorBoard event files to read. Default: the first "
                                                 "there of charts/episodic_return (CleanRL), eval/mean_reward, "
                                                 "rollout/ep_rew_mean (Stable-Baselines3).")] = None,
    files: Annotated[str, typer.Option("--files", help="The kinds of run file the directories given are searched "
                                                       "for, comma-separated: monitor (*.monitor.csv), evaluations "
                                                       "(evaluations.npz), tensorboard (events.out.tfevents.*). RL "
                                                       "Zoo keeps a run's Monitor files and evaluations in one "
                                                       "directory: read one of them.")
                 ] = "monitor,evaluations,tensorboard",
    paired: Annotated[bool, typer.Option(help="The seeds share randomness across methods (seed s of each on the "
                                              "same starts): compare them pair by pair. Default: independent.")
                      ] = False,
    cut_to_shortest: Annotated[bool, typer.Option(help="Compare runs that end at different steps (budgets of "
                                                       "episodes) on the steps every one reached; without it such "
                                                       "runs are refused.")] = False,
    margin: Annotated[float | None, typer.Option(help="The difference that counts as none, in the values' units, "
                                                      "declared before reading the report; without it no "
                                                      "comparison is called equivalent.", min=0.0)] = None,
    metric: Annotated[str, typer.Option(help="The metrics compared, declared before reading the report, comma-"
                                             "separated: final (the mean of the points in the last tenth of the "
                                             "steps) and auc (the mean over all the steps of the value in force); "
                                             "each one more doubles the family the tests are corrected over.")
                      ] = "final",
    scores: Annotated[list[str] | None, typer.Option(help="An environment's reference scores, ENV=LOW:HIGH (a "
                                                          "random policy's and an expert's, say), that the "
                                                          "aggregates across environments normalise by; repeat the "
                                                          "option. An Atari game's published random and human "
                                                          "scores are known.")] = None,
    out: Annotated[str | None, typer.Option(help="Directory to write the report into (new, empty, or one compare "
                                                 "wrote). Default: runs/compare.", show_default=False)] = None,
    force: Force = False,
    plan: Annotated[bool, typer.Option("--plan", help="Print the design the report would test (the family, whether "
                                                      "these seeds can decide, the difference each comparison can "
                                                      "detect) and stop: nothing is tested or written.")] = False,
) -> None:
    """Verdicts and a report for runs other libraries made: what each file was taken as is printed first."""
    from rlcompare.experiment.formats import FILES, OutsideRunError
    from rlcompare.experiment.outside import grouping, read_runs, run_files
    from rlcompare.studies import compare_runs
    from rlcompare.studies.compare_numbers import METRICS
    from rlcompare.studies.interface import listed
    from rlcompare.validation import ConfigError

    out_dir = out_path(out, Path("runs/compare"))
    check_out(out_dir, compare_runs.COMPARISON, force)
    try:
        rule = grouping(group)
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint="'--group'") from None
    if margin is not None and margin <= 0:
        raise typer.BadParameter(f"{margin:g}; allowed: a positive number", param_hint="'--margin'")
    try:
        metrics = listed("metric", metric, tuple(METRICS))
        kinds = listed("files", files, tuple(FILES))
        references = compare_runs.parse_scores(scores or [])
    except ConfigError as error:
        raise bad_option(error) from None
    try:
        root, found = run_files(paths, kinds)
        frame = read_runs(found, root, rule, tag)
        print_frame(compare_runs.pairing_table(frame), f"What each file was taken as (rule {group!r}, below {root})")
        if plan:
            for line in compare_runs.plan(frame, paired=paired, margin=margin, cut=cut_to_shortest, metrics=metrics):
                console.print(line, highlight=False, soft_wrap=True)
            return
        shown = compare_runs.report(out_dir, frame, paired=paired, margin=margin, cut=cut_to_shortest, force=force,
                                    metrics=metrics, scores=references)
    except OutsideRunError as error:
        fail(str(error))
    print_report(shown)


EXPORT = store.Owner("export")


@command("export")
def export(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", help="A run directory (written by run, or one "
                                                                   "configuration of a study).")],
    to: Annotated[str, typer.Option(help="csv (the tidy table: method, env, seed, step, value) or tensorboard "
                                         "(event files under charts/episodic_return, one directory a seed: "
                                         "METHOD/ENV/SEED).")] = "csv",
    out: Annotated[str | None, typer.Option(help="Directory to write into (new, empty, or one export wrote). "
                                                 "Default: runs/export.", show_default=False)] = None,
) -> None:
    """Write a run's training episodes (each return at the environment steps up to its end, as Stable-Baselines3's
    Monitor records them) where other tools read them."""
    from rlcompare.experiment.engines import load_run
    from rlcompare.experiment.export import claim_label, tensorboard_directory, write_tensorboard
    from rlcompare.experiment.outside import episodes_table, run_label

    if to not in ("csv", "tensorboard"):
        raise typer.BadParameter(f"{to!r}; allowed: csv, tensorboard", param_hint="'--to'")
    if store.owner_of(run_dir) != store.RUN:
        raise typer.BadParameter(f"{run_dir}: not a run directory rlcompare wrote; allowed: a run directory",
                                 param_hint="'RUN_DIR'")
    out_dir = out_path(out, Path("runs/export"))
    check_out(out_dir, EXPORT, False)
    results = load_run(run_dir)
    label = run_label(results)
    table = episodes_table(results, label)
    with store.output_directory(out_dir, EXPORT):
        claim_label(out_dir, label, run_dir)
        if to == "csv":
            name = f"{label}.csv"
            store.enter_outputs(out_dir / name)
            store.write_bytes_atomic(out_dir / name, table.to_csv(index=False).encode())
            written = [out_dir / name]
        else:
            # this run's files of an earlier export go; other runs exported here stay
            first = table.iloc[0]
            store.remove_outputs(out_dir, f"{tensorboard_directory(first['method'], first['env'], '*')}/"
                                          "events.out.tfevents.*")
            written = write_tensorboard(table, out_dir)
    console.print(f"{plural(len(table), 'episode')} of {table['seed'].nunique()} seeds written to "
                  f"{plural(len(written), 'file')} in {out_dir}", highlight=False)


command("uci")(uci)
