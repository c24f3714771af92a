"""The Kepler drift and the interaction kick of n planets as straight-line
code, generated for each n and coordinate system: every position,
distance and Hessian factor in a local variable (registers), where the
generic kernels of :mod:`varint.kernels.nbody` go through a scratch array
and loops whose length is known only at run time; and the planets'
Kepler equations side by side, so that the processor overlaps their
solutions (each is a chain of dependent operations). The formulas, and the
order of every operation, are those of the generic kernels
(:func:`varint.kernels.nbody._interaction`,
:func:`~varint.kernels.nbody._interaction_hvp`,
:func:`varint.kernels.kepler.kepler_step`): the tests hold this code to
them bit for bit. For two planets and one deviation vector the kick is
about 4× and the drift 1.4× faster than the generic loops (the kernel
timings of studies/bench_planetary.py).

The generated functions are ``kick(x, V, k, h, par)`` (p −= h∇B(q),
δp −= h D²B(q) δq for the first k rows of V; returns
:data:`~varint.kernels.nbody.ENCOUNTER` after a kick that leaves two
planets within the close-encounter distance) and ``drift(x, V, k, h,
par)`` (returning the Kepler status; nothing moves when a planet's step
fails). :func:`flows` compiles them with the jump into the ``apply`` of a
model's parts.
"""

from __future__ import annotations

import math
from functools import cache

import numba

from . import kepler as kep
from .kepler import KEPLER_DEGENERATE, KEPLER_OK
from .nbody import ENCOUNTER, INTERACTION, KEPLER, _jump

__all__ = ["kick_kernel", "drift_kernel", "flows"]

_AX = "xyz"


