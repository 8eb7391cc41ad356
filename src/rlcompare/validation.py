"""What a valid setting is, for every configuration rlcompare reads: the tabular and deep configurations, a
method's hyperparameters, a sweep file and a study's options.

One error, :class:`ConfigError`, names the field, quotes the value and says what is allowed. One rule each for
an integer, a finite number, a flag and a choice, written once (:class:`Integer`, :class:`Number`, :data:`FLAG`,
:class:`Choice`), and every config declares each field's rule beside it (:func:`setting`) or checks its fields
against a table of them (:func:`check_fields`). NumPy's scalars count as the Python values they hold
(``np.int64(3)`` is an integer, ``np.float32(0.5)`` a number, and ``np.bool_(True)`` a flag), known by the
abstract numbers they register as (:mod:`numbers`), so that checking a setting imports no NumPy; a bool is never
a number.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

from rlcompare.formatting import cut, quote

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value outside what is allowed; names the field and the allowed values.

    ``value`` is the value itself; the message quotes at most the start of it (:func:`~rlcompare.formatting.quote`),
    and of an unknown field's name."""

    def __init__(self, field_name: str, value: Any, allowed: str) -> None:
        self.field_name, self.value, self.allowed = field_name, value, allowed
        super().__init__(f"{cut(str(field_name), 80)}: got {quote(value)}; allowed: {allowed}")


class UnknownKey(ConfigError):
    """A key that names no field (a misspelt hyperparameter): says so, and lists the fields there are."""

    def __init__(self, key: str, allowed: str) -> None:
        self.field_name, self.value, self.allowed = key, key, allowed
        ValueError.__init__(self, f"{cut(key, 80)}: unknown key; allowed: {allowed}")


def require(ok: bool, name: str, value: Any, allowed: str) -> None:
    """A :class:`ConfigError` naming ``name`` unless ``ok``."""
    if not ok:
        raise ConfigError(name, value, allowed)


def is_flag(value: Any) -> bool:
    """A bool, Python's or NumPy's."""
    return isinstance(value, bool) or _is_numpy(value, "bool")


def is_integer(value: Any) -> bool:
    """An int or a NumPy integer, not a bool."""
    return isinstance(value, numbers.Integral) and not is_flag(value)


def is_number(value: Any) -> bool:
    """A finite int or float, Python's or NumPy's, not a bool (an integer too large for a float is finite)."""
    if is_integer(value):
        return True
    return isinstance(value, numbers.Real) and not is_flag(value) and math.isfinite(value)


PLAIN_TYPES = (int, float, str)
"""Python's own scalars: what :func:`plain` returns as they are (``bool`` is not ``int`` to ``type``)."""


def plain(value: Any) -> Any:
    """A NumPy scalar as the Python value it holds (what ``config.json`` and a config's hash read), a tuple's too;
    anything else as it is."""
    if isinstance(value, tuple):
        if all(type(item) in PLAIN_TYPES for item in value):  # a million seeds in a blink
            return value
        return tuple(map(plain, value))
    return value.item() if _is_numpy(value) else value


def _is_numpy(value: Any, kind: str = "") -> bool:
    """Whether ``value`` is a NumPy scalar (of ``kind``, as NumPy names its type: ``bool``), without importing
    NumPy."""
    cls = type(value)
    return cls.__module__ == "numpy" and hasattr(value, "item") and cls.__name__.startswith(kind)


def plain_fields(config: Any) -> None:
    """Every field of the frozen dataclass ``config`` as :func:`plain` makes it (called first in its
    ``__post_init__``, so that NumPy's scalars are accepted and stored as Python's)."""
    for item in dataclasses.fields(config):
        object.__setattr__(config, item.name, plain(getattr(config, item.name)))


class Rule(Protocol):
    """What a field may hold: a test, and the words that say what passes it."""

    @property
    def allowed(self) -> str: ...

    def holds(self, value: Any) -> bool: ...


@dataclass(frozen=True)
class Integer:
    """An integer in ``[minimum, maximum]`` (either end open where None)."""

    minimum: int | None = None
    maximum: int | None = None

    @property
    def allowed(self) -> str:
        if self.maximum is None:
            return "an integer" if self.minimum is None else f"an integer >= {self.minimum}"
        if self.minimum is None:
            return f"an integer <= {self.maximum}"
        return f"an integer in [{self.minimum}, {self.maximum}]"

    def holds(self, value: Any) -> bool:
        return (is_integer(value) and (self.minimum is None or value >= self.minimum)
                and (self.maximum is None or value <= self.maximum))


