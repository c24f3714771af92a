"""Symplectic splitting schemes for H = A(p) + B(q), as data.

A scheme is a palindromic product of the exact flows of the drift
A = ½ pᵀM⁻¹p and the kick B = V(q), optionally wrapped in the corrector
flow of C = {B, {B, A}} = ∇Vᵀ M⁻¹ ∇V (Skokos & Gerlach 2010, eqs. 22 and 26):

    S^c(τ) = e^{−gτ³/2 L_C} S(τ) e^{−gτ³/2 L_C}.

Every scheme is stored as the independent half of its palindrome (centre
last), exactly as published, and expanded by :meth:`SplittingScheme.stages`.
One generic stepper (:mod:`varint.kernels.tm`) runs them all; nothing here is
scheme-specific code.

References
----------
.. [LR01] J. Laskar & P. Robutel, Celest. Mech. Dyn. Astron. 80, 39 (2001).
.. [BCF13] S. Blanes, F. Casas, A. Farrés, J. Laskar, J. Makazaga & A. Murua,
   Appl. Numer. Math. 68, 58 (2013).
.. [BM02] S. Blanes & P. C. Moan, J. Comput. Appl. Math. 142, 313 (2002).
.. [FR90] E. Forest & R. D. Ruth, Physica D 43, 105 (1990); H. Yoshida,
   Phys. Lett. A 150, 262 (1990).
.. [KL97] W. Kahan & R.-C. Li, Math. Comp. 66, 1089 (1997).
.. [S14] Ch. Skokos, E. Gerlach, J. D. Bodyfelt, G. Papamikos & S. Eggl,
   Phys. Lett. A 378, 1809 (2014): the three-part split ABC of the DDNLS.
.. [SS05] M. Sofroniou & G. Spaletta, Optim. Methods Softw. 20, 597 (2005).
.. [D19] C. Danieli, B. Many Manda, T. Mithun & Ch. Skokos, Math. Eng. 1, 447
   (2019): s9ABC6, s11ABC6, s17ABC8 (and s19ABC8, whose table is not here).
.. [BCM06] S. Blanes, F. Casas & A. Murua, SIAM J. Sci. Comput. 27, 1817
   (2006): symmetric compositions of a symmetric second-order map with
   processing (the kernels and processors of :class:`ProcessedScheme`).

Schemes over k ≥ 2 named parts
------------------------------
A Hamiltonian split into k integrable parts H = P_1 + … + P_k (the DDNLS's
on-site part A and its two hopping parts B and C, [S14]_) is integrated by
:class:`CompositionScheme`: a symmetric composition of the symmetric
second-order map S2 (ABC² for k = 3). Both kinds live in one registry,
:data:`SCHEMES`, resolved by :func:`get_scheme`, and both become a *word*
(:func:`scheme_word`): the ordered flows, each a slot (which part), a
coefficient and the power of τ of its length, which the part stepper
(:mod:`varint.kernels.parts`) runs.
"""

from __future__ import annotations

import functools
import math
import numbers
from dataclasses import dataclass, field

import numpy as np

__all__ = ["SplittingScheme", "CompositionScheme", "ProcessedScheme", "SCHEMES", "DEFAULT_SCHEME",
           "default_for", "get_scheme", "register_scheme", "registered", "stage_arrays", "stage_times",
           "scheme_word", "part_stages", "CORRECTOR"]

#: Stage kinds used by :meth:`SplittingScheme.stages`.
DRIFT, KICK = 0, 1