def _source(n, jacobi):
    """Python source of the kick of n planets (module docstring)."""
    n3 = 3 * n
    # par: n, G, coords, m0 … mn, M0 … Mn, …; planet i (0-based) has mass
    # par[4 + i] and interior mass M_i = par[4 + n + i].
    lines = ["def kick(x, V, k, h, par):", "    G = par[1]", "    mstar = par[3]"]
    add = lines.append
    for i in range(n):
        add(f"    m{i} = par[{4 + i}]")
        add(f"    M{i} = par[{4 + n + i}]")
    for i in range(n):
        for a, ax in enumerate(_AX):
            add(f"    q{i}{ax} = x[{3 * i + a}]")
    # Heliocentric positions: u_i = q_i + S/M_i, S = Σ_{j<i} m_j u_j.
    for i in range(n):
        for ax in _AX:
            if jacobi and i > 0:
                s = " + ".join(f"m{j} * u{j}{ax}" for j in range(i))
                add(f"    u{i}{ax} = q{i}{ax} + ({s}) * (1.0 / M{i})")
            else:
                add(f"    u{i}{ax} = q{i}{ax}")
    terms = []   # (name, K expression, d vector names (a, b or None), space)
    if jacobi:
        terms += [(f"s{i}", f"G * mstar * m{i}", (f"u{i}", None)) for i in range(1, n)]
    terms += [(f"p{i}_{j}", f"G * m{i} * m{j}", (f"u{i}", f"u{j}"))
              for i in range(n) for j in range(i + 1, n)]
    direct = [(f"d{i}", f"-G * m{i} * M{i}", (f"q{i}", None)) for i in range(1, n)] if jacobi \
        else []
    for i in range(n):
        for ax in _AX:
            add(f"    gu{i}{ax} = 0.0")
    for name, K, (a, b) in terms + direct:
        for ax in _AX:
            add(f"    {name}{ax} = {a}{ax}" + (f" - {b}{ax}" if b else ""))
        add(f"    r2 = {name}x * {name}x + {name}y * {name}y + {name}z * {name}z")
        add(f"    c_{name} = ({K}) / (r2 * math.sqrt(r2))")
        add(f"    t_{name} = 3.0 / r2")
    for name, _, (a, b) in terms:
        i = int(a[1:])
        for ax in _AX:
            add(f"    gu{i}{ax} += c_{name} * {name}{ax}")
            if b:
                add(f"    gu{int(b[1:])}{ax} -= c_{name} * {name}{ax}")
    _transpose(add, n, jacobi, "gu", "g")
    for name, _, (a, _b) in direct:
        i = int(a[1:])
        for ax in _AX:
            add(f"    g{i}{ax} += c_{name} * {name}{ax}")
    for i in range(n):
        for a, ax in enumerate(_AX):
            add(f"    x[{n3 + 3 * i + a}] -= h * g{i}{ax}")
    # Close encounters (varint.kernels.nbody._encounter), after the kick.
    add(f"    f2 = par[{5 + 4 * n}]")
    add("    met = 0")
    if n > 1:
        add("    if f2 != 0.0:")
        t = 6 + 4 * n
        for i in range(n):
            for j in range(i + 1, n):
                ui = " + ".join(f"u{i}{ax} ** 2" for ax in _AX)
                uj = " + ".join(f"u{j}{ax} ** 2" for ax in _AX)
                d2 = " + ".join(f"(u{i}{ax} - u{j}{ax}) ** 2" for ax in _AX)
                add(f"        if met == 0 and ({d2}) < f2 * par[{t}] * (({ui}) + ({uj})):")
                add("            met = ENCOUNTER")
                t += 1
    add("    for c in range(k):")
    ind = "        "
    for i in range(n):
        for a, ax in enumerate(_AX):
            add(f"{ind}e{i}{ax} = V[c, {3 * i + a}]")
    for i in range(n):
        for ax in _AX:
            if jacobi and i > 0:
                s = " + ".join(f"m{j} * w{j}{ax}" for j in range(i))
                add(f"{ind}w{i}{ax} = e{i}{ax} + ({s}) * (1.0 / M{i})")
            else:
                add(f"{ind}w{i}{ax} = e{i}{ax}")
            add(f"{ind}hu{i}{ax} = 0.0")
    for name, _, (a, b) in terms:
        ia = int(a[1:])
        for ax in _AX:
            add(f"{ind}v{ax} = w{ia}{ax}" + (f" - w{int(b[1:])}{ax}" if b else ""))
        add(f"{ind}s = t_{name} * ({name}x * vx + {name}y * vy + {name}z * vz)")
        for ax in _AX:
            add(f"{ind}b{ax} = c_{name} * (v{ax} - s * {name}{ax})")
        for ax in _AX:
            add(f"{ind}hu{ia}{ax} += b{ax}")
            if b:
                add(f"{ind}hu{int(b[1:])}{ax} -= b{ax}")
    # The direct terms act on the Jacobi positions, after the transpose.
    body = []
    _transpose(body.append, n, jacobi, "hu", "hv", ind)
    lines.extend(body)
    for name, _, (a, _b) in direct:
        i = int(a[1:])
        for ax in _AX:
            add(f"{ind}v{ax} = e{i}{ax}")
        add(f"{ind}s = t_{name} * ({name}x * vx + {name}y * vy + {name}z * vz)")
        for ax in _AX:
            add(f"{ind}hv{i}{ax} += c_{name} * (v{ax} - s * {name}{ax})")
    for i in range(n):
        for a, ax in enumerate(_AX):
            add(f"{ind}V[c, {n3 + 3 * i + a}] -= h * hv{i}{ax}")
    add("    return met")
    return "\n".join(lines) + "\n"


def _transpose(add, n, jacobi, src, dst, ind="    "):
    """dst = Lᵀ src (the backward recursion of
    :func:`varint.kernels.nbody.jacobi_transpose`), or a copy."""
    for ax in _AX:
        if jacobi:
            add(f"{ind}T{ax} = 0.0")
        for j in range(n - 1, -1, -1):
            if jacobi:
                add(f"{ind}{dst}{j}{ax} = {src}{j}{ax} + m{j} * T{ax}")
                if j > 0:
                    add(f"{ind}T{ax} += {dst}{j}{ax} * (1.0 / M{j})")
            else:
                add(f"{ind}{dst}{j}{ax} = {src}{j}{ax}")


@cache
def kick_kernel(n, jacobi):
    """The compiled kick of n planets (Jacobi or democratic heliocentric
    coordinates), built once per process and (n, coordinates)."""
    scope = {"math": math, "ENCOUNTER": ENCOUNTER}
    exec(compile(_source(n, jacobi), f"<varint planetary kick n={n}>", "exec"), scope)
    return numba.njit(error_model="numpy", inline="always")(scope["kick"])


