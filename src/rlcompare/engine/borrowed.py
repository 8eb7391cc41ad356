"""Arrays that compiled code reads and writes without counting references to them.

Numba counts the references to every array it passes around: an atomic increment and decrement of the array's
owner each time a variable takes it, which its pruning pass removes only where the code between them is simple.
A step of a training loop hands the weights and the random streams to helpers with branches and loops (ε-greedy's
random tie-break, the trace list), so a step paid two to six atomic operations: 10-45% of a tabular step's time
(Watkins's Q(λ) ran at half its speed). :func:`borrowed` gives a view with no owner; numba's pruning pass deletes
every count on an owner it sees is none, and the loops run as a kernel written in C would.

A borrowed view is valid while its owner lives. The episode loops borrow the arrays they are given, which their
caller holds for the whole call, and nothing else: an array a loop allocates would be freed after its last use
as an owner, under the view.
"""

from __future__ import annotations

from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def borrowed(typingctx, array):
    """The same array (data, shape, strides and type) without its owner, so that no reference to it is counted."""

    def codegen(context, builder, signature, arguments):
        source = context.make_array(signature.args[0])(context, builder, value=arguments[0])
        view = context.make_array(signature.return_type)(context, builder)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(view, field, getattr(source, field))
        view.meminfo = cgutils.get_null_value(view.meminfo.type)
        view.parent = cgutils.get_null_value(view.parent.type)
        return view._getvalue()

    return array(array), codegen