@dataclass(frozen=True)
class SplittingScheme:
    """A palindromic splitting scheme ``e^{a1 τ L_A} e^{b1 τ L_B} …``.

    Parameters
    ----------
    name : str
        Literature name, e.g. ``"SBAB2C"``; the registry key.
    drift_first : bool
        ``True`` for ABA layouts (SABA_n, ABA864, compositions of leapfrog),
        ``False`` for BAB layouts (SBAB_n).
    drifts, kicks : tuple of float
        Independent halves of the drift and kick coefficients, centre last.
        The centre belongs to whichever list is one longer for its layout
        (see :meth:`stages`).
    order : int
        Order of the energy error for H = ½pᵀM⁻¹p + V(q), where the
        perturbation parameter ε of [LR01]_ is 1: the smaller of the nominal
        orders.
    corrector : float or None
        The constant g of the corrector ``e^{−gτ³/2 L_C}`` on each side, or
        ``None`` for an uncorrected scheme.
    reference : str
        Where the coefficients come from.
    nominal_order : str
        The order as published, e.g. ``"(4,2)"`` for SBAB2: O(τ⁴ε + τ²ε²).

    Raises
    ------
    ValueError
        If a field has the wrong type (e.g. a coefficient that is not a
        finite real number, an order that is not a positive integer, a
        corrector that is not a finite number or None), the drift or kick
        coefficients do not sum to 1, or the two halves have lengths that
        fit no palindromic layout. The message names the scheme and the
        field.
    """

    name: str
    drift_first: bool
    drifts: tuple[float, ...]
    kicks: tuple[float, ...]
    order: int
    corrector: float | None = None
    reference: str = ""
    nominal_order: str = ""
    _stages: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        self._check_fields()
        first, second = (self.drifts, self.kicks) if self.drift_first else (self.kicks, self.drifts)
        if len(first) not in (len(second), len(second) + 1) or not second:
            raise ValueError(
                f"scheme {self.name!r}: {len(self.drifts)} drift and {len(self.kicks)} kick "
                "coefficients fit no palindromic layout (the outer kind needs as many "
                "coefficients as the inner one, or one more)"
            )
        seq = []
        for i in range(len(first)):
            seq.append(first[i])
            if i < len(second):
                seq.append(second[i])
        # Mirror everything but the centre stage.
        full = seq + seq[-2::-1]
        kinds = []
        outer, inner = (DRIFT, KICK) if self.drift_first else (KICK, DRIFT)
        for i in range(len(seq)):
            kinds.append(outer if i % 2 == 0 else inner)
        kinds = kinds + kinds[-2::-1]
        for kind, label in ((DRIFT, "drift"), (KICK, "kick")):
            total = math.fsum(c for c, k in zip(full, kinds, strict=True) if k == kind)
            if not abs(total - 1.0) <= 1e-14:
                raise ValueError(
                    f"scheme {self.name!r}: the {label} coefficients sum to {total!r}, expected 1"
                )
        object.__setattr__(self, "_stages", tuple(zip(kinds, full, strict=True)))

    def _check_fields(self):
        """Check every field's type and value, and store the coefficients
        as tuples of floats (a list or array would make the frozen scheme
        unhashable)."""
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"a scheme's name must be a non-empty string, got {self.name!r}")
        where = f"scheme {self.name!r}"
        if not isinstance(self.drift_first, (bool, np.bool_)):
            raise ValueError(f"{where}: drift_first must be True (ABA layout) or False (BAB), "
                             f"got {self.drift_first!r}")
        for label in ("drifts", "kicks"):
            values = getattr(self, label)
            if isinstance(values, (str, bytes)) or not hasattr(values, "__len__"):
                raise ValueError(f"{where}: {label} must be a sequence of numbers, got "
                                 f"{values!r}")
            for i, c in enumerate(values):
                if (isinstance(c, (bool, np.bool_)) or not isinstance(c, numbers.Real)
                        or not math.isfinite(c)):
                    raise ValueError(f"{where}: {label}[{i}] must be a finite real number, "
                                     f"got {c!r}")
            object.__setattr__(self, label, tuple(float(c) for c in values))
        if (isinstance(self.order, (bool, np.bool_)) or not isinstance(self.order, numbers.Integral)
                or self.order < 1):
            raise ValueError(f"{where}: order must be a positive integer, got {self.order!r}")
        object.__setattr__(self, "order", int(self.order))
        if self.corrector is not None:
            g = self.corrector
            if isinstance(g, (bool, np.bool_)) or not isinstance(g, numbers.Real) \
                    or not math.isfinite(g):
                raise ValueError(f"{where}: corrector must be a finite number (the constant g) "
                                 f"or None, got {g!r}")
            object.__setattr__(self, "corrector", float(g))
        for label in ("reference", "nominal_order"):
            if not isinstance(getattr(self, label), str):
                raise ValueError(f"{where}: {label} must be a string, got "
                                 f"{getattr(self, label)!r}")

    def stages(self) -> tuple[tuple[int, float], ...]:
        """The full palindrome as ``(kind, coefficient)`` pairs, in order of
        application (kind is ``DRIFT`` = 0 or ``KICK`` = 1); correctors not
        included."""
        return self._stages

    @property
    def n_parts(self) -> int:
        """2: the drift A = ½pᵀM⁻¹p and the kick B = V(q) (the corrector
        C = {B, {B, A}} is made of the same two)."""
        return 2

    @property
    def n_kicks(self) -> int:
        """Kick stages in one step (force evaluations without reuse)."""
        return sum(1 for k, _ in self._stages if k == KICK)

    @property
    def force_evaluations(self) -> int:
        """∇V evaluations per step in a long run.

        A kick at the end of a step and one at the start of the next act at
        the same q, so BAB layouts reuse that force; a corrector needs ∇V
        (and D²V) at the step boundary, which costs one more evaluation in
        ABA layouts.
        """
        n = self.n_kicks
        if not self.drift_first:
            n -= 1
        elif self.corrector is not None:
            n += 1
        return n

    def describe(self) -> dict:
        """JSON-serialisable description (for result provenance)."""
        return {
            "name": self.name,
            "order": self.order,
            "nominal_order": self.nominal_order,
            "corrector": self.corrector,
            "force_evaluations": self.force_evaluations,
            "reference": self.reference,
        }

    def corrected(self, g: float, name: str | None = None) -> SplittingScheme:
        """This scheme wrapped in the corrector of constant ``g`` (order 4 for
        H = T(p) + V(q) when the uncorrected scheme is O(τ^{2n}ε + τ²ε²))."""
        order = min(4, int(self.nominal_order.strip("()").split(",")[0])) if self.nominal_order else 4
        return SplittingScheme(
            name=name or self.name + "C",
            drift_first=self.drift_first,
            drifts=self.drifts,
            kicks=self.kicks,
            order=order,
            corrector=g,
            reference=self.reference,
            nominal_order=self.nominal_order.replace(",2)", ",4)") if self.nominal_order else "",
        )

    def repeated(self, m: int) -> SplittingScheme:
        """S(τ/m)^m as one scheme of step τ: m steps of this one per
        interval τ, the flows of the same part at the joints merged (exact:
        they are one flow). With ``renorm`` every τ this runs m steps per
        renormalisation, and the drifts of a drift-first scheme cost m + 1
        flows per τ instead of 2m — the Kepler drifts of a Wisdom–Holman
        map, which dominate its cost.

        Raises
        ------
        ValueError
            If m is not a positive integer, or the scheme has a corrector
            (its correctors would sit at every joint).
        """
        if isinstance(m, (bool, np.bool_)) or not isinstance(m, numbers.Integral) or m < 1:
            raise ValueError(f"m must be a positive integer (steps per interval), got {m!r}")
        if self.corrector is not None:
            raise ValueError(f"scheme {self.name!r} has a corrector; repeat the scheme without "
                             "it (its correctors would act at every joint)")
        merged: list[list] = []
        for _ in range(int(m)):
            for kind, c in self._stages:
                if merged and merged[-1][0] == kind:
                    merged[-1][1] += c / m
                else:
                    merged.append([kind, c / m])
        half = merged[:(len(merged) + 1) // 2]
        return SplittingScheme(
            name=f"{self.name}x{m}", drift_first=self.drift_first,
            drifts=tuple(c for k, c in half if k == DRIFT),
            kicks=tuple(c for k, c in half if k == KICK), order=self.order,
            reference=f"{self.reference}; {m} steps of τ/{m} per interval τ",
            nominal_order=self.nominal_order)

    @classmethod
    def from_composition(cls, name, gammas, order, reference=""):
        """A symmetric composition Π_i S2(γ_i τ) of the leapfrog
        S2(h) = e^{h/2 L_A} e^{h L_B} e^{h/2 L_A}, adjacent drifts merged.

        ``gammas`` is the independent half, centre last.
        """
        g = list(gammas)
        drifts = [g[0] / 2] + [(g[i] + g[i + 1]) / 2 for i in range(len(g) - 1)]
        return cls(name=name, drift_first=True, drifts=tuple(drifts), kicks=tuple(g),
                   order=order, reference=reference, nominal_order=f"({order})")


# --------------------------------------------------------------------------
# Words: a scheme as the ordered flows it applies.

#: The slot of the corrector flow e^{h L_C}, C = {B,{B,A}}, in a word.
CORRECTOR = -1


def scheme_word(scheme):
    """The flows of one step of ``scheme``, in order of application.

    Parameters
    ----------
    scheme : SplittingScheme or CompositionScheme

    Returns
    -------
    tuple of (slot, coefficient, power)
        Flow e^{c τ^power L_slot}. For a two-part scheme slot 0 is the drift
        (A = ½pᵀM⁻¹p), slot 1 the kick (B = V), and :data:`CORRECTOR` the
        corrector, whose length is −gτ³/2 on each side of the step
        (Skokos & Gerlach 2010, eq. 22); for a k-part composition the slots
        are the parts 0 … k−1.
    """
    if isinstance(scheme, CompositionScheme):
        return tuple((slot, c, 1) for slot, c in scheme.word())
    if not isinstance(scheme, SplittingScheme):
        raise ValueError(f"scheme_word needs a SplittingScheme or CompositionScheme, got "
                         f"{type(scheme).__name__} {scheme!r}")
    word = tuple((0 if kind == DRIFT else 1, c, 1) for kind, c in scheme.stages())
    if scheme.corrector is not None:
        # Both correctors act on p at the q of the outer stage, so for a BAB
        # layout they commute with the first and last kick, and for an ABA
        # layout they sit outside the first and last drift, as in eq. 22.
        end = ((CORRECTOR, -scheme.corrector / 2, 3),)
        word = end + word + end
    return word


def _merge(word):
    """Adjacent flows of the same part composed into one (exact: they are
    the flow of one autonomous Hamiltonian); zero-length flows dropped."""
    out = []
    for slot, c in word:
        if out and out[-1][0] == slot:
            out[-1] = (slot, out[-1][1] + c)
        else:
            out.append((slot, c))
    return tuple((s, c) for s, c in out if c != 0.0)


def strang_word(n_parts):
    """S2(h) for H = P_0 + … + P_{k−1}: e^{h/2 L_0} … e^{h L_{k−1}} … e^{h/2 L_0},
    the symmetric second-order map (ABC² of [S14]_ for k = 3), as
    (slot, coefficient) pairs."""
    half = [(slot, 0.5) for slot in range(n_parts - 1)]
    return tuple(half + [(n_parts - 1, 1.0)] + half[::-1])



@dataclass(frozen=True)
class CompositionScheme:
    """A symmetric composition Π_i S2(γ_i τ) of the second-order map
    S2 = :func:`strang_word` over ``n_parts`` parts, adjacent flows of the
    same part merged (Yoshida 1990; Kahan & Li 1997; McLachlan 1995).

    Parameters
    ----------
    name : str
        Literature name, e.g. ``"s9ABC6"``; the key in :data:`SCHEMES`.
    n_parts : int
        The number of parts k ≥ 2 of the split it composes.
    gammas : tuple of float
        The independent half of the palindromic γ_1 … γ_s, centre last
        (s = 2·len − 1 stages), as published; Σγ = 1.
    order : int
        Order of the energy error.
    reference : str
        Where the coefficients come from.

    Raises
    ------
    ValueError
        If a field has the wrong type, the γ do not sum to 1, or n_parts < 2.
    """

    name: str
    n_parts: int
    gammas: tuple
    order: int
    reference: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"a scheme's name must be a non-empty string, got {self.name!r}")
        where = f"scheme {self.name!r}"
        if isinstance(self.n_parts, bool) or not isinstance(self.n_parts, numbers.Integral) \
                or self.n_parts < 2:
            raise ValueError(f"{where}: n_parts must be an integer >= 2, got {self.n_parts!r}")
        if isinstance(self.order, bool) or not isinstance(self.order, numbers.Integral) \
                or self.order < 1:
            raise ValueError(f"{where}: order must be a positive integer, got {self.order!r}")
        g = self.gammas
        if isinstance(g, (str, bytes)) or not hasattr(g, "__len__") or len(g) == 0:
            raise ValueError(f"{where}: gammas must be a non-empty sequence of numbers, got {g!r}")
        for i, c in enumerate(g):
            if isinstance(c, bool) or not isinstance(c, numbers.Real) or not math.isfinite(c):
                raise ValueError(f"{where}: gammas[{i}] must be a finite real number, got {c!r}")
        object.__setattr__(self, "gammas", tuple(float(c) for c in g))
        object.__setattr__(self, "n_parts", int(self.n_parts))
        object.__setattr__(self, "order", int(self.order))
        total = math.fsum(self.stage_gammas())
        if not abs(total - 1.0) <= 1e-14:
            raise ValueError(f"{where}: the composition coefficients sum to {total!r}, expected 1")

    def stage_gammas(self):
        """The full palindrome γ_1 … γ_s."""
        g = list(self.gammas)
        return tuple(g + g[-2::-1])

    @property
    def stages(self):
        """s, the number of S2 maps per step."""
        return 2 * len(self.gammas) - 1

    def word(self):
        """The merged (slot, coefficient) flows of one step."""
        base = strang_word(self.n_parts)
        return _merge([(slot, g * c) for g in self.stage_gammas() for slot, c in base])

    def flows_per_step(self):
        """Flows of each part in one step: (count of part 0, …)."""
        counts = [0] * self.n_parts
        for slot, _ in self.word():
            counts[slot] += 1
        return tuple(counts)

    def describe(self) -> dict:
        """JSON-serialisable description (for result provenance)."""
        return {"name": self.name, "parts": self.n_parts, "stages": self.stages,
                "order": self.order, "flows_per_step": list(self.flows_per_step()),
                "reference": self.reference}


