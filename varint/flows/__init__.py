"""Exact flows, implicit and extended-phase-space steps of Hamiltonians
beyond ½pᵀM⁻¹p + V(q), each fused with its tangent map.

Every function here is a small numba kernel acting in place on one orbit
``x`` (q, p) of length 2N and on ``k`` deviation vectors held as the rows
of ``V`` (k, 2N), the layout of the part stepper
(:mod:`varint.kernels.parts`). The model's own compiled derivatives
(:mod:`varint.models.hamiltonian`) are passed in as arguments, so numba
compiles them into the flow.

* :mod:`.split` — the flows of the parts of H = T(p) + V(q) with any T
  (the drift of T and the kick of V) and of H = A + V(q) with A the free
  motion seen from a rotating frame, a uniform magnetic field (Larmor
  rotation) or an isotropic oscillator: exactly solvable, their tangent maps
  exact, so every explicit two-part scheme and its tangent map apply.
* :mod:`.gauss` — implicit Gauss–Legendre Runge–Kutta steps (s = 2, 3, 4;
  orders 4, 6, 8) for any H(q, p), whose tangent map is the derivative of
  the converged implicit step.
* :mod:`.tao` — Tao's (2016) explicit flows of two bound copies of phase
  space, for any H(q, p), and their tangent maps.
"""
