"""NumPy's floating-point errors ignored around a few ufunc calls, as
``with np.errstate(all="ignore"):`` does, for a tenth of its cost (a
prepared run's short call, :mod:`varint.prepared`; issue 28: the fixed
cost of a call).

NumPy keeps its error handling in a context variable holding one
immutable object (divide, over, under, invalid, the callback, the buffer
size). ``np.errstate`` builds a new object from the current one at each
entry and sets it; :func:`ignoring` builds it once per current object (the
last pair kept) and sets the same one, then :func:`restore` resets the
variable, as ``errstate.__exit__`` does. So the handling inside is exactly
``errstate``'s (the callback and buffer size of the moment kept), in any
thread or asynchronous context (each has its own variable). Where NumPy
has no such variable (another major version), both fall back to
``np.errstate`` itself.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["ignoring", "restore"]


def _numpy_handling() -> tuple[Any, Any]:
    """NumPy's context variable of the handling and its maker of handling
    objects (None, None where this NumPy has none)."""
    try:
        from numpy._core import umath
    except ImportError:     # pragma: no cover - NumPy 1
        return None, None
    return getattr(umath, "_extobj_contextvar", None), getattr(umath, "_make_extobj", None)


_extobj_contextvar, _make_extobj = _numpy_handling()
if _make_extobj is None:    # pragma: no cover - see the module
    _extobj_contextvar = None

#: (the handling object current at the last call, the one ignoring every
#: error made from it): a tuple, replaced whole, so a thread reads one pair.
_LAST: tuple[Any, Any] = (None, None)


def ignoring() -> Any:
    """Ignore every floating-point error from now until :func:`restore`
    of the token returned (in this thread or context)."""
    global _LAST
    if _extobj_contextvar is None:      # pragma: no cover - see the module
        state = np.errstate(all="ignore")
        state.__enter__()
        return state
    current = _extobj_contextvar.get()
    last, quiet = _LAST
    if last is not current:
        quiet = _make_extobj(all="ignore")
        _LAST = (current, quiet)
    return _extobj_contextvar.set(quiet)


def restore(token: Any) -> None:
    """The handling as before the :func:`ignoring` that returned ``token``."""
    if _extobj_contextvar is None:      # pragma: no cover - see the module
        token.__exit__(None, None, None)
    else:
        _extobj_contextvar.reset(token)