@dataclass(frozen=True)
class ProcessedScheme:
    """A processed scheme P ∘ K(τ)ⁿ ∘ P⁻¹ for H = ½pᵀM⁻¹p + V(q): a cheap
    kernel K of high *effective* order, and a processor P applied only
    where the state is read ([BCM06]_; Blanes, Casas & Ros, SIAM J. Sci.
    Comput. 21, 711 (1999)).

    The kernel K(τ) = Π_i S2(a_i τ) is a symmetric composition of the
    leapfrog S2(h) = e^{h/2 L_A} e^{h L_B} e^{h/2 L_A}; alone it has a low
    order, but it is conjugate to a method of order ``order``: the
    processor P(τ) = S2(p_1 τ) ∘ S2(p_2 τ) ∘ … ∘ S2(p_r τ) (S2(p_r τ)
    acts first; Σ p_j = 0, so P is near the identity) makes
    P ∘ Kⁿ ∘ P⁻¹ = φ_{nτ} + O(nτ·τ^order), with P⁻¹(τ) = S2(−p_r τ) ∘ … ∘
    S2(−p_1 τ). A run maps its initial state once by P⁻¹, steps the
    kernel, and reads every output through P; the processor's cost is paid
    per output, not per step. Both maps are drifts and kicks, so their
    tangent maps are exact and carry the deviation vectors (the TM
    method, :mod:`varint.methods.tm`).

    Parameters
    ----------
    name : str
        The key in :data:`SCHEMES`.
    kernel : tuple of float
        The independent half of the kernel's palindromic a_i, centre last.
    processor : tuple of float
        p_1 … p_r, in the order of the product above (p_1 acts last).
    order : int
        The effective order (of the processed method).
    reference : str

    Raises
    ------
    ValueError
        If a field has the wrong type, the a_i do not sum to 1, or the p_j
        do not sum to 0.
    """

    name: str
    kernel: tuple
    processor: tuple
    order: int
    reference: str = ""
    _kernel: SplittingScheme = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"a scheme's name must be a non-empty string, got {self.name!r}")
        where = f"scheme {self.name!r}"
        for label in ("kernel", "processor"):
            values = getattr(self, label)
            if isinstance(values, (str, bytes)) or not hasattr(values, "__len__") \
                    or len(values) == 0:
                raise ValueError(f"{where}: {label} must be a non-empty sequence of numbers, "
                                 f"got {values!r}")
            for i, c in enumerate(values):
                if isinstance(c, (bool, np.bool_)) or not isinstance(c, numbers.Real) \
                        or not math.isfinite(c):
                    raise ValueError(f"{where}: {label}[{i}] must be a finite real number, "
                                     f"got {c!r}")
            object.__setattr__(self, label, tuple(float(c) for c in values))
        total = math.fsum(self.processor)
        if not abs(total) <= 1e-14:
            raise ValueError(f"{where}: the processor coefficients sum to {total!r}, expected 0")
        # The kernel is a leapfrog composition; its own order (2) is not the
        # processed method's. The sum rule is checked there.
        object.__setattr__(self, "_kernel", SplittingScheme.from_composition(
            self.name + "-kernel", self.kernel, order=2, reference=self.reference))
        if isinstance(self.order, (bool, np.bool_)) or not isinstance(self.order, numbers.Integral) \
                or self.order < 1:
            raise ValueError(f"{where}: order must be a positive integer, got {self.order!r}")
        object.__setattr__(self, "order", int(self.order))

    @property
    def kernel_scheme(self) -> SplittingScheme:
        """The kernel K as a :class:`SplittingScheme` (drifts merged)."""
        return self._kernel

    @property
    def force_evaluations(self) -> int:
        """∇V evaluations per kernel step in a long run."""
        return self._kernel.force_evaluations

    def processor_stages(self, tau: float, inverse: bool = False):
        """Stage tables of P(τ) (or P⁻¹(τ)) for the TM stepper, as
        :func:`stage_arrays`: adjacent drifts merged, no correctors.

        Returns
        -------
        kinds : ndarray of int64
        h : ndarray of float64
        hc : ndarray of float64 (zeros)
        """
        # New arrays every call: callers may keep and change them.
        return tuple(a.copy() for a in _processor_stages(self, float(tau), bool(inverse)))

    def describe(self) -> dict:
        """JSON-serialisable description (for result provenance)."""
        return {"name": self.name, "order": self.order, "processed": True,
                "kernel_stages": 2 * len(self.kernel) - 1,
                "processor_stages": len(self.processor),
                "force_evaluations": self.force_evaluations, "reference": self.reference}


