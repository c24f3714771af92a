"""Test drivers for the flows of varint.flows: many steps of one orbit in a
compiled loop, the Taylor reference from Hamilton's equations, and the
Hamiltonians the tests share."""

import functools

import numpy as np
import sympy as sp
from numba import njit

from varint.flows.gauss import (GAUSS, gauss_stepper, gauss_work, no_dtime,
                                stage_parameters)
from varint.flows.tao import tao_stepper, tao_work
from varint.models.hamiltonian import from_hamiltonian
from varint.schemes import get_scheme, part_stages


@functools.cache
def _gauss_loop(grad, grad_hess, dtime, timed):
    """The compiled loop of :func:`gauss_steps` for a model with kernels
    ``grad``, ``grad_hess`` and ``dtime``, time-dependent (``timed``) or
    not. It calls the step with the argument types of the part stepper's
    flow (:func:`varint.flows.general.general_apply`: ``timed`` a
    compile-time constant, the method's tables read-only), so that a test
    comparing the two compiles the step's helpers once, not once per caller
    (10 CPU s cold on the coupled general model)."""
    gauss_step = gauss_stepper(grad, grad_hess, dtime)

    @njit
    def loop(h, n, x, V, pars, A, b, c, d, E, work, prev, pt):
        s = c.shape[0]
        for i in range(n):
            if timed:
                # The times of this step's stages and start, from the integer step.
                t = i * h
                for j in range(s):
                    pars[j, -1] = t + c[j] * h
                pars[s, -1] = t
            status, _ = gauss_step(h, x, V, V.shape[0], pars, A, b, c, d, E, work, prev, timed,
                                   pt)
            if status != 0:
                return status
        return 0

    return loop


def _read_only(a):
    """A read-only copy of ``a``: numba types it as the part stepper's flow
    sees the tables it closes over."""
    a = np.array(a, dtype=np.float64)
    a.flags.writeable = False
    return a


def gauss_steps(model, x, W=None, h=0.01, n=1, scheme="GL6", prev=None, pt=None):
    """``n`` Gauss–Legendre steps from ``x`` (2N,) with the tangent map on
    the columns of ``W`` (2N, k), from the previous stages ``prev`` (the
    method's state; None: none); returns (x, W) and leaves the last stages
    in ``prev`` if given. A time-dependent model starts at t = 0 with the
    momentum conjugate to time ``pt`` (1,) (zero if None), advanced in
    place."""
    x = np.array(x, dtype=np.float64)
    W = np.zeros((model.dim, 0)) if W is None else np.array(W, dtype=np.float64)
    V = np.ascontiguousarray(W.T)
    g = GAUSS[scheme]
    A, b, c, d, E = (_read_only(a) for a in g.arrays)
    work = np.empty(gauss_work(model.n_dof, g.stages, V.shape[0]))
    if prev is None:
        prev = np.full(g.stages * model.dim, np.nan)
    timed = bool(model.time_dependent)
    pt = np.zeros(1) if pt is None else pt
    loop = _gauss_loop(model.grad_h, model.grad_hess_h, model.dtime_h if timed else no_dtime,
                       timed)
    status = loop(float(h), int(n), x, V, stage_parameters(model.parameters_at(0.0), g.stages),
                  A, b, c, d, E, work, prev, pt)
    assert status == 0, f"Gauss–Legendre failed with status {status}"
    return x, np.ascontiguousarray(V.T)


@functools.cache
def _tao_loop(grad_hess):
    """The compiled loop of :func:`tao_steps` for a model with kernel
    ``grad_hess``."""
    tao_step = tao_stepper(grad_hess)

    @njit
    def loop(n, parts, h, omega, x, x2, V, G, par, work):
        for _ in range(n):
            status = tao_step(parts, h, omega, x, x2, V, V.shape[0], G, par, work)
            if status != 0:
                return status
        return 0

    return loop


def tao_steps(model, x, W=None, h=0.01, n=1, scheme="ABC2", omega=20.0, copy=None, G=None):
    """``n`` steps of Tao's method (composition ``scheme`` over H_A, H_B,
    ω H_C) from ``x`` lifted to the diagonal (or the second copy ``copy``
    and its tangent ``G``); returns (x, W, copy, G)."""
    x = np.array(x, dtype=np.float64)
    x2 = x.copy() if copy is None else np.array(copy, dtype=np.float64)
    G = np.eye(model.dim) if G is None else np.array(G, dtype=np.float64)
    W = np.zeros((model.dim, 0)) if W is None else np.array(W, dtype=np.float64)
    V = np.ascontiguousarray(W.T)
    parts, hs = part_stages(get_scheme(scheme), float(h), {0: 0, 1: 1, 2: 2})
    work = np.empty(tao_work(model.n_dof, V.shape[0]))
    status = _tao_loop(model.grad_hess_h)(int(n), parts, hs, float(omega), x, x2, V, G,
                                          model.parameters_at(None), work)
    assert status == 0, f"Tao's method failed with status {status}"
    return x, np.ascontiguousarray(V.T), x2, G


