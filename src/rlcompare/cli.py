"""The ``rlcompare`` command line: parse, call one library function, print."""

from __future__ import annotations

import dataclasses
import functools
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, get_type_hints

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from rlcompare.algorithms.registry import METHODS
from rlcompare.experiment import store
from rlcompare.experiment.config import DEFAULT_STAGES, ConfigError, ExperimentConfig, field_docs
from rlcompare.experiment.store import StoreError
from rlcompare.studies import TITLES

if TYPE_CHECKING:
    from rlcompare.experiment.benchmark import BenchTable

app = typer.Typer(
    help="Run, measure and explain comparisons of reinforcement-learning algorithms.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
)
console = Console(width=None if Console().is_terminal else 120)
_DEFAULT_SEEDS = len(ExperimentConfig().seeds)

def _method_help(name: str, reads: tuple[str, ...], book: str) -> str:
    options = ", ".join("--" + field.replace("_", "-") for field in reads)
    return f"{name} ({book}; reads {options})" if reads else f"{name} ({book})"


ALGORITHM_HELP = ", ".join(_method_help(name, m.reads, m.book) for name, m in METHODS.items()) + "."
FirstSeed = Annotated[int, typer.Option(help="First seed. Seed s starts episodes as env.reset(seed=s) does.")]
Force = Annotated[bool, typer.Option(
    "--force", help="Write into OUT even though it holds files rlcompare did not write; they are left as they are "
                    "(rlcompare never replaces or deletes a file it did not write).")]