@functools.lru_cache(maxsize=64)
def _processor_stages(scheme, tau, inverse):
    # In order of application: P applies S2(p_r τ) first, P⁻¹ S2(−p_1 τ).
    coeffs = [-c for c in scheme.processor] if inverse else list(scheme.processor[::-1])
    word = _merge([(kind, c * h) for c in coeffs
                   for kind, h in ((DRIFT, 0.5), (KICK, 1.0), (DRIFT, 0.5))])
    h = np.array([c * tau for _, c in word], dtype=np.float64)
    return np.array([k for k, _ in word], dtype=np.int64), h, np.zeros_like(h)


#: Every registered scheme, two-part (:class:`SplittingScheme`) and k-part
#: (:class:`CompositionScheme`), by upper-cased name, in registration order.
SCHEMES: dict[str, SplittingScheme | CompositionScheme | ProcessedScheme] = {}

#: The scheme of the TM method and the TDH methods when none is given: the
#: paper's S_B2^c (Skokos & Gerlach 2010), SBAB2 with corrector.
DEFAULT_SCHEME = "SBAB2C"


def default_for(model, method="tm"):
    """The scheme ``method`` runs ``model`` with when none is given.

    A model split into parts may declare its preferred scheme
    (``model.parts.default_scheme``): the lattices name the best of their
    fused part stepper (ABA864 for the KG and FPUT chains, s11ABC6 for the
    DDNLS; Danieli et al. 2019), which reaches an energy error at a fraction
    of the cost of SBAB2C on the generic stepper (``studies/bench_peers.py``,
    the lattice case). The TM method takes it; every other method, and
    every model without one, takes :data:`DEFAULT_SCHEME`.

    Parameters
    ----------
    model : Model
    method : str, default "tm"

    Returns
    -------
    str or SplittingScheme or CompositionScheme
        The model's declared default or :data:`DEFAULT_SCHEME`.

    References
    ----------
    C. Danieli, B. Many Manda, T. Mithun & Ch. Skokos, Math. Eng. 1, 447
    (2019).
    """
    own = getattr(getattr(model, "parts", None), "default_scheme", None)
    return own if own is not None and method == "tm" else DEFAULT_SCHEME