@dataclass(frozen=True)
class Number:
    """A finite number between ``low`` and ``high``, each end included unless said open."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    @property
    def allowed(self) -> str:
        if math.isinf(self.high):
            if math.isinf(self.low):
                return "a finite number"
            return f"a finite number {'>' if self.low_open else '>='} {self.low:g}"
        if math.isinf(self.low):
            return f"a finite number {'<' if self.high_open else '<='} {self.high:g}"
        return (f"a number in {'(' if self.low_open else '['}{self.low:g}, {self.high:g}"
                f"{')' if self.high_open else ']'}")

    def holds(self, value: Any) -> bool:
        if not is_number(value):
            return False
        above = self.low < value if self.low_open else self.low <= value
        below = value < self.high if self.high_open else value <= self.high
        return bool(above and below)


@dataclass(frozen=True)
class Choice:
    """One of ``values``."""

    values: tuple[Any, ...]

    @property
    def allowed(self) -> str:
        return ", ".join(map(str, self.values))

    def holds(self, value: Any) -> bool:
        try:
            return value in self.values
        except TypeError:  # an unhashable or incomparable value is none of them
            return False


@dataclass(frozen=True)
class Predicate:
    """A rule that is a test and the words that say what passes it (:data:`FLAG`, :data:`WIDTHS`)."""

    allowed: str
    holds: Callable[[Any], bool]


UNIT = Number(0.0, 1.0)
"""[0, 1]: a probability, a discount, a trace decay."""
STEP_SIZE = Number(0.0, 1.0, low_open=True)
"""(0, 1]: a step size or a share."""
POSITIVE = Number(0.0, low_open=True)
"""A finite number > 0."""
NON_NEGATIVE = Number(0.0)
"""A finite number >= 0."""
COUNT = Integer(1)
"""An integer >= 1."""
FLAG = Predicate("true or false", is_flag)


def _are_widths(value: Any) -> bool:
    return isinstance(value, tuple) and len(value) >= 1 and all(COUNT.holds(width) for width in value)


WIDTHS = Predicate("a tuple of layer widths, each an integer >= 1", _are_widths)
"""A network's hidden layers: at least one, each an integer >= 1."""


SEEDS_ALLOWED = "distinct integers in [0, 2**63), at least one"
MAX_SEEDS = 1_000_000
"""The most seeds a command takes: twenty times the largest design here (Figure 6.3's 50,000 runs). Refused when
the options are read, before anything is built for each seed (a count past it once overflowed, or ran for minutes
checking seeds one at a time)."""
SEED_COUNT = Integer(1, MAX_SEEDS)


def check_seed_range(count: Any, first: Any, count_name: str = "seeds", first_name: str = "first_seed") -> None:
    """The seeds ``first`` to ``first + count - 1``: ``count`` within :data:`SEED_COUNT` and every seed below
    2**63, else a :class:`ConfigError` naming the option at fault."""
    check(count_name, count, SEED_COUNT)
    check(first_name, first, Integer(0, 2**63 - count))


def is_seeds(value: Any) -> bool:
    """A list or tuple of distinct integers in [0, 2**63), at least one: the seeds of a configuration."""
    return (isinstance(value, list | tuple) and len(value) >= 1 and all(Integer(0, 2**63 - 1).holds(s) for s in value)
            and len(set(map(int, value))) == len(value))


def check(name: str, value: Any, rule: Rule) -> None:
    """A :class:`ConfigError` naming ``name`` unless ``value`` holds to ``rule``."""
    require(rule.holds(value), name, value, rule.allowed)


def check_fields(config: Any, rules: Mapping[str, Rule]) -> None:
    """Each field of ``config`` named in ``rules`` checked against its rule, in the table's order."""
    for name, rule in rules.items():
        check(name, getattr(config, name), rule)


def setting(default: T, rule: Rule) -> T:
    """A dataclass field holding ``default``, with the ``rule`` it must hold to beside it (:func:`check_settings`)."""
    return dataclasses.field(default=default, metadata={"rule": rule})


def check_settings(config: Any) -> None:
    """The fields of the frozen dataclass ``config`` made plain (:func:`plain_fields`), then each declared with
    :func:`setting` checked against its rule, in the fields' order (called first in its ``__post_init__``)."""
    plain_fields(config)
    check_fields(config, field_rules(config))


def field_rules(config: Any) -> dict[str, Rule]:
    """The rule of each field of the dataclass ``config`` declared with :func:`setting`, in the fields' order."""
    return _rules_of(config.__class__)


@functools.cache
def _rules_of(cls: type) -> dict[str, Rule]:
    return {item.name: item.metadata["rule"] for item in dataclasses.fields(cls) if "rule" in item.metadata}