def one_line_errors(command: Callable) -> Callable:
    """A command whose errors of the store or of the operating system (a full disk, a read-only directory)
    end it with one clear line and exit code 2; what was finished before them stays on disk."""

    @functools.wraps(command)
    def wrapped(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except OSError as error:  # StoreError included
            message = str(error) if isinstance(error, StoreError) or not error.strerror else (
                f"{error.filename}: {error.strerror}" if error.filename else error.strerror)
            _fail(message)

    return wrapped


def _seeds(count: int, first: int) -> tuple[int, ...]:
    if count < 1:
        raise typer.BadParameter(f"got {count}; allowed: an integer >= 1", param_hint="'--seeds'")
    if first < 0:
        raise typer.BadParameter(f"got {first}; allowed: an integer >= 0", param_hint="'--first-seed'")
    return tuple(range(first, first + count))


def _option(field_name: str) -> str:
    """The option that gives a configuration field: ``--hash-size`` for ``hash_size``, ``--stage`` for ``stages``."""
    return "--stage" if field_name == "stages" else "--" + field_name.replace("_", "-")


def _option_name(field_name: str) -> str:
    return f"'{_option(field_name)}'"


def _config(**values) -> ExperimentConfig:
    """Build the configuration, turning a bad value into a usage error that names the option."""
    try:
        return ExperimentConfig(**values)
    except ConfigError as error:
        raise typer.BadParameter(f"got {store.quote(error.value)}; allowed: {error.allowed}",
                                 param_hint=_option_name(error.field_name)) from None


def _out_path(text: str | None, default: Path) -> Path:
    """The ``--out`` directory: the default where none is given; never the empty path."""
    if text is None:
        return default
    try:
        return store.check_path(text)
    except StoreError as error:
        raise typer.BadParameter(str(error).removeprefix("--out: "), param_hint="'--out'") from None


def _check_out(out: Path, owner: store.Owner, force: bool) -> None:
    """Refuse an output directory before any training, so a bad path costs nothing computed."""
    problem = store.refusal(out, owner, force=force)
    if problem:
        raise typer.BadParameter(problem, param_hint="'--out'")


def _stages(specs: list[str]) -> tuple[tuple[str, float], ...]:
    """``name=share`` pairs from ``--stage``; none given: the defaults."""
    if not specs:
        return DEFAULT_STAGES
    stages = []
    for spec in specs:
        name, _, share = spec.partition("=")
        try:
            stages.append((name.strip(), float(share)))
        except ValueError:
            raise typer.BadParameter(f"got {spec!r}; allowed: NAME=SHARE with SHARE in (0, 1], e.g. early=0.1",
                                     param_hint="'--stage'") from None
    return tuple(stages)


def _bins(spec: str | None) -> int | tuple[int, ...] | None:
    """``20`` or ``1,1,6,12`` from ``--bins``; none given: the environment's default."""
    if spec is None:
        return None
    try:
        values = tuple(int(part) for part in spec.split(","))
    except ValueError:
        raise typer.BadParameter(f"got {spec!r}; allowed: an integer >= 1, or one per observation dimension "
                                 "separated by commas, e.g. 1,1,6,12", param_hint="'--bins'") from None
    return values[0] if len(values) == 1 else values


def _bounds(spec: str | None) -> tuple[tuple[float, float], ...] | None:
    """``LOW:HIGH,LOW:HIGH,...`` from ``--bounds``, one pair per observation dimension."""
    if spec is None:
        return None
    try:
        return tuple((float(low), float(high)) for low, high in (pair.split(":") for pair in spec.split(",")))
    except ValueError:
        raise typer.BadParameter(f"got {spec!r}; allowed: LOW:HIGH per observation dimension, separated by "
                                 "commas, e.g. -2.4:2.4,-3:3,-0.21:0.21,-3.5:3.5", param_hint="'--bounds'") from None


_FORMS: dict[str, tuple[Any, Any, str]] = {
    "seeds": (int, _DEFAULT_SEEDS, "Given as a count: the seeds are first-seed, first-seed + 1, ..."),
    "bins": (str | None, None, "Given as one number, or one per dimension separated by commas, e.g. 1,1,6,12."),
    "bounds": (str | None, None, "Given as LOW:HIGH per dimension, separated by commas, e.g. "
                                 "-2.4:2.4,-3:3,-0.21:0.21,-3.5:3.5."),
    "stages": (list[str] | None, None, "Given as NAME=SHARE; repeat the option. Default: "
                                       + " ".join(f"{name}={share}" for name, share in DEFAULT_STAGES) + "."),
}
"""Fields the command line gives in another form than the configuration holds them: the option's type, its
default, and what its help adds to the field's docstring (:func:`_config_from` reads them)."""
_HELP = {"algorithm": ALGORITHM_HELP}
"""Help in place of a field's docstring: every method of the registry and the options it reads."""


def _field_options() -> list[inspect.Parameter]:
    """An option per field of :class:`ExperimentConfig`, in the class's order, named after the field, with its
    default and its docstring as help (:data:`_FORMS` where the command line's form differs); ``--first-seed``
    follows ``--seeds``."""
    types, docs = get_type_hints(ExperimentConfig), field_docs()
    options = []
    for field in dataclasses.fields(ExperimentConfig):
        kind, default, how = _FORMS.get(field.name, (types[field.name], field.default, ""))
        text = _HELP.get(field.name) or " ".join(part for part in (docs.get(field.name, ""), how) if part)
        options.append(inspect.Parameter(field.name, inspect.Parameter.KEYWORD_ONLY, default=default,
                                         annotation=Annotated[kind, typer.Option(_option(field.name), help=text)]))
        if field.name == "seeds":
            options.append(inspect.Parameter("first_seed", inspect.Parameter.KEYWORD_ONLY, default=0,
                                             annotation=FirstSeed))
    return options


def _config_from(options: dict[str, Any]) -> ExperimentConfig:
    """The configuration the options of :func:`config_options` give, taken out of ``options``."""
    values = {field.name: options.pop(field.name) for field in dataclasses.fields(ExperimentConfig)}
    first_seed = options.pop("first_seed")
    return _config(**values | {"bounds": _bounds(values["bounds"]), "bins": _bins(values["bins"]),
                               "seeds": _seeds(values["seeds"], first_seed), "stages": _stages(values["stages"] or [])})


def config_options(command: Callable[..., None]) -> Callable[..., None]:
    """``command(config, ...)`` as a command taking an option per field of :class:`ExperimentConfig` in place of
    ``config`` (:func:`_field_options`); a bad value is refused, naming its option, before ``command`` runs."""
    parameters = inspect.signature(command, eval_str=True).parameters.values()
    rest = [parameter.replace(kind=inspect.Parameter.KEYWORD_ONLY) for parameter in parameters
            if parameter.name != "config"]

    @functools.wraps(command)
    def wrapped(**options: Any) -> None:
        return command(_config_from(options), **options)

    wrapped.__signature__ = inspect.Signature([*_field_options(), *rest])  # what typer reads
    return wrapped


def progress_label(config: ExperimentConfig) -> str:
    """A configuration's name, and how its environment is stepped when that is at Python speed."""
    if config.environment.is_ported:
        return config.name
    return f"{config.name} ({config.env} through Gymnasium's API: Python speed)"


def _progress(eta: bool = False) -> Progress:
    """A progress bar on a terminal; nothing but the per-configuration lines in a log."""
    columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn()]
    if eta:
        columns += [TextColumn("ETA"), TimeRemainingColumn()]
    return Progress(*columns, console=console, disable=not console.is_terminal)


