"""A method's options checked against the names it takes (rule 1 of
:class:`varint.protocol.Propagator`: a misspelt tolerance must not pass
silently).

Its own module, below the method registry of :mod:`varint.methods` and every
propagator, so that a propagator imports it without importing the registry
that imports the propagator.
"""

from __future__ import annotations


def method_options(method, given, valid):
    """``given`` options checked against the ``valid`` names of ``method``.

    Raises
    ------
    TypeError
        Naming the unknown option and the valid ones (rule 1 of the
        protocol: a misspelt tolerance must not pass silently).
    """
    unknown = sorted(set(given) - set(valid))
    if unknown:
        listed = ", ".join(valid) if valid else "none"
        raise TypeError(f"unknown option {unknown[0]!r} for method {method!r}; valid options: "
                        f"{listed} (see varint.METHODS for the other methods)")
    return dict(given)
