"""One compiled interpreter of arithmetic expressions over rows of states,
shared by every model (issue 28: a model's energy compiled from its own
expression cost one more compiled kernel per expression, ~1–2 CPU s each
on a cold cache, for calls that save a few tens of µs each).

A program is a list of instructions ``(op, destination, a, b)`` over
registers, each register a block of :data:`BLOCK` rows' values, evaluated
block by block: each instruction is one IEEE operation applied to each row
of the block (a sum, difference, product, quotient, negation, square root,
libm's ``pow``), so a row's value is the same operations in the same order
as a kernel compiled from the expression's text, or NumPy's ufuncs on its
columns, would apply to it (:mod:`varint.models.potential_rows` says when
those are NumPy's). numba compiles without fast-math: LLVM neither fuses a
product and a sum nor reorders them, whether the loop over a block's rows
is vectorised or not (each row's lane is the row's own operation).

The programs are made by :mod:`varint.models.potential_rows`; this module
only runs them, compiled once (numba's disk cache) whatever the model. Its
compilation (~0.7 CPU s on a loaded machine, against ~0.15 s for one
expression's own kernel; ``studies/results/energy24/``) is paid only where
calls repeat: the models evaluate their energies with NumPy until this
kernel is :func:`ready` or a caller says its calls repeat (a prepared or
remembered run's short call, :class:`varint.rerun.ShortCall`).
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from .. import codecache

__all__ = ["BLOCK", "LOAD", "CONSTANT", "POWER_ROW", "ADD", "SUBTRACT", "MULTIPLY", "DIVIDE",
           "NEGATE", "SQRT", "POW", "STORE", "run_program", "ready"]

#: Rows per block: a register holds one block's values; a program's
#: registers stay in the first cache levels for a few hundred of them.
BLOCK = 32

# Instructions (op, d, a, b): register d from a and b (registers, or
# indices as stated).
#: d = column a of the states.
LOAD = 0
#: d = constants[a] (set once, before the first block).
CONSTANT = 1
#: d = row a of the powers (:class:`varint.models.potential_rows.NumPyPowers`).
POWER_ROW = 2
#: d = a + b.
ADD = 3
#: d = a − b.
SUBTRACT = 4
#: d = a × b.
MULTIPLY = 5
#: d = a / b.
DIVIDE = 6
#: d = −a.
NEGATE = 7
#: d = √a.
SQRT = 8
#: d = a ** constants[b] (libm's ``pow``: the exponent a run-time double).
POW = 9
#: row d of the output = a.
STORE = 10


@njit(cache=True, error_model="numpy", nogil=True)
def run_program(states, powers, code, constants, n_registers, out):
    """Run the program ``code`` (K, 4) int64 with ``constants`` over the
    rows of ``states`` (R, ≥ columns read) and of ``powers`` (P, R; (0, 0)
    for a program without :data:`POWER_ROW`), in ``n_registers`` registers,
    writing its outputs into ``out`` (outputs, R). Arrays C-contiguous,
    float64 but ``code``."""
    rows = states.shape[0]
    registers = np.empty((n_registers, BLOCK))
    for k in range(code.shape[0]):
        if code[k, 0] == CONSTANT:
            registers[code[k, 1], :] = constants[code[k, 2]]
    for start in range(0, rows, BLOCK):
        m = min(BLOCK, rows - start)
        for k in range(code.shape[0]):
            op, d, a, b = code[k, 0], code[k, 1], code[k, 2], code[k, 3]
            if op == LOAD:
                for i in range(m):
                    registers[d, i] = states[start + i, a]
            elif op == POWER_ROW:
                for i in range(m):
                    registers[d, i] = powers[a, start + i]
            elif op == ADD:
                for i in range(m):
                    registers[d, i] = registers[a, i] + registers[b, i]
            elif op == SUBTRACT:
                for i in range(m):
                    registers[d, i] = registers[a, i] - registers[b, i]
            elif op == MULTIPLY:
                for i in range(m):
                    registers[d, i] = registers[a, i] * registers[b, i]
            elif op == DIVIDE:
                for i in range(m):
                    registers[d, i] = registers[a, i] / registers[b, i]
            elif op == NEGATE:
                for i in range(m):
                    registers[d, i] = -registers[a, i]
            elif op == SQRT:
                for i in range(m):
                    registers[d, i] = np.sqrt(registers[a, i])
            elif op == POW:
                e = constants[b]
                for i in range(m):
                    registers[d, i] = registers[a, i] ** e
            elif op == STORE:
                for i in range(m):
                    out[d, start + i] = registers[a, i]


@functools.cache
def _on_disk() -> bool:
    # (Read once per process: a later process's compile is not waited for.)
    return codecache.in_disk_cache(run_program)


def ready() -> bool:
    """Whether :func:`run_program` runs without being compiled: compiled or
    loaded in this process, or in numba's disk cache (loading it then
    costs milliseconds)."""
    return bool(run_program.signatures) or _on_disk()