@app.command()
@one_line_errors
@config_options
def run(
    config: ExperimentConfig,
    out: Annotated[str | None, typer.Option(help="Run directory to write (new, empty, or a run directory "
                                                 "rlcompare wrote). Default: runs/run.", show_default=False)] = None,
    force: Force = False,
) -> None:
    """Train one configuration over many seeds and write its run directory."""
    from rlcompare.experiment.runner import run as run_experiment

    out_dir = _out_path(out, Path("runs/run"))
    _check_out(out_dir, store.RUN, force)
    if not config.environment.is_ported:
        console.print(progress_label(config))
    _announce_compiling()
    with store.output_directory(out_dir, store.RUN, force=force), _progress() as progress:
        task = progress.add_task(progress_label(config), total=config.episodes)
        results = run_experiment(config, out=out_dir, progress=lambda n: progress.advance(task, n))
    _print_done(progress, config.name, results, reused=False)
    _print_summary([results], paper=False)
    console.print(f"Run directory: {out_dir}")


@app.command()
@one_line_errors
def reproduce(
    study: Annotated[str, typer.Argument(
        help=f"Which study: {', '.join(TITLES)} (see --list).")]
    = "paper",
    seeds: Annotated[int | None, typer.Option(
        "--seeds", "--runs",
        help="Number of seeds (runs); seeds are first-seed, first-seed + 1, ... Default: 30 for paper, why, "
             "cartpole and acrobot; the book's runs for the others (100 for book-10.2 and book-12.10, 50,000 for "
             "book-6.3, whose asymptotic phase runs the first 1 in 5,000 of them, at least 2; 50 for "
             "cliff); 10 for deep; 20 for sensitivity, whose seeds come from its sweep (SeedSequence(0).spawn(N)).",
        show_default=False)] = None,
    first_seed: FirstSeed = 0,
    episodes: Annotated[int | None, typer.Option(
        help="Training episodes per seed (paper, why, cartpole, acrobot, sensitivity, and deep's tabular pair; the "
             "paper gives none; book-6.3: its asymptotic phase). Default: 5000; 1500 for sensitivity; 100,000 for "
             "book-6.3.", show_default=False)] = None,
    algorithms: Annotated[str, typer.Option(
        help="Comma-separated algorithms run on the paper's grid besides the random baseline; 'all' for every "
             "one. Each adds rows to Tables I and II.")] = "q_learning,sarsa",
    out: Annotated[str | None, typer.Option(
        help="Study directory (new, empty, or this study's, written by rlcompare); one run directory per "
             "configuration. Default: runs/STUDY.", show_default=False)] = None,
    videos: Annotated[bool, typer.Option(help="Render videos of the greedy agents into the report.")] = True,
    grid: Annotated[list[str] | None, typer.Option(
        help="Sensitivity: the values of one axis of the grid, KEY=V1,V2,... with KEY alpha, gamma, epsilon_end or "
             "truncation_as_terminal; repeat the option. Default: alpha=0.01,0.05,0.1,0.2,0.5 gamma=0.9,0.99,1 "
             "epsilon_end=0,0.01,0.05 truncation_as_terminal=false,true.", show_default=False)] = None,
    workers: Annotated[int | None, typer.Option(
        help="Sensitivity on this machine: trials at once. Default: every core. Deep: configurations trained at "
             "once. Default: one per core, at most 4.", show_default=False)] = None,
    address: Annotated[str | None, typer.Option(
        help="Sensitivity: run the trials on the Ray cluster at this address ('auto': the one 'ray start' began "
             "here; or HOST:PORT) instead of this machine's cores.", show_default=False)] = None,
    steps: Annotated[int | None, typer.Option(
        help="Deep: environment steps of every training, in place of each preset's (for a quick look).",
        show_default=False)] = None,
    methods: Annotated[str | None, typer.Option(
        help="Deep: comma-separated deep methods. Default: every one.", show_default=False)] = None,
    envs: Annotated[str | None, typer.Option(
        help="Deep: comma-separated environments (CartPole-v1, Acrobot-v1, MountainCar-v0). Default: all three.",
        show_default=False)] = None,
    list_studies: Annotated[bool, typer.Option("--list", help="List the studies and exit.")] = False,
    force: Force = False,
) -> None:
    """Reproduce a study. The paper: random baseline, Q-Learning and SARSA, ε constant 0.5 and decaying from 1;
    cartpole and acrobot ask the paper's question there with the same settings.

    Configurations already complete in OUT are loaded, not trained again.
    """
    from rlcompare.studies.book import STUDIES
    from rlcompare.studies.paper import ENV_STUDIES

    if list_studies:
        for name, title in TITLES.items():
            console.print(f"{name:<12} {title}")
        return
    if study not in TITLES:
        raise typer.BadParameter(f"got {study!r}; allowed: {', '.join(TITLES)}", param_hint="'STUDY'")
    out_dir = _out_path(out, Path("runs") / study)
    _check_out(out_dir, store.Owner("study", study), force)
    if study == "deep":
        _reproduce_deep(seeds, first_seed, steps, episodes, methods, envs, workers, out_dir, force)
        return
    _announce_compiling()
    if study == "sensitivity":
        _reproduce_sensitivity(seeds, first_seed, episodes, grid or [], out_dir, workers, address, force)
    elif study == "why":
        _reproduce_why(_seeds(_DEFAULT_SEEDS if seeds is None else seeds, first_seed),
                       5000 if episodes is None else episodes, out_dir, force)
    elif study == "paper" or study in ENV_STUDIES:
        count = _DEFAULT_SEEDS if seeds is None else seeds
        _reproduce_paper(study, _seeds(count, first_seed), 5000 if episodes is None else episodes,
                         _algorithms(algorithms), out_dir, videos, force)
    elif study == "book-6.3":
        from rlcompare.studies.book import fig_6_3_study

        if episodes is not None and episodes < 1:
            raise typer.BadParameter(f"got {episodes}; allowed: an integer >= 1", param_hint="'--episodes'")
        count = STUDIES[study].runs if seeds is None else seeds
        _reproduce_book(fig_6_3_study(episodes), _seeds(count, first_seed), out_dir, force)
    else:
        count = STUDIES[study].runs if seeds is None else seeds
        _reproduce_book(STUDIES[study], _seeds(count, first_seed), out_dir, force)