@functools.cache
def _taylor(symbolic, k):
    import heyoka as hy

    from varint.baselines.taylor import heyoka_system

    system, variables = heyoka_system(symbolic)
    if k:
        system = hy.var_ode_sys(system, hy.var_args.vars, order=1)
    return hy.taylor_adaptive(system, np.zeros(len(variables) * (1 + (len(variables) if k
                                                                         else 0))), tol=1e-16)


def taylor_reference(model, x0, t, tangent=False):
    """The orbit at time ``t`` from ``x0`` by heyoka's Taylor method on
    Hamilton's equations of the model's expression (tolerance 1e-16), and,
    with ``tangent``, the full tangent map (2N, 2N)."""
    d = model.dim
    ta = _taylor(model.symbolic(), bool(tangent))
    ta.time = 0.0
    ta.state[:] = 0.0
    ta.state[:d] = x0
    if tangent:
        ta.state[d:] = np.eye(d).ravel()
    ta.propagate_until(float(t))
    if tangent:
        return ta.state[:d].copy(), ta.state[d:].reshape(d, d).copy()
    return ta.state[:d].copy()


def symplectic_form(n):
    """J = [[0, 1], [−1, 0]] for N = n degrees of freedom."""
    J = np.zeros((2 * n, 2 * n))
    J[:n, n:] = np.eye(n)
    J[n:, :n] = -np.eye(n)
    return J


# -- the Hamiltonians the tests share --------------------------------------------------
@functools.cache
def cr3bp(mu=0.01):
    """The restricted three-body problem in the synodic frame (integrable
    part: the rotating frame)."""
    x, y, px, py = sp.symbols("x y p_x p_y")
    mu = sp.nsimplify(mu)
    r1 = sp.sqrt((x + mu) ** 2 + y ** 2)
    r2 = sp.sqrt((x - 1 + mu) ** 2 + y ** 2)
    H = (px ** 2 + py ** 2) / 2 + y * px - x * py - (1 - mu) / r1 - mu / r2
    return from_hamiltonian(H, [x, y], [px, py], name="CR3BP test")


@functools.cache
def relativistic():
    """T = √(1 + |p|²) in the Hénon–Heiles potential (separable, T not
    quadratic)."""
    x, y, px, py = sp.symbols("x y p_x p_y")
    H = sp.sqrt(1 + px ** 2 + py ** 2) + (x ** 2 + y ** 2) / 2 + x ** 2 * y - y ** 3 / 3
    return from_hamiltonian(H, [x, y], [px, py], name="relativistic HH")


@functools.cache
def larmor():
    """A charged particle in a uniform magnetic field B = 2 along z
    (symmetric gauge) and a quartic well: the Larmor rotation plus V."""
    x, y, z, px, py, pz = sp.symbols("x y z p_x p_y p_z")
    B = 2
    H = ((px + B * y / 2) ** 2 + (py - B * x / 2) ** 2 + pz ** 2) / 2 + (x ** 4 + y ** 4
                                                                           + z ** 4) / 4
    return from_hamiltonian(H, [x, y, z], [px, py, pz], name="Larmor test")


@functools.cache
def bottle():
    """A charged particle in a magnetic bottle B_z = 1 + z², vector
    potential (B_z/2)(−y, x, 0) (general, non-separable)."""
    x, y, z, px, py, pz = sp.symbols("x y z p_x p_y p_z")
    Bz = 1 + z ** 2
    H = ((px + Bz * y / 2) ** 2 + (py - Bz * x / 2) ** 2 + pz ** 2) / 2
    return from_hamiltonian(H, [x, y, z], [px, py, pz], name="bottle test")


@functools.cache
def tao_example():
    """Tao's (2016) first example, H = (q² + 1)(p² + 1)/2 (general)."""
    q, p = sp.symbols("q p")
    return from_hamiltonian((q ** 2 + 1) * (p ** 2 + 1) / 2, [q], [p], name="Tao example")


@functools.cache
def coupled_general():
    """A non-integrable 2-dof H without exploitable structure: Hénon–Heiles
    plus the couplings (x p_y)²/8 and x y p_x/4 (a coordinate and its own
    momentum in one term: no part of it is solvable alone)."""
    x, y, px, py = sp.symbols("x y p_x p_y")
    H = ((px ** 2 + py ** 2) / 2 + (x ** 2 + y ** 2) / 2 + x ** 2 * y - y ** 3 / 3
         + (x * py) ** 2 / 8 + x * y * px / 4)
    return from_hamiltonian(H, [x, y], [px, py], name="coupled general")


def finite_difference(step, x, eps=1e-6):
    """Central differences of the map ``step`` (x ↦ x') at x: (2N, 2N)."""
    d = len(x)
    D = np.empty((d, d))
    for j in range(d):
        e = np.zeros(d)
        e[j] = eps
        D[:, j] = (step(x + e) - step(x - e)) / (2 * eps)
    return D
