"""A compiled kernel called again and again with arguments of the same
types, without numba's dispatch at every call.

Calling a numba dispatcher types every argument (a fingerprint of each
array and of each named tuple's fields) and looks the types up among its
compiled versions before it runs the machine code: ~5 µs for a generated
stepper's six arguments (a named tuple of seven arrays among them), as
much as the one step it then takes in a prepared run's one-step call
(:mod:`varint.prepared`). A caller that builds the arguments itself, with
the same dtypes, dimensions, layouts and flags at every call, can look the
compiled version up once, at its first call, and call it directly
(numba's ``Dispatcher.overloads[types].entry_point``, which
``Dispatcher.get_overload`` returns): the same machine code on the same
arguments, so the same bits.

The compiled version unboxes its arguments as the types it was compiled
for and checks nothing more, so an argument of another type (another
dtype, a non-contiguous array) would be misread: :class:`Resolved` is only
for callers whose arguments are made the same way at every call, which
its users state where they make them.
"""

from __future__ import annotations

__all__ = ["Resolved"]


class Resolved:
    """``dispatcher`` called through its dispatch at the first call, then
    through the compiled version that call selected.

    Parameters
    ----------
    dispatcher : numba.core.dispatcher.Dispatcher
        A jitted function (compiled on demand or loaded from numba's cache).

    Notes
    -----
    Where the first call ran a compiled version for other types than its
    arguments' own (numba converts an argument to a compatible type when
    no exact version exists: a C-contiguous array passed to a version for
    any layout), no compiled version has exactly those types, and every
    call keeps going through the dispatcher.
    """

    __slots__ = ("dispatcher", "_entry")

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self._entry = None

    @classmethod
    def of(cls, function):
        """``function`` as a :class:`Resolved` where it is a numba
        dispatcher, else itself (a model's kernel may be plain Python)."""
        return cls(function) if hasattr(function, "overloads") else function

    def __call__(self, *args):
        entry = self._entry
        if entry is not None:
            return entry(*args)
        out = self.dispatcher(*args)
        # The types numba gave these arguments at that call, and the
        # version compiled for exactly them (None: a converting call).
        types = tuple(self.dispatcher.typeof_pyval(a) for a in args)
        compiled = self.dispatcher.overloads.get(types)
        if compiled is not None:
            self._entry = compiled.entry_point
        return out