def _algorithms(spec: str) -> tuple[str, ...]:
    from rlcompare.experiment.config import ALGORITHMS

    learners = tuple(a for a in ALGORITHMS if a != "random")
    chosen = learners if spec.strip() == "all" else tuple(a.strip() for a in spec.split(",") if a.strip())
    unknown = [a for a in chosen if a not in learners]
    if unknown or not chosen:
        raise typer.BadParameter(f"got {spec!r}; allowed: 'all' or a comma-separated list of "
                                 f"{', '.join(learners)}", param_hint="'--algorithms'")
    return chosen


def _reproduce_paper(study: str, seeds: tuple[int, ...], episodes: int, algorithms: tuple[str, ...], out: Path,
                     videos: bool, force: bool) -> None:
    from rlcompare.studies.paper import ENV_STUDIES, paper_configs
    from rlcompare.studies.paper import reproduce as reproduce_study

    env = ENV_STUDIES.get(study, "MountainCar-v0")
    if episodes < 1:
        raise typer.BadParameter(f"got {episodes}; allowed: an integer >= 1", param_hint="'--episodes'")
    configs = paper_configs(seeds, episodes, algorithms, env=env)
    finished = []
    with _progress() as progress:
        task = progress.add_task(env, total=sum(c.episodes for c in configs))
        for results, reused in reproduce_study(out, configs, progress=lambda n: progress.advance(task, n),
                                               study=study, force=force):
            finished.append(results)
            _print_done(progress, results.config.name, results, reused)
    _print_summary(finished, paper=env == "MountainCar-v0")
    _report(out, videos)