def _drift_source(n):
    """Python source of the Kepler drift of n planets (module docstring)."""
    n3 = 3 * n
    omu, okm = 5 + 2 * n, 5 + 3 * n   # par offsets of μ_i and m′_i
    lines = ["def drift(x, V, k, h, par):", "    if h == 0.0:", "        return KEPLER_OK"]
    add = lines.append
    sc = "rx{i}, ry{i}, rz{i}, vx{i}, vy{i}, vz{i}, r0{i}, beta{i}, eta{i}, zeta{i}"
    G = "X{i}, G0{i}, G1{i}, G2{i}, G3{i}, G4{i}, G5{i}"
    for i in range(n):
        add(f"    mu{i} = par[{omu + i}]")
        add(f"    km{i} = par[{okm + i}]")
        add(f"    im{i} = 1.0 / km{i}")
        add(f"    ok{i}, {sc.format(i=i)}, h2{i} = prepare(x, {3 * i}, {n3 + 3 * i}, mu{i}, "
            f"im{i})")
    add("    if not (" + " and ".join(f"ok{i}" for i in range(n)) + "):")
    add("        return KEPLER_DEGENERATE")
    for i in range(n):
        add(f"    st{i}, {G.format(i=i)} = solve_fast(r0{i}, eta{i}, zeta{i}, beta{i}, h)")
    for i in range(n):
        add(f"    if st{i} != KEPLER_OK:")
        add(f"        st{i}, {G.format(i=i)} = solve_universal(r0{i}, eta{i}, zeta{i}, beta{i}, "
            f"mu{i}, h, h2{i})")
        add(f"        if st{i} != KEPLER_OK:")
        add(f"            return st{i}")
    for i in range(n):
        add(f"    r{i} = r0{i} + eta{i} * G1{i} + zeta{i} * G2{i}")
        add(f"    if not (r{i} > 0.0 and r{i} < math.inf):")
        add("        return KEPLER_DEGENERATE")
    for i in range(n):
        add(f"    finish(x, V, k, {3 * i}, {n3 + 3 * i}, mu{i}, km{i}, im{i}, h, {sc.format(i=i)}, "
            f"{G.format(i=i)})")
    add("    return KEPLER_OK")
    return "\n".join(lines) + "\n"


@cache
def drift_kernel(n):
    """The compiled Kepler drift of n planets (module docstring), built once
    per process and n."""
    scope = {"math": math, "prepare": kep.prepare, "finish": kep.finish,
             "solve_fast": kep.solve_fast, "solve_universal": kep.solve_universal,
             "KEPLER_OK": KEPLER_OK, "KEPLER_DEGENERATE": KEPLER_DEGENERATE}
    exec(compile(_drift_source(n), f"<varint planetary drift n={n}>", "exec"), scope)
    # Called, not inlined: compiled once per process and signature (k),
    # shared by every part stepper and lane block, where inlined it was
    # compiled into each (about half of a stepper's 60 CPU s). The call
    # costs 0-10 % of a two-planet WH step (studies/planetary_parts_call.py,
    # measured 1.001-1.10 on a loaded machine).
    return numba.njit(error_model="numpy")(scope["drift"])


@cache
def flows(n, jacobi):
    """``apply(part, h, x, V, k, par, work)`` of n planets: the flows of
    :func:`varint.kernels.nbody.apply_flow`, with the generated drift and
    kick."""
    kick = kick_kernel(n, jacobi)
    drift = drift_kernel(n)

    # Inlined into the part stepper: a call with array arguments costs their
    # reference counts, ~50 ns a step here (the drift is called: see
    # drift_kernel).
    @numba.njit(error_model="numpy", inline="always")
    def apply(part, h, x, V, k, par, work):
        if part == KEPLER:
            status = drift(x, V, k, h, par)
            if status != KEPLER_OK and math.isfinite(x[0]):
                # The part stepper does not read a flow's status: a NaN in the
                # state stops the orbit there (reported as non-finite, named
                # by varint.methods.planetary); an earlier mark is kept.
                x[0] = math.nan
            return status
        if part == INTERACTION:
            status = kick(x, V, k, h, par)
            if status != KEPLER_OK:
                x[0] = math.inf     # an encounter: +inf tells it from a failed drift
            return status
        _jump(x, V, k, h, par)
        return KEPLER_OK

    return apply