def register_scheme(scheme: SplittingScheme | CompositionScheme | ProcessedScheme
                    ) -> SplittingScheme | CompositionScheme | ProcessedScheme:
    """Add ``scheme`` to :data:`SCHEMES` under its upper-cased name.

    Raises
    ------
    ValueError
        If ``scheme`` is not a :class:`SplittingScheme`,
        :class:`CompositionScheme` or :class:`ProcessedScheme` (a name is not enough: the registry holds
        coefficients) or its name is taken.
    """
    if not isinstance(scheme, (SplittingScheme, CompositionScheme, ProcessedScheme)):
        known = (f"; {scheme!r} is already registered, get it with get_scheme({scheme!r})"
                 if isinstance(scheme, str) and scheme.upper() in SCHEMES else "")
        raise ValueError(
            f"register_scheme needs a SplittingScheme or CompositionScheme, got "
            f"{type(scheme).__name__} {scheme!r}; build one with SplittingScheme(name, "
            "drift_first, drifts, kicks, order) or CompositionScheme(name, n_parts, gammas, "
            "order)" + known)
    key = scheme.name.upper()
    if key in SCHEMES:
        raise ValueError(f"a scheme named {scheme.name!r} is already registered")
    SCHEMES[key] = scheme
    return scheme


def get_scheme(scheme: str | SplittingScheme | CompositionScheme | ProcessedScheme,
               n_parts: int | None = None, processed: bool = False
               ) -> SplittingScheme | CompositionScheme | ProcessedScheme:
    """The registered scheme of a name (case-insensitive), or a scheme
    passed through.

    Parameters
    ----------
    scheme : str, SplittingScheme, CompositionScheme or ProcessedScheme
    n_parts : int, optional
        The split the caller integrates: 2 for the drift and kick of
        H = T + V (a :class:`SplittingScheme`, which the TM stepper, the
        TDH methods, the two-particle method and the section finder run);
        None for any.
    processed : bool, default False
        Whether the caller applies a :class:`ProcessedScheme`'s processor
        (the TM method does); otherwise one is refused, since its kernel
        alone is a low-order method.

    Raises
    ------
    ValueError
        For an unknown name (the message lists the valid ones), a scheme
        over another number of parts than ``n_parts`` (the message says
        which models it runs on), or a processed scheme where
        ``processed`` is False.
    """
    if isinstance(scheme, str) and scheme.upper() in SCHEMES:
        scheme = SCHEMES[scheme.upper()]
    elif not isinstance(scheme, (SplittingScheme, CompositionScheme, ProcessedScheme)):
        raise ValueError(f"unknown scheme {scheme!r}; expected one of: "
                         f"{', '.join(s.name for s in SCHEMES.values())}")
    if isinstance(scheme, ProcessedScheme):
        if not processed:
            raise ValueError(
                f"scheme {scheme.name!r} is processed (a kernel and a processor applied at "
                "outputs); only method='tm' with the drift and kick of H = T + V on a "
                "time-independent model applies the processor (not the TDH, two-particle or "
                "section methods, nor a lattice's part stepper): choose another scheme here")
        return scheme
    if n_parts == 2 and not isinstance(scheme, SplittingScheme):
        raise ValueError(
            f"scheme {scheme.name!r} composes the flows of {scheme.n_parts} parts; it runs on "
            f"models that declare a {scheme.n_parts}-part split (e.g. varint.models.DDNLS) with "
            "method='tm'")
    return scheme


def registered(n_parts: int | None = None):
    """The registered schemes in registration order; with ``n_parts = 2``
    the two-part ones (:class:`SplittingScheme`), with another number the
    compositions over that many parts. Processed schemes
    (:class:`ProcessedScheme`, the TM method only) are only in the full
    list."""
    if n_parts is None:
        return tuple(SCHEMES.values())
    if n_parts == 2:
        return tuple(s for s in SCHEMES.values() if isinstance(s, SplittingScheme))
    return tuple(s for s in SCHEMES.values()
                 if isinstance(s, CompositionScheme) and s.n_parts == n_parts)


# --------------------------------------------------------------------------
# Laskar & Robutel (2001): SABA_n (drift first) and SBAB_n (kick first).
# Halves centre last; g is the corrector constant of each scheme.
_LR = "Laskar & Robutel, Celest. Mech. Dyn. Astron. 80, 39 (2001)"
_s3, _s5, _s15, _s21, _s30 = (math.sqrt(v) for v in (3, 5, 15, 21, 30))
_saba4_p, _saba4_m = math.sqrt(525 + 70 * _s30), math.sqrt(525 - 70 * _s30)