def _reproduce_why(seeds: tuple[int, ...], episodes: int, out: Path, force: bool) -> None:
    from rlcompare.studies.why import run_why, why_configs

    if episodes < 1:
        raise typer.BadParameter(f"got {episodes}; allowed: an integer >= 1", param_hint="'--episodes'")
    runs = {}
    with _progress() as progress:
        task = progress.add_task("why", total=episodes * len(why_configs(seeds, episodes)))
        for name, results, reused in run_why(out, seeds, episodes, lambda n: progress.advance(task, n), force=force):
            runs[name] = results
            _print_done(progress, name, results, reused)
    _why_report(out, runs)


def _why_report(out: Path, runs=None) -> None:
    from rlcompare.studies.why import build_why_report

    path, findings = build_why_report(out, runs)
    for sentence in findings:
        console.print(Text(sentence), highlight=False)
    console.print(f"Report: {path}")


def _deep_study():
    """The deep study's module, or one line saying how to install the ``deep`` extra (exit 2)."""
    try:
        from rlcompare.studies import deep
    except ImportError as error:  # the deep engine's DeepUnavailable says how to install the extra
        _fail(str(error))
    return deep


def _listed(spec: str | None, allowed: tuple[str, ...], option: str) -> tuple[str, ...]:
    """A comma-separated choice among ``allowed``; None: all of them."""
    if spec is None:
        return allowed
    chosen = tuple(name.strip() for name in spec.split(",") if name.strip())
    if not chosen or any(name not in allowed for name in chosen):
        raise typer.BadParameter(f"got {spec!r}; allowed: a comma-separated list of {', '.join(allowed)}",
                                 param_hint=f"'{option}'")
    return chosen


def _reproduce_deep(seeds: int | None, first_seed: int, steps: int | None, episodes: int | None,
                    methods: str | None, envs: str | None, workers: int | None, out: Path, force: bool) -> None:
    deep = _deep_study()
    for value, option in ((steps, "--steps"), (episodes, "--episodes"), (workers, "--workers")):
        if value is not None and value < 1:
            raise typer.BadParameter(f"got {value}; allowed: an integer >= 1", param_hint=f"'{option}'")
    plan = deep.Plan(seeds=_seeds(deep.DEFAULT_SEEDS if seeds is None else seeds, first_seed),
                     methods=_listed(methods, tuple(deep.DEEP_METHODS), "--methods"),
                     envs=_listed(envs, deep.ENVS, "--envs"), steps=steps,
                     tabular_episodes=deep.TABULAR_EPISODES if episodes is None else episodes,
                     workers=deep.DEFAULT_WORKERS if workers is None else workers)
    try:
        configs = plan.deep_configs()
    except ConfigError as error:
        hint = "'--steps'" if error.field_name == "total_steps" else error.field_name
        raise typer.BadParameter(f"got {store.quote(error.value)}; allowed: {error.allowed}", param_hint=hint) from None
    console.print(Text(f"Training {len(configs)} deep configurations x {len(plan.seeds)} seeds; each compiles its "
                       "program first (10-40 s, once per machine).", style="dim"))
    with _progress() as progress:
        tasks = {"tabular": progress.add_task("tabular", total=sum(
                     c.progress_total for c in plan.tabular_configs().values())),
                 "deep": progress.add_task("deep (seeds)", total=sum(c.progress_total for c in configs.values()))}
        for name, results, reused in deep.reproduce(out, plan, force=force,
                                                    progress=lambda kind, n: progress.advance(tasks[kind], n)):
            _print_deep_done(progress, name, results, reused)
    _deep_report(out)


def _print_deep_done(progress: Progress, name: str, results, reused: bool) -> None:
    timings = results.meta.get("timings", {})
    how = "loaded" if reused else (f"{timings.get('wall_seconds', 0):.1f} s, compiled in "
                                   f"{timings.get('compile_seconds', 0):.1f} s")
    progress.console.print(f"{name}: {how}")


def _deep_report(out: Path) -> None:
    deep = _deep_study()
    with console.status("Building the report"):
        path, lines, problems = deep.build_report(out)
    for line in lines:
        console.print(Text(f"  {line}"), highlight=False)
    for problem in problems:
        console.print(Text("Missing: ", style="yellow") + Text(problem), highlight=False)
    console.print(f"Report: {path}")


