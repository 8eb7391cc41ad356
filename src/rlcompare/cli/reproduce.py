"""``rlcompare reproduce STUDY``: one subcommand per record of :mod:`rlcompare.studies.registry`, each taking exactly
the fields of its study's options (their docstrings as help) besides ``--out`` and ``--force``; ``reproduce``
alone runs the paper, whose options it takes."""

from __future__ import annotations

import dataclasses
import inspect
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, get_type_hints

import typer

from rlcompare import pace
from rlcompare.cli.app_help import SUMMARIES, PlainCommand, PlainGroup
from rlcompare.cli.console import (
    ConsoleUI,
    announce_compiling,
    bad_option,
    check_out,
    console,
    fail,
    one_line_errors,
    option_flag,
    out_path,
    print_report,
    with_signature,
)
from rlcompare.experiment import rundir, store
from rlcompare.studies.interface import Options
from rlcompare.studies.registry import DEFAULT_STUDY, MEASURED_DEFAULTS, STUDIES, Study
from rlcompare.tabular.config import field_docs
from rlcompare.validation import ConfigError

if TYPE_CHECKING:  # the design's statistics import scipy: not for every command's --help
    from rlcompare.studies.plans import StudyPlan

FORCE_HELP = ("Write into OUT even though it holds files rlcompare did not write (they are left as they are: "
              "rlcompare never replaces or deletes a file it did not write), and replace the runs rlcompare wrote "
              "there with other settings.")
PLAN_HELP = ("Print the design that would run and exit, without training or writing anything: every training, "
             "its seeds and the steps or episodes it runs, each family of tests with its smallest attainable p, and "
             "whether the design can decide.")
UNDECIDABLE_HELP = ("Run a design that cannot decide its headline question (its first line says why); without this "
                    "it is refused, naming the seeds that could.")
COMMON = ("out", "force", "plan", "allow_undecidable")
"""Options of every study, beside its own."""


def _common_parameters(study: str) -> list[inspect.Parameter]:
    out = Annotated[str | None, typer.Option(
        help=f"Study directory (new, empty, or this study's, written by rlcompare); one run directory per "
             f"configuration. Default: runs/{study}.", show_default=False)]
    flags = {"force": ("--force", FORCE_HELP), "plan": ("--plan", PLAN_HELP),
             "allow_undecidable": ("--allow-undecidable", UNDECIDABLE_HELP)}
    return [inspect.Parameter("out", inspect.Parameter.KEYWORD_ONLY, default=None, annotation=out), *(
        inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=False,
                          annotation=Annotated[bool, typer.Option(flag, help=text)])
        for name, (flag, text) in flags.items())]


def option_parameters(options: type[Options]) -> list[inspect.Parameter]:
    """An option per field of ``options``, named after it (and its other spellings), with its default and its
    docstring as help; a tuple of strings is given by repeating the option, a boolean as ``--x/--no-x``."""
    # a class is hashable; mypy takes type[Options] for unhashable (python/mypy#11470)
    docs, types = field_docs(options), get_type_hints(options)  # type: ignore[arg-type]
    parameters = []
    for field in dataclasses.fields(options):
        kind, default = types[field.name], field.default
        if kind == tuple[str, ...]:
            kind, default = list[str] | None, None
        flags = (option_flag(field.name), *field.metadata.get("spellings", ()))
        if kind is bool:
            flags = (f"{flags[0]}/--no-{flags[0][2:]}",)
        parameters.append(inspect.Parameter(
            field.name, inspect.Parameter.KEYWORD_ONLY, default=default,
            annotation=Annotated[kind, typer.Option(*flags, help=docs.get(field.name, ""),
                                                    show_default=default is not None)]))
    return parameters


def study_options(study: Study, values: dict[str, Any]) -> Options:
    """The study's options from the command line's values; a refused value is a usage error naming its option."""
    given = {name: tuple(value) if isinstance(value, list) else value for name, value in values.items()}
    try:
        return study.options(**{name: value for name, value in given.items() if value is not None})
    except ConfigError as error:
        raise bad_option(error) from None


def load_runner(study: Study, *, planner: bool = False) -> Any:
    """The study's runner (or, ``planner``, what gives its design: :meth:`Study.load_planner`); a missing optional
    extra ends the command with one line saying how to install it."""
    try:
        return study.load_planner() if planner else study.load_runner()
    except ImportError as error:
        if not study.extra:
            raise
        fail(str(error))


def study_plan(study: Study, planner: Any, options: Options) -> StudyPlan:
    """The study's design from its options (:mod:`rlcompare.studies.plans`); a refused value names its option, a
    missing optional extra is one line, as :func:`load_runner` says it."""
    try:
        return planner.study_plan(options)  # type: ignore[no-any-return]
    except ConfigError as error:
        raise bad_option(error) from None
    except ImportError as error:  # what a plan reads of an extra (the Atari ROMs), loaded where it reads it
        if not study.extra:
            raise
        fail(str(error))