_LASKAR_ROBUTEL = [
    # name, drift_first, drifts, kicks, n, g
    ("SABA1", True, (0.5,), (1.0,), 1, 1 / 12),
    ("SABA2", True, (0.5 - _s3 / 6, _s3 / 3), (0.5,), 2, (2 - _s3) / 24),
    ("SABA3", True, (0.5 - _s15 / 10, _s15 / 10), (5 / 18, 4 / 9), 3, (54 - 13 * _s15) / 648),
    ("SABA4", True,
     (0.5 - _saba4_p / 70, (_saba4_p - _saba4_m) / 70, _saba4_m / 35),
     (0.25 - _s30 / 72, 0.25 + _s30 / 72), 4, 0.0033967750482086013315321577834921),
    ("SBAB1", False, (1.0,), (0.5,), 1, -1 / 24),
    ("SBAB2", False, (0.5,), (1 / 6, 2 / 3), 2, 1 / 72),
    ("SBAB3", False, (0.5 - _s5 / 10, 1 / _s5), (1 / 12, 5 / 12), 3, (13 - 5 * _s5) / 288),
    ("SBAB4", False, (0.5 - _s21 / 14, _s21 / 14), (1 / 20, 49 / 180, 16 / 45), 4,
     0.0036447936001532493022971399654498),
]

for _name, _df, _d, _k, _n, _g in _LASKAR_ROBUTEL:
    _base = SplittingScheme(
        _name, _df, _d, _k, order=2, reference=_LR, nominal_order=f"({2 * _n},2)")
    register_scheme(_base)
    register_scheme(_base.corrected(_g))

# Blanes, Casas, Farrés, Laskar, Makazaga & Murua (2013).
_BCF = "Blanes, Casas, Farrés, Laskar, Makazaga & Murua, Appl. Numer. Math. 68, 58 (2013)"
_aba864_b = (0.183083687472197221961703757166430291072,
             0.310782859898574869507522291054262796375,
             -0.0265646185119588006972121379164987592663)
register_scheme(SplittingScheme(
    "ABA864", True,
    drifts=(0.0711334264982231177779387300061549964174,
            0.241153427956640098736487795326289649618,
            0.521411761772814789212136078067994229991,
            -0.333698616227678005726562603400438876027),
    # Centre kick from the sum rule: one public table drops a digit.
    kicks=_aba864_b + (1 - 2 * math.fsum(_aba864_b),),
    order=4, reference=_BCF, nominal_order="(8,6,4)"))
register_scheme(SplittingScheme(
    "ABAH864", True,
    drifts=(0.06810235651658372084723976682061164571212,
            0.2511360387221033233072829580455350680082,
            -0.07507264957216562516006821767601620052338,
            -0.009544719701745007811488218957217113269121,
            0.5307579480704471776340674235341732001443),
    kicks=(0.1684432593618954534310382697756917558148,
           0.4243177173742677224300351657407231801453,
           -0.5858109694681756812309015355404036521923,
           0.4930499927320125053698281000239887162321),
    order=4, reference=_BCF, nominal_order="(8,6,4)"))
# ABA(10,6,4): 8 kicks, for H = A + εB with A integrable (a Kepler drift):
# O(ε τ¹⁰ + ε² τ⁶ + ε³ τ⁴).
register_scheme(SplittingScheme(
    "ABA1064", True,
    drifts=(0.03809449742241219545697532230863756534060,
            0.1452987161169137492940200726606637497442,
            0.2076276957255412507162056113249882065158,
            0.4359097036515261592231548624010651844006,
            -0.6538612258327867093807117373907094120024),
    kicks=(0.09585888083707521061077150377145884776921,
           0.2044461531429987806805077839164344779763,
           0.2170703479789911017143385924306336714532,
           -0.01737538195906509300561788011852699719871),
    order=4, reference=_BCF, nominal_order="(10,6,4)"))

# Compositions of the leapfrog.
_x1 = 1 / (2 - 2 ** (1 / 3))
register_scheme(SplittingScheme.from_composition(
    "FR4", (_x1, -(2 ** (1 / 3)) * _x1), order=4,
    reference="Forest & Ruth, Physica D 43, 105 (1990); Yoshida, Phys. Lett. A 150, 262 (1990)"))
_KL = "Kahan & Li, Math. Comp. 66, 1089 (1997)"
register_scheme(SplittingScheme.from_composition(
    "s9odr6", (0.39216144400731413927925056, 0.33259913678935943859974864,
               -0.70624617255763935980996482, 0.08221359629355080023149045,
               0.79854399093482996339895035), order=6, reference=_KL))
register_scheme(SplittingScheme.from_composition(
    "s11odr6", (0.21375583945878254555518066964857, 0.18329381407425713911385974425217,
                0.17692819473098943794898811709929, -0.44329082681170215849622829626258,
                0.11728560432865935385403585669136, 0.50405474843802736404832781714239),
    order=6, reference=_KL))

# Orders 8 and 10: symmetric compositions of the leapfrog with the smallest
# max|γ| known for their stage counts (Hairer, Lubich & Wanner, Geometric
# Numerical Integration, 2nd ed., Sect. V.3.2, eqs. 3.13, 3.14 and the
# p10s35 table). The digits agree with two further public tables, and the odd
# power sums Σγ³, Σγ⁵ (Σγ⁷, Σγ⁹ for order 10) vanish to round-off
# (tests/test_schemes.py); the orders are measured there and against the
# Taylor reference.
register_scheme(SplittingScheme.from_composition(
    "s15odr8", (0.74167036435061295344822780, -0.40910082580003159399730010,
                0.19075471029623837995387626, -0.57386247111608226665638773,
                0.29906418130365592384446354, 0.33462491824529818378495798,
                0.31529309239676659663205666, -0.79688793935291635401978884),
    order=8, reference="McLachlan, SIAM J. Sci. Comput. 16, 151 (1995); in " + _KL))
register_scheme(SplittingScheme.from_composition(
    "s17odr8", (0.13020248308889008087881763, 0.56116298177510838456196441,
                -0.38947496264484728640807860, 0.15884190655515560089621075,
                -0.39590389413323757733623154, 0.18453964097831570709183254,
                0.25837438768632204729397911, 0.29501172360931029887096624,
                -0.60550853383003451169892108),
    order=8, reference=_KL + " (s17odr8a)"))