def _reproduce_book(study, seeds: tuple[int, ...], out: Path, force: bool) -> None:
    from rlcompare.studies.book import run_study, write_study_report

    configs = study.configs(seeds)
    runs = {}
    with _progress() as progress:
        task = progress.add_task(study.name, total=sum(c.episodes for c in configs.values()))
        for name, results, reused in run_study(study, out, seeds, progress=lambda n: progress.advance(task, n),
                                               force=force):
            runs[name] = results
            _print_done(progress, name, results, reused)
    console.print(f"Report: {write_study_report(study, out, runs)}")


def _reproduce_sensitivity(seeds: int | None, first_seed: int, episodes: int | None, grid: list[str], out: Path,
                           workers: int | None, address: str | None, force: bool) -> None:
    import time

    from rlcompare.experiment.sweep import SweepError
    from rlcompare.studies import sensitivity

    count = sensitivity.DEFAULT_SEEDS if seeds is None else len(_seeds(seeds, 0))
    if first_seed != 0:
        raise typer.BadParameter(f"got {first_seed}; allowed: 0 (the sensitivity study's seeds come from its sweep, "
                                 "SeedSequence(0).spawn(N))", param_hint="'--first-seed'")
    episodes = sensitivity.DEFAULT_EPISODES if episodes is None else episodes
    if episodes < 1:
        raise typer.BadParameter(f"got {episodes}; allowed: an integer >= 1", param_hint="'--episodes'")
    if workers is not None and workers < 1:
        raise typer.BadParameter(f"got {workers}; allowed: an integer >= 1", param_hint="'--workers'")
    try:
        plan, text = sensitivity.plan(sensitivity.parse_grid(grid), count, episodes)
    except SweepError as error:
        raise typer.BadParameter("; ".join(error.problems), param_hint="'--grid'") from None
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint="'--grid'") from None
    started = time.perf_counter()
    finished, ran = _run_trials(
        plan, "local" if address is None else "ray", workers, address,
        f"of {episodes} episodes on {'Ray at ' + address if address else 'this machine'}; study {out}",
        lambda executor, progress: sensitivity.run_sensitivity(out, plan, text, executor, progress, force=force))
    trained = time.perf_counter() - started
    console.print(f"{ran} trials run, {finished} already finished: {trained:.1f} s")
    _sensitivity_report(out)
    console.print(f"Wall time: {time.perf_counter() - started:.1f} s")


def _run_trials(plan, backend: str, workers: int | None, address: str | None, where: str,
                run_trials: Callable) -> tuple[int, int]:
    """Connect the backend before anything is written, then ``run_trials(executor, progress)`` with a progress
    bar over the plan's trials; a backend that cannot run them ends the command with one line."""
    from rlcompare.experiment.backends import BackendError, make_backend

    try:
        executor = make_backend(backend, workers=workers, address=address)
        executor.connect()
        trials = len(plan.trials())
        console.print(f"{plan.name}: {len(plan.configs)} configurations x {len(plan.seeds)} seeds = {trials} trials "
                      f"{where}")
        with _progress(eta=True) as progress:
            task = progress.add_task("trials", total=trials)
            return run_trials(executor, lambda trial: progress.advance(task))
    except BackendError as error:
        _fail(str(error))


def _sensitivity_report(out: Path) -> None:
    from rlcompare.studies.sensitivity import build_report

    with console.status("Building the sensitivity report"):
        path, problems, summary = build_report(out)
    for line in summary:
        console.print(Text(line), highlight=False)
    for problem in problems:
        console.print(Text("Missing: ", style="yellow") + Text(problem), highlight=False)
    console.print(f"Report: {path}")


def _announce_compiling() -> None:
    """Say so before a run that will compile the kernels, which takes a while on a fresh machine."""
    from rlcompare._numba_cache import holds_nothing_yet

    if holds_nothing_yet():
        console.print("Compiling: the first run of each method on each environment and features compiles its "
                      "training loop (10-20 s on two cores); later runs load it.")


def _print_done(progress: Progress, name: str, results, reused: bool) -> None:
    timings = results.meta["timings"]
    compiled = f" (and {timings['compile_seconds']:.0f} s compiling or loading its loop)" \
        if timings.get("compile_seconds", 0) >= 1 else ""
    how = "loaded (already complete)" if reused else f"{timings['wall_seconds']:.1f} s{compiled}"
    progress.console.print(f"{name:<24} {len(results.seeds)} seeds x {results.config.episodes} episodes: {how}")


