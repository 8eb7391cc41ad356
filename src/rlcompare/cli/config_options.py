"""Options derived from :class:`~rlcompare.tabular.config.ExperimentConfig`: one per field, named after it,
with its default and its docstring as help, and the forms the command line gives some of them in."""

from __future__ import annotations

import dataclasses
import functools
import inspect
from collections.abc import Callable
from typing import Annotated, Any, get_type_hints

import typer

from rlcompare.algorithms.registry import METHODS
from rlcompare.cli.console import bad_option, option_flag, with_signature
from rlcompare.tabular.config import DEFAULT_STAGES, ExperimentConfig, field_docs
from rlcompare.validation import ConfigError, check_seed_range

_DEFAULT_SEEDS = len(ExperimentConfig.seeds)


def _method_help(name: str, reads: tuple[str, ...], book: str) -> str:
    options = ", ".join("--" + field.replace("_", "-") for field in reads)
    return f"{name} ({book}; reads {options})" if reads else f"{name} ({book})"


ALGORITHM_HELP = ", ".join(_method_help(name, m.reads, m.book) for name, m in METHODS.items()) + "."
FirstSeed = Annotated[int, typer.Option(help="First seed. Seed s starts episodes as env.reset(seed=s) does.")]


def _config(**values: Any) -> ExperimentConfig:
    """Build the configuration, turning a bad value into a usage error that names the option."""
    try:
        return ExperimentConfig(**values)
    except ConfigError as error:
        raise bad_option(error) from None


def _seeds(count: int, first: int) -> tuple[int, ...]:
    try:
        check_seed_range(count, first)
    except ConfigError as error:
        raise bad_option(error) from None
    return tuple(range(first, first + count))


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
PLAIN_WORDS = {
    " (DiscretizeObservation(env, bins))": "",
    "None: the environment's default (": "Default: the environment's (",
    "; None: the environment's defaults (its observation box, with chosen bounds where the box is unbounded: "
    "docs/environments.md)": ". Default: the environment's observation bounds, with chosen ones where those are "
                             "infinite (docs/environments.md)",
    "None for the behaviour's ε (on-policy), 0 for greedy": "by default the behaviour's ε (on-policy), 0 for greedy",
    "SARSA's box, Algorithm 2": "as SARSA does, Algorithm 2",
    "Q-Learning's box, Algorithm 1": "as Q-Learning does, Algorithm 1",
    "None: the method's own box (drawn_next).": "Default: each method's own order.",
    "Only the one-step learners have it (rlcompare.algorithms.registry.Method.one_step; docs/why.md)":
        "Only the one-step learners take it (docs/why.md)",
    "with Discrete actions and Discrete or Box observations": "whose actions are a finite set and whose observations "
                                                              "are a state's number or an array of numbers",
    "(old Gym done)": "(as the old Gym's done did)",
}
"""Words of the configuration's docstrings said plainly in the command line's help, which is read by people who
type options, not Python: no None, no class or attribute names, no Gymnasium space types (a test checks that each
phrase is still in a docstring)."""


def plain(text: str) -> str:
    """A field's docstring in the words of :data:`PLAIN_WORDS`."""
    for phrase, words in PLAIN_WORDS.items():
        text = text.replace(phrase, words)
    return text


def _field_options() -> list[inspect.Parameter]:
    """An option per field of :class:`ExperimentConfig`, in the class's order, named after the field, with its
    default and its docstring as help (:data:`_FORMS` where the command line's form differs); ``--first-seed``
    follows ``--seeds``."""
    types, docs = get_type_hints(ExperimentConfig), field_docs()
    options = []
    for field in dataclasses.fields(ExperimentConfig):
        kind, default, how = _FORMS.get(field.name, (types[field.name], field.default, ""))
        text = _HELP.get(field.name) or " ".join(part for part in (plain(docs.get(field.name, "")), how) if part)
        options.append(inspect.Parameter(field.name, inspect.Parameter.KEYWORD_ONLY, default=default,
                                         annotation=Annotated[kind, typer.Option(option_flag(field.name), help=text)]))
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

    return with_signature(wrapped, inspect.Signature([*_field_options(), *rest]))