register_scheme(SplittingScheme.from_composition(
    "s35odr10", (0.07879572252168641926390768, 0.31309610341510852776481247,
                 0.02791838323507806610952027, -0.22959284159390709415121340,
                 0.13096206107716486317465686, -0.26973340565451071434460973,
                 0.07497334315589143566613711, 0.11199342399981020488957508,
                 0.36613344954622675119314812, -0.39910563013603589787862981,
                 0.10308739852747107731580277, 0.41143087395589023782070412,
                 -0.00486636058313526176219566, -0.39203335370863990644808194,
                 0.05194250296244964703718290, 0.05066509075992449633587434,
                 0.04967437063972987905456880, 0.04931773575959453791768001),
    order=10, reference="Sofroniou & Spaletta, Optim. Methods Softw. 20, 597 (2005) "
                        "(s35odr10; Kahan & Li's own order-10 compositions have 31 and 33 "
                        "stages)"))

# Blanes & Moan (2002), SRKN_14^a (order 6).
_srkn_a = (0.037859319840611600, 0.10263563310243500, -0.025867888266558700,
           0.31424140307144700, -0.13014445951741500, 0.10641770036954300,
           -0.0087942431285105800)
_srkn_b = (0.091719152624461650, 0.18398317000500600, -0.056534365832888270,
           0.0049146887747128540, 0.14376112716835800, 0.32856769374680400,
           -0.19641146648645423)
register_scheme(SplittingScheme(
    "SRKN14a", True,
    # Centre drift from the sum rule (published as 0.2073050690568954).
    drifts=_srkn_a + (1 - 2 * math.fsum(_srkn_a),),
    kicks=_srkn_b, order=6,
    reference="Blanes & Moan, J. Comput. Appl. Math. 142, 313 (2002)", nominal_order="(6)"))


# Processed schemes ([BCM06]_): kernels Π S2(a_i τ) of effective order 6, 8
# and 10 with 11, 13 and 23 stages (against 14 kicks of SRKN14a, 17 of
# s17odr8 and 35 of s35odr10), and their processors. The free parameters
# (a_1 = 0.168 of the order-8 kernel, γ_6 = −0.1 of the order-6 processor)
# are the published choices; the other digits are as published (14–19
# significant digits; the sum rules close each table). The effective orders
# are measured in tests/test_processed.py, the error floors in
# studies/frontier.py. Processors are published as their first half γ_j,
# the second half −γ_j, and p = −γ.
_BCM06 = "Blanes, Casas & Murua, SIAM J. Sci. Comput. 27, 1817 (2006)"


def _antisymmetric(first):
    """p_1 … p_r of a processor published as its first r/2 coefficients
    γ_j whose second half is −γ_j, with p = −γ."""
    return tuple(-g for g in first) + tuple(first)


_a1, _a5 = 0.1705768865009222157, -0.423366140892658048
_g6 = (None, -0.20621953139126, 0.23651387483203, 0.09086982276241, 0.24687306977659, -0.1)
register_scheme(ProcessedScheme(
    "P11odr6", kernel=(_a1, _a1, _a1, _a1, _a5, 1 - 2 * (4 * _a1 + _a5)),
    processor=_antisymmetric((-math.fsum(_g6[1:]),) + _g6[1:]), order=6,
    reference=_BCM06 + " (s = 11, effective order 6)"))
_k8 = (0.168, 0.168, 0.585550530805562, -0.460090457516872, 0.172863148729731,
       0.179664539695039)
_g8 = (-0.008488123494574411, -0.337188967354338, 0.333987768164597, 0.588351189003849,
       0.162324207599241, -0.511744926116413, 0.236885952363384, 0.598212975943381,
       -0.543415765371656)
register_scheme(ProcessedScheme(
    "P13odr8", kernel=_k8 + (1 - 2 * math.fsum(_k8),),
    processor=_antisymmetric((-math.fsum(_g8),) + _g8), order=8,
    reference=_BCM06 + " (s = 13, effective order 8)"))
_k10 = (0.121657748919383,) * 5 + (-0.511318780154828, -0.172858614884985, 0.123016258833066,
                                   0.441503951671565, -0.327071324165477, 0.070952700957766)
_g10 = (0.4727142080578221, 0.01344750613191108, -0.4637104712987078, -0.3045590922565247,
        -0.5382945821834320, -0.1899795533199732, 0.1548256472553489, -0.3594148033156072,
        0.3430345669677392, 0.5334030283695922, 0.009116042043427756)
register_scheme(ProcessedScheme(
    "P23odr10", kernel=_k10 + (1 - 2 * math.fsum(_k10),),
    processor=_antisymmetric((-math.fsum(_g10),) + _g10), order=10,
    reference=_BCM06 + " (s = 23, effective order 10)"))


def stage_arrays(scheme: SplittingScheme, tau: float):
    """Stage tables for the compiled stepper, already scaled by τ.

    Returns
    -------
    kinds : ndarray of int64, shape (n_stages,)
        ``DRIFT`` (0) or ``KICK`` (1).
    h : ndarray of float64, shape (n_stages,)
        Drift length ``a_i τ`` or kick length ``b_i τ``.
    hc : ndarray of float64, shape (n_stages,)
        Corrector length on kick stages: ``−gτ³/2`` on the first and last
        stage, 0 elsewhere. Correctors act on p only, like kicks, so a
        corrector next to a kick at the same q is fused with it; for ABA
        layouts a kick stage of zero length carries it.
    """
    # New arrays every call: callers may keep and change them.
    return tuple(a.copy() for a in _stage_arrays(scheme, float(tau)))


@functools.lru_cache(maxsize=64)
def _stage_arrays(scheme, tau):
    st = list(scheme.stages())
    h_c = 0.0 if scheme.corrector is None else -scheme.corrector * tau ** 3 / 2
    kinds, h, hc = [], [], []
    for kind, c in st:
        kinds.append(kind)
        h.append(c * tau)
        hc.append(0.0)
    if h_c != 0.0:
        if scheme.drift_first:
            kinds = [KICK] + kinds + [KICK]
            h = [0.0] + h + [0.0]
            hc = [h_c] + hc + [h_c]
        else:
            hc[0] = hc[-1] = h_c
    return (np.array(kinds, dtype=np.int64), np.array(h, dtype=np.float64),
            np.array(hc, dtype=np.float64))