@app.command()
@one_line_errors
def sweep(
    sweep_file: Annotated[Path, typer.Argument(help="A sweep file (TOML); see examples/sweep.toml, or "
                                                    "examples/sweep-deep.toml for deep configurations.")],
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
) -> None:
    """Run every configuration of a sweep over its seeds; finished trials in OUT are kept, the rest run."""
    from rlcompare.experiment.backends import BACKENDS
    from rlcompare.experiment.sweep import SweepError, load_sweep
    from rlcompare.experiment.sweep_store import run_sweep

    try:
        plan = load_sweep(sweep_file)
    except SweepError as error:
        _print_error(f"{error.source}: every problem of the sweep file", tuple(error.problems))
        raise typer.Exit(2) from None
    if backend not in BACKENDS:
        raise typer.BadParameter(f"got {backend!r}; allowed: {', '.join(BACKENDS)}", param_hint="'--backend'")
    if workers is not None and workers < 1:
        raise typer.BadParameter(f"got {workers}; allowed: an integer >= 1", param_hint="'--workers'")
    unknown = [key for key in group_by or [] if key not in plan.swept]
    if unknown:
        raise typer.BadParameter(f"got {unknown[0]!r}; allowed: a swept key ({', '.join(plan.swept) or 'none'})",
                                 param_hint="'--group-by'")
    out_dir = _out_path(out, Path("runs") / "sweeps" / plan.name)
    _check_out(out_dir, store.SWEEP, force)
    finished, ran = _run_trials(
        plan, backend, workers, address, f"on the {backend} backend; store {out_dir}",
        lambda executor, progress: run_sweep(plan, sweep_file.read_text(), out_dir, executor, progress=progress,
                                             force=force))
    console.print(f"{ran} trials run, {finished} already finished")
    if report_:
        _sweep_report(out_dir, tuple(group_by or ()))


@app.command()
@one_line_errors
def report(
    study_dir: Annotated[Path, typer.Argument(help="A study directory written by reproduce, or a sweep's store.")],
    videos: Annotated[bool, typer.Option(help="Render videos of the greedy agents.")] = True,
    group_by: Annotated[list[str] | None, typer.Option(
        help="A sweep: also write its table grouped by this swept key; repeat the option.")] = None,
) -> None:
    """Rebuild the tables, verdicts, figures, videos and report.html of a study or a sweep, without training."""
    from rlcompare.studies.book import STUDIES, write_study_report

    allowed = "a study directory written by 'rlcompare reproduce' or a sweep's store"
    if not study_dir.is_dir():
        raise typer.BadParameter(f"{study_dir} is not a directory; allowed: {allowed}", param_hint="'STUDY_DIR'")
    owner = store.owner_of(study_dir)
    if owner == store.SWEEP:
        _sweep_report(study_dir, tuple(group_by or ()))
    elif owner == store.Owner("study", "sensitivity"):
        _sensitivity_report(study_dir)
    elif owner == store.Owner("study", "why"):
        _why_report(study_dir)
    elif owner == store.Owner("study", "deep"):
        _deep_report(study_dir)
    elif owner is not None and owner.kind == "study" and owner.name in STUDIES:
        console.print(f"Report: {write_study_report(STUDIES[owner.name], study_dir)}")
    elif owner is not None and owner.kind == "study":
        _report(study_dir, videos)
    else:
        what = f"holds {owner}" if owner is not None else "was not written by rlcompare (it holds no .rlcompare.json)"
        raise typer.BadParameter(f"{study_dir} {what}; allowed: {allowed}", param_hint="'STUDY_DIR'")


def _sweep_report(root: Path, group_by: tuple[str, ...]) -> None:
    from rlcompare.studies.sweep_report import build_sweep_report

    with console.status("Building the sweep's report"):
        path, problems = build_sweep_report(root, group_by)
    for problem in problems:
        console.print(Text("Missing: ", style="yellow") + Text(problem), highlight=False)
    console.print(f"Report: {path}")


