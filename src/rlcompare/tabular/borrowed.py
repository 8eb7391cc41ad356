"""Arrays that compiled code reads and writes without counting references to them.

Numba counts the references to every array it passes around: an atomic increment and decrement of the array's
owner each time a variable takes it, which its pruning pass removes only where the code between them is simple.
A step of a training loop hands the weights and the random streams to helpers with branches and loops (ε-greedy's
random tie-break, the trace list), so a step paid two to six atomic operations: 10-45% of a tabular step's time
(Watkins's Q(λ) ran at half its speed). :func:`borrowed` gives a view with no owner; numba's pruning pass deletes
every count on an owner it sees is none, and the loops run as a kernel written in C would.

A borrowed view is valid while its owner lives. The episode loops borrow the arrays they are given, which their
caller holds for the whole call, and the arrays they allocate, whose owners they pass to :func:`kept` after the
loop: numba frees an array after the last use of its owner, and a view is not a use.
"""

from __future__ import annotations

from typing import Any, Protocol, TypeVar, cast

import numpy as np
from llvmlite import ir
from numba.core import types
from numba.core.typing.templates import Signature
from numba.extending import intrinsic

from rlcompare.compiled import Codegen

Arrays = TypeVar("Arrays", bound=np.ndarray | tuple[np.ndarray, ...])


def _view(context: Any, builder: Any, array_type: types.Array, value: Any) -> Any:
    source = context.make_array(array_type)(context, builder, value=value)
    view = context.make_array(array_type)(context, builder)
    for field in ("nitems", "itemsize", "data", "shape", "strides"):
        setattr(view, field, getattr(source, field))
    view.meminfo = ir.Constant(view.meminfo.type, None)  # a null pointer: no owner
    view.parent = ir.Constant(view.parent.type, None)
    return view._getvalue()


def _members(arrays: types.Type) -> list[types.Type] | None:
    """The types of the members of a tuple (named or not) holding an array; None for any other type."""
    if not isinstance(arrays, types.UniTuple | types.Tuple | types.NamedUniTuple | types.NamedTuple):
        return None
    members = list(arrays)
    return members if any(isinstance(t, types.Array) for t in members) else None


@intrinsic
def _borrowed(typingctx: Any, arrays: types.Type) -> tuple[Signature, Codegen] | None:
    if isinstance(arrays, types.Array):
        return arrays(arrays), lambda context, builder, signature, arguments: _view(
            context, builder, arrays, arguments[0])
    members = _members(arrays)
    if members is None:  # nothing counted: the value itself (a port's parameters)
        if not isinstance(arrays, types.BaseTuple | types.Number | types.Boolean):
            return None
        return arrays(arrays), lambda context, builder, signature, arguments: arguments[0]

    def codegen(context: Any, builder: Any, signature: Signature, arguments: tuple[Any, ...]) -> Any:
        values = [builder.extract_value(arguments[0], k) for k in range(len(members))]
        views = [_view(context, builder, t, v) if isinstance(t, types.Array) else v
                 for t, v in zip(members, values, strict=True)]
        return context.make_tuple(builder, arrays, views)

    return arrays(arrays), codegen


@intrinsic
def _kept(typingctx: Any, owners: types.Type) -> tuple[Signature, Codegen]:
    return types.none(owners), lambda context, builder, signature, arguments: context.get_dummy_value()


class Borrowing(Protocol):
    def __call__(self, arrays: Arrays, /) -> Arrays:
        """The same array (data, shape, strides and type) without its owner, so that no reference to it is
        counted; a tuple (named or not) gives the same tuple with its arrays' views, its other members as they are
        (an environment's tables; a tuple without arrays is itself). Compiled code only."""


class Keeping(Protocol):
    def __call__(self, owners: np.ndarray | tuple[np.ndarray, ...], /) -> None:
        """Nothing, but ``owners`` (arrays, or a tuple of them) are alive until here: called after the last use of
        the views borrowed from them. Compiled code only."""


borrowed = cast(Borrowing, _borrowed)
"""An intrinsic: its typing function takes numba's typing context before the arrays, and called from Python it
raises; to the type checker, the function compiled code calls."""
kept = cast(Keeping, _kept)