def reproduce_study(study: Study, values: dict[str, Any]) -> None:
    """Check the options and the design (``--plan``: print it and stop), then the output directory; train what
    the study's directory lacks, then its report."""
    from rlcompare.studies import plans

    began = time.perf_counter()
    out, force = out_path(values.pop("out"), Path("runs") / study.name), values.pop("force")
    show_plan, allow_undecidable = values.pop("plan"), values.pop("allow_undecidable")
    options = study_options(study, values)
    check_out(out, store.Owner("study", study.name), force)
    planner = load_runner(study, planner=True)  # --plan loads no report's modules
    videos = getattr(options, "videos", True)
    plan, paces, rest = study_plan(study, planner, options), pace.stored(), pace.rest_key(study.name, videos)
    plan = plans.with_known_spread(plan, out, study.name)
    finished = [t.name for t in plan.trainings if (out / t.name / rundir.META_FILE).is_file()]
    if show_plan:
        for line in plan.lines(paces, rest, finished):
            console.print(line, highlight=False, soft_wrap=True)
        return
    runner = load_runner(study)
    if plan.undecidable and not allow_undecidable:
        fail(f"{plan.first_line()} Run it anyway with --allow-undecidable.")
    console.print(plan.first_line(), highlight=False)
    console.print(plan.time_line(paces, rest, finished), highlight=False)
    announce_compiling()
    # one hold of the directory's lock for the training and the report, so no other process writes in between
    with store.output_directory(out, store.Owner("study", study.name), force=force):
        try:
            runs = runner.run(out, options, ConsoleUI(), study=study.name, force=force)
        except ConfigError as error:
            raise bad_option(error) from None
        report = runner.report(out, ConsoleUI(), runs=runs, videos=videos)
        # what this run spent beside what its trainings' paces, just kept, account for: the next plan adds it
        trained = plan.training_seconds(pace.stored(), finished, as_run=True) or 0.0
        pace.record_rest(rest, time.perf_counter() - began - trained)
        print_report(report)


def study_command(study: Study) -> Callable[..., None]:
    """``rlcompare reproduce NAME`` for one study."""

    @one_line_errors
    def command(**values: Any) -> None:
        reproduce_study(study, values)

    command.__doc__ = (f"{study.summary[0].upper()}{study.summary[1:]}. Its default, measured: "
                       f"{MEASURED_DEFAULTS[study.name]} (docs/defaults.md).")
    return with_signature(command, inspect.Signature([*option_parameters(study.options),
                                                      *_common_parameters(study.name)]))


def list_studies() -> None:
    for name, study in STUDIES.items():
        console.print(f"{name:<12} {study.summary}", highlight=False)


def default_study(ctx: typer.Context, **values: Any) -> None:
    """Without a study's name, the paper's; options before a study's name are refused, since they are the
    paper's."""
    if values.pop("list_studies"):
        list_studies()
        raise typer.Exit(0)
    if ctx.invoked_subcommand is not None:
        given = [name for name in values if getattr(ctx.get_parameter_source(name), "name", "") == "COMMANDLINE"]
        if given:
            fail(f"{option_flag(given[0])} before the study's name is the paper's option; put it after the name: "
                 f"rlcompare reproduce {ctx.invoked_subcommand} {option_flag(given[0])} ...")
        return
    one_line_errors(reproduce_study)(STUDIES[DEFAULT_STUDY], values)


class StudyGroup(PlainGroup):
    """The ``reproduce`` group: a name that is not a study's is a usage error listing the studies."""

    def resolve_command(self, ctx: Any, args: list[str]) -> Any:
        if args and not args[0].startswith("-") and args[0] not in self.commands:
            raise typer.BadParameter(f"got {args[0]!r}; allowed: {', '.join(self.commands)}", ctx,
                                     param_hint="'STUDY'")
        return super().resolve_command(ctx, args)


def reproduce_app() -> typer.Typer:
    """The ``reproduce`` group: the paper's options on the group itself, then a subcommand per study."""
    app = typer.Typer(help="Reproduce a study: train what its directory lacks (configurations already complete "
                           "in OUT are loaded, not trained again), then build its report. Without a study's name, "
                           "the paper, whose options are below.", short_help=SUMMARIES["reproduce"],
                      rich_markup_mode="rich", cls=StudyGroup)
    list_option = Annotated[bool, typer.Option("--list", help="List the studies and exit.")]

    def callback(ctx: typer.Context, **values: Any) -> None:
        default_study(ctx, **values)

    app.callback(invoke_without_command=True)(with_signature(callback, inspect.Signature([
        inspect.Parameter("ctx", inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation=typer.Context),
        *option_parameters(STUDIES[DEFAULT_STUDY].options), *_common_parameters(DEFAULT_STUDY),
        inspect.Parameter("list_studies", inspect.Parameter.KEYWORD_ONLY, default=False, annotation=list_option)])))
    for name, study in STUDIES.items():
        command = study_command(study)
        app.command(name, help=command.__doc__, short_help=f"{study.summary[0].upper()}{study.summary[1:]}.",
                    cls=PlainCommand)(command)
    return app