def _report(study_dir: Path, videos: bool) -> None:
    from rlcompare.studies.paper_report import build_report

    with console.status("Building the report"):
        outcome = build_report(study_dir, videos=videos)
    console.print(Text("Findings", style="bold"))
    for sentence in outcome.findings:
        console.print(Text(f"  {sentence}"), highlight=False)
    for problem in outcome.problems:
        console.print(Text("Missing: ", style="yellow") + Text(problem), highlight=False)
    timings = ", ".join(f"{part} {seconds:.1f} s" for part, seconds in outcome.seconds.items())
    console.print(f"Report: {outcome.path}  ({timings})")
    if outcome.problems:
        raise typer.Exit(1)


@app.command()
def bench(
    environments: Annotated[bool, typer.Option(help="Also measure every ported environment against its own "
                                                    "Gymnasium loop and through the adapter.")] = True,
    sweeps: Annotated[bool, typer.Option(help="Only measure sweeps: trials per second of short trials on the "
                                              "local backend (1 and 2 workers) and on Ray.")] = False,
    address: Annotated[str | None, typer.Option(help="With --sweeps: the Ray cluster (default: a new local Ray "
                                                     "instance with 2 CPUs).")] = None,
    deep: Annotated[bool, typer.Option(help="Only measure the deep engine, beside Stable-Baselines3 where the "
                                            "'bench' extra is installed.")] = False,
    to_score: Annotated[bool, typer.Option(help="With --deep: also the wall time to a greedy return of 475 on "
                                                "CartPole, ours beside Stable-Baselines3 (several minutes).")] = False,
) -> None:
    """Steps per second of the kernels on 1 and all threads against a plain Gymnasium loop."""
    from rlcompare.experiment import benchmark
    from rlcompare.experiment.backends import BackendError

    if deep:
        try:
            from rlcompare.deep.bench import deep_table, score_table
        except ImportError as error:  # the deep engine's DeepUnavailable says how to install the extra
            _fail(str(error))
        with console.status("Measuring the deep engine and Stable-Baselines3 (a few minutes)"):
            _print_table(deep_table())
            if to_score:
                _print_table(score_table())
        return
    if sweeps:
        try:
            _print_table(benchmark.sweep_benchmark(address))
        except BackendError as error:
            _fail(str(error))
        return
    _print_table(benchmark.kernel_table(benchmark.run_benchmark()))
    if environments:
        _print_table(benchmark.port_table(benchmark.run_port_benchmark()))


def _print_table(table: BenchTable) -> None:
    """A benchmark's table (:class:`~rlcompare.experiment.benchmark.BenchTable`): its label column left, its
    numbers right; then its notes."""
    shown = Table(title=table.title)
    for index, column in enumerate(table.columns):
        shown.add_column(column, justify="right" if index else "left")
    for row in table.rows:
        shown.add_row(*row)
    console.print(shown)
    for note in table.notes:
        console.print(Text(note, style="yellow"))


def _print_summary(results, *, paper: bool) -> None:
    from rlcompare.analysis.tables import per_seed_metrics, table_ii
    from rlcompare.studies.paper import PAPER_TABLE_II

    frame = table_ii({r.config.name: per_seed_metrics(r) for r in results}, PAPER_TABLE_II if paper else {})
    columns = ["configuration", "behaviour mean", "greedy mean", "greedy success"]
    frame = frame[[*columns, "paper (Table II)"] if paper else columns]
    table = Table(title="Mean cumulative reward over seeds [95% bootstrap interval]",
                  caption="behaviour: ε-greedy return averaged over all training episodes; greedy: return of "
                          "the final greedy policy; success: its episodes that reached the goal")
    for column in frame.columns:
        table.add_column(column, justify="left" if column == "configuration" else "right", no_wrap=True)
    for row in frame.itertuples(index=False):
        table.add_row(*(str(value) for value in row))
    console.print(table)


def _print_error(message: str, details: tuple[str, ...] = ()) -> None:
    """``Error: message`` on standard error, unwrapped and never read as markup, and a line per detail."""
    errors = Console(stderr=True, soft_wrap=True, highlight=False)
    errors.print(Text("Error: ", style="red") + Text(store.cut(message, 2000)))
    for detail in details:
        errors.print(Text(f"  {store.cut(detail, 2000)}"))


def _fail(message: str) -> None:
    """One line, exit code 2."""
    _print_error(message)
    raise typer.Exit(2)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
