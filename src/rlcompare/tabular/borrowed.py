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

from numba.core import cgutils, types
from numba.extending import intrinsic


def _view(context, builder, array_type, value):
    source = context.make_array(array_type)(context, builder, value=value)
    view = context.make_array(array_type)(context, builder)
    for field in ("nitems", "itemsize", "data", "shape", "strides"):
        setattr(view, field, getattr(source, field))
    view.meminfo = cgutils.get_null_value(view.meminfo.type)
    view.parent = cgutils.get_null_value(view.parent.type)
    return view._getvalue()


@intrinsic
def borrowed(typingctx, arrays):
    """The same array (data, shape, strides and type) without its owner, so that no reference to it is counted; a
    tuple of arrays gives the tuple of their views."""
    if isinstance(arrays, types.Array):
        return arrays(arrays), lambda context, builder, signature, arguments: _view(
            context, builder, arrays, arguments[0])
    if not (isinstance(arrays, types.BaseTuple) and all(isinstance(t, types.Array) for t in arrays)):
        return None

    def codegen(context, builder, signature, arguments):
        views = [_view(context, builder, t, builder.extract_value(arguments[0], k)) for k, t in enumerate(arrays)]
        return context.make_tuple(builder, arrays, views)

    return arrays(arrays), codegen


@intrinsic
def kept(typingctx, owners):
    """Nothing, but ``owners`` (arrays, or a tuple of them) are alive until here: called after the last use of the
    views borrowed from them."""
    return types.none(owners), lambda context, builder, signature, arguments: context.get_dummy_value()