def stage_times(scheme: SplittingScheme):
    """The time of each stage of :func:`stage_arrays` in units of τ from the
    start of its step, for a time-dependent V integrated in the extended
    phase space (A = ½pᵀM⁻¹p + p_t drifts t by its length, B = V(q, t)
    kicks at fixed t; :mod:`varint.kernels.tm`).

    Stage s acts at c_s = the sum of the drift coefficients before it
    (summed exactly, :func:`math.fsum`). A value within 1e-14 of 1 (the
    last kick of a BAB scheme) is exactly 1, so that kick and the first
    kick of the next step are at the same time, bit for bit, and the
    stepper can reuse the force between them.

    Returns
    -------
    ndarray of float64, shape (n_stages,)
    """
    kinds, h, _ = stage_arrays(scheme, 1.0)
    out: list[float] = []
    before: list[float] = []
    for kind, c in zip(kinds, h, strict=True):
        total = math.fsum(before)
        out.append(1.0 if abs(total - 1.0) <= 1e-14 else total)
        if kind == DRIFT:
            before.append(float(c))
    return np.array(out, dtype=np.float64)


def part_stages(scheme, tau, slots):
    """Stage tables of the part stepper, already scaled by τ.

    Parameters
    ----------
    scheme : SplittingScheme or CompositionScheme
    tau : float
    slots : mapping of slot -> int
        The model's part index of each slot of the word (including
        :data:`CORRECTOR` if the scheme has one).

    Returns
    -------
    parts : ndarray of int64, shape (n_flows,)
    h : ndarray of float64, shape (n_flows,)
        Flow lengths c τ^power.
    """
    word = scheme_word(scheme)
    parts = np.array([slots[slot] for slot, _, _ in word], dtype=np.int64)
    h = np.array([c * tau ** power for _, c, power in word], dtype=np.float64)
    return parts, h


# --------------------------------------------------------------------------
# Compositions of ABC² (three-part split of the DDNLS, [S14]_, [D19]_).
# γ tables: independent half, centre last. The digits were checked against
# several public tables and every one is verified by its measured order
# (tests/test_schemes.py, studies/lattices.py). The 19-stage order-8 table
# behind D19's s19ABC8 was not found, so s19ABC8 is not registered (no
# other table stands in for it).
_cbrt2, _fifth2 = 2 ** (1 / 3), 2 ** (1 / 5)
_y4 = (1 / (2 - _cbrt2), -_cbrt2 / (2 - _cbrt2))
_y6_1, _y6_0 = 1 / (2 - _fifth2), -_fifth2 / (2 - _fifth2)
_p4 = 1 / (4 - 4 ** (1 / 3))
_YOSHIDA = "Yoshida, Phys. Lett. A 150, 262 (1990)"
_SS05 = "Sofroniou & Spaletta, Optim. Methods Softw. 20, 597 (2005)"
_ABC = [
    ("ABC2", (1.0,), 2, "Strang splitting of A + B + C; Skokos et al., Phys. Lett. A 378, 1809 "
                        "(2014)"),
    ("ABC4_Y", _y4, 4, _YOSHIDA + " (triple jump)"),
    ("ABC4_S", (_p4, _p4, 1 - 4 * _p4), 4, "Suzuki, Phys. Lett. A 146, 319 (1990)"),
    ("ABC6_Y", (_y4[0] * _y6_1, _y4[1] * _y6_1, _y4[0] * _y6_1, _y4[0] * _y6_0,
                _y4[1] * _y6_0), 6, _YOSHIDA + " (triple jump of ABC4_Y)"),
    ("ABC6_YA", (0.78451361047755726382, 0.23557321335935813368, -1.1776799841788710069,
                 1.3151863206839112189), 6, _YOSHIDA + " (solution A)"),
    ("s9ABC6", (0.39216144400731413927925056, 0.33259913678935943859974864,
                -0.70624617255763935980996482, 0.08221359629355080023149045,
                0.79854399093482996339895035), 6, _KL + " (s9odr6a)"),
    ("s11ABC6", (0.21375583945878254555518066964857, 0.18329381407425713911385974425217,
                 0.17692819473098943794898811709929, -0.44329082681170215849622829626258,
                 0.11728560432865935385403585669136, 0.50405474843802736404832781714239),
     6, _SS05 + " (s11odr6)"),
    ("s13ABC6", (0.13861930854051695245808013042625, 0.13346562851074760407046858832209,
                 0.13070531011449225190542755785015, 0.12961893756907034772505366537091,
                 -0.35000324893920896516170830911323, 0.11805530653002387170273438954049,
                 0.39907751534871587459988795520665), 6, _SS05 + " (s13odr6)"),
    ("s15ABC8", (0.74167036435061295344822780, -0.40910082580003159399730010,
                 0.19075471029623837995387626, -0.57386247111608226665638773,
                 0.29906418130365592384446354, 0.33462491824529818378495798,
                 0.31529309239676659663205666, -0.79688793935291635401978884), 8,
     "McLachlan, SIAM J. Sci. Comput. 16, 151 (1995) (s15odr8)"),
    ("s17ABC8", (0.13020248308889008087881763, 0.56116298177510838456196441,
                 -0.38947496264484728640807860, 0.15884190655515560089621075,
                 -0.39590389413323757733623154, 0.18453964097831570709183254,
                 0.25837438768632204729397911, 0.29501172360931029887096624,
                 -0.60550853383003451169892108), 8, _KL + " (s17odr8a)"),
    ("s21ABC8", (0.10647728984550031823931967854896, 0.10837408645835726397433410591546,
                 0.35337821052654342419534541324080, -0.23341414023165082198780281128319,
                 -0.24445266791528841269462171413216, 0.11317848435755633314700952515599,
                 0.11892905625000350062692972283951, 0.12603912321825988140305670268365,
                 0.12581718736176041804392391641587, 0.11699135019217642180722881433533,
                 -0.38263596012643665350944670744040), 8, _SS05 + " (s21odr8)"),
]
for _name, _half, _order, _ref in _ABC:
    register_scheme(CompositionScheme(_name, 3, _half, _order, _ref))
