r"""Symmetric compositions of Störmer–Verlet: explicit variational integrators of orders 2–10.

For a separable :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)` with constant
:math:`M`, Störmer–Verlet :math:`\Phi_h` is the degree-1 Lobatto Galerkin method
(:class:`~galerkin_vi.Galerkin` ``(1)``), explicit. The composition

.. math::

    \Psi_h = \Phi_{\gamma_m h} \circ \cdots \circ \Phi_{\gamma_1 h},
    \qquad \sum_i \gamma_i = 1,\quad \gamma_{m+1-i} = \gamma_i,

is again variational: its discrete Lagrangian is the sum of the sub-steps'
discrete Lagrangians with the inner positions eliminated by stationarity, so it
is symplectic, conserves the discrete Noether momenta of the symmetries of
:math:`L` exactly and keeps the energy bounded over exponentially long times.
It is symmetric (:math:`\Psi_{-h} = \Psi_h^{-1}`), so its order is even; it
has order :math:`p` when the :math:`\gamma_i` satisfy the order conditions of
[HLW06]_ §V.3: :math:`\sum\gamma_i^{2j+1} = 0` for :math:`1 \le j < p/2` among
them (order 4 needs only :math:`\sum\gamma_i^3 = 0`; orders 6–10 add conditions
that are not power sums).

Splitting methods generalise this. For :math:`H = T(p) + V(q)` with quadratic
:math:`T` (constant :math:`M`), the kick :math:`B_\beta: p \mapsto p + \beta h F(q)` and
the drift :math:`A_\alpha: q \mapsto q + \alpha h M^{-1}p` are exact flows, and

.. math::

    \Psi_h = B_{b_{m+1}} \circ A_{a_m} \circ B_{b_m} \circ \cdots \circ A_{a_1} \circ B_{b_1},
    \qquad \sum_i a_i = \sum_i b_i = 1,

palindromic in :math:`a` and in :math:`b`, is a composition of variational maps
(each :math:`B \circ A \circ B` is the map of the discrete Lagrangian
:math:`a h\,T((q_1 - q_0)/(a h)) - h(\beta^- V(q_0) + \beta^+ V(q_1))`), symmetric,
and takes :math:`m` force evaluations per step (the last kick's force is the next
step's first). A composition of Störmer–Verlet is the case :math:`a_i = \gamma_i`,
:math:`b_i = (\gamma_{i-1} + \gamma_i)/2`. Free kick coefficients satisfy more order
conditions per evaluation; the Runge–Kutta–Nyström splittings of [BM02]_ also use
that :math:`[B,[B,[B,A]]] = 0` for a quadratic :math:`T`, and reach errors 30–1000
times smaller than the compositions of Störmer–Verlet at an equal number of force
evaluations (benchmarks/composition_schemes.py). They need an exact drift: a
gyroscopic term :math:`a(t)\cdot v` that varies with :math:`t` (whose drift the
sub-step integrates by the trapezoidal rule) is refused for them, not for the
compositions of Störmer–Verlet.

Schemes (``scheme=`` per order; the first is the default):

==========  ========================  =============  ====================================
order       scheme                    stages         source
==========  ========================  =============  ====================================
2           ``"verlet"``              1              Störmer–Verlet itself
4           ``"blanes_moan"``         6              [BM02]_ SRKN6b, splitting
4           ``"suzuki"``              5              [Suz90]_, closed form
4           ``"yoshida"``             3              [Yos90]_ triple jump, closed form
6           ``"blanes_moan"``         11             [BM02]_ SRKN11b, splitting
6           ``"kahan_li"``            9              [KL97]_ s9odr6a, [HLW06]_ §V.3.2
6           ``"yoshida"``             7              [Yos90]_ solution A, [HLW06]_ §V.3.2
6, 8, 10    ``"triple_jump"``         9, 27, 81      [Yos90]_ recursive, closed form
8           ``"kahan_li"``            17             [KL97]_ s17odr8a, [HLW06]_ §V.3.2
8           ``"mclachlan"``           15             [McL95]_ s15odr8, [HLW06]_ §V.3.2
10          ``"sofroniou_spaletta"``  35             [SS05]_ s35odr10
==========  ========================  =============  ====================================

Tabulated coefficients carry the 26 digits their sources give; two independent
public transcriptions agree digit for digit (OrdinaryDiffEq.jl's symplectic
tableaus ``KahanLi6``, ``KahanLi8``, ``McAte8``, ``SofSpa10`` and a second Julia
code's composition table), and the coefficients satisfy the power-sum order
conditions to 1e-26 (tests). Closed forms are evaluated at 40 digits. Both are
rounded to double once. The splittings of [BM02]_ are published with 15 digits (the
free coefficients of its Table 3, transcribed identically by Principia's
``symplectic_runge_kutta_nyström_integrator.hpp`` and other public codes); the one
drift and the one kick that follow from :math:`\sum a_i = \sum b_i = 1` are computed
at 40 digits, so the order conditions hold to about 1e-15: below double round-off,
but in mpmath SRKN11b's errors follow :math:`h^6` only down to about 1e-18, where
the :math:`h^4` term of the rounded coefficients takes over.

References
----------
.. [Yos90] H. Yoshida, "Construction of higher order symplectic integrators",
   Phys. Lett. A 150 (1990) 262–268.
.. [Suz90] M. Suzuki, "Fractal decomposition of exponential operators with
   applications to many-body theories and Monte Carlo simulations",
   Phys. Lett. A 146 (1990) 319–323.
.. [KL97] W. Kahan, R.-C. Li, "Composition constants for raising the orders of
   unconventional schemes for ordinary differential equations",
   Math. Comp. 66 (1997) 1089–1099.
.. [McL95] R. I. McLachlan, "On the numerical integration of ordinary
   differential equations by symmetric composition methods",
   SIAM J. Sci. Comput. 16 (1995) 151–168.
.. [SS05] M. Sofroniou, G. Spaletta, "Derivation of symmetric composition
   constants for symmetric integrators", Optim. Methods Softw. 20 (2005) 597–613.
.. [BM02] S. Blanes, P. C. Moan, "Practical symplectic partitioned Runge–Kutta and
   Runge–Kutta–Nyström methods", J. Comput. Appl. Math. 142 (2002) 313–330, Table 3.
.. [HLW06] E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*,
   2nd ed., Springer 2006, §V.3.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import mpmath
import numpy as np
from numpy.typing import NDArray

__all__ = ["SCHEMES", "Composition", "CompositionScheme", "SubSteps", "VERLET_SUBSTEPS"]

_DIGITS = 40


@dataclass(frozen=True)
class CompositionScheme:
    """One published composition: the first half of its palindromic coefficients
    (the middle one included) as decimal strings, or a closed form, and its source.

    A splitting (``kicks`` given) lists instead the free first-half coefficients of
    its drifts (``half``) and of its kicks (``kicks``); the one coefficient of each
    that completes the palindrome follows from their sum being 1.
    """

    order: int
    stages: int
    half: tuple[str, ...] | None
    reference: str
    kicks: tuple[str, ...] | None = None

    @property
    def splitting(self) -> bool:
        """Whether the kicks are free (not those of a composition of Störmer–Verlet)."""
        return self.kicks is not None


_YOSHIDA = "H. Yoshida, Phys. Lett. A 150 (1990) 262-268"
_SUZUKI = "M. Suzuki, Phys. Lett. A 146 (1990) 319-323"
_KAHAN_LI = "W. Kahan, R.-C. Li, Math. Comp. 66 (1997) 1089-1099"
_MCLACHLAN = "R. I. McLachlan, SIAM J. Sci. Comput. 16 (1995) 151-168"
_SOFSPA = "M. Sofroniou, G. Spaletta, Optim. Methods Softw. 20 (2005) 597-613"
_HLW = "; E. Hairer, C. Lubich, G. Wanner, Geometric Numerical Integration (2006) V.3.2"
_BLANES_MOAN = "S. Blanes, P. C. Moan, J. Comput. Appl. Math. 142 (2002) 313-330, Table 3"

#: every scheme by (order, name); ``half`` None: a closed form (:func:`_closed_form`)
SCHEMES: dict[tuple[int, str], CompositionScheme] = {
    (2, "verlet"): CompositionScheme(2, 1, ("1",), "Stormer-Verlet (one stage)"),
    (4, "yoshida"): CompositionScheme(4, 3, None, _YOSHIDA + ", triple jump"),
    (4, "suzuki"): CompositionScheme(4, 5, None, _SUZUKI),
    (4, "blanes_moan"): CompositionScheme(
        4, 6,
        ("0.245298957184271", "0.604872665711080"),
        _BLANES_MOAN + ", SRKN6b",
        kicks=("0.0829844064174052", "0.396309801498368", "-0.0390563049223486"),
    ),
    (6, "blanes_moan"): CompositionScheme(
        6, 11,
        (
            "0.123229775946271", "0.290553797799558", "-0.127049212625417",
            "-0.246331761062075", "0.357208872795928",
        ),
        _BLANES_MOAN + ", SRKN11b",
        kicks=(
            "0.0414649985182624", "0.198128671918067", "-0.0400061921041533",
            "0.0752539843015807", "-0.0115113874206879",
        ),
    ),
    (6, "kahan_li"): CompositionScheme(
        6, 9,
        (
            "0.39216144400731413927925056", "0.33259913678935943859974864",
            "-0.70624617255763935980996482", "0.08221359629355080023149045",
            "0.79854399093482996339895035",
        ),
        _KAHAN_LI + ", s9odr6a" + _HLW,
    ),
    (6, "yoshida"): CompositionScheme(
        6, 7,
        (
            "0.78451361047755726381949763", "0.23557321335935813368479318",
            "-1.17767998417887100694641568", "1.31518632068391121888424973",
        ),
        _YOSHIDA + ", solution A" + _HLW,
    ),
    (6, "triple_jump"): CompositionScheme(6, 9, None, _YOSHIDA + ", recursive triple jump"),
    (8, "kahan_li"): CompositionScheme(
        8, 17,
        (
            "0.13020248308889008087881763", "0.56116298177510838456196441",
            "-0.38947496264484728640807860", "0.15884190655515560089621075",
            "-0.39590389413323757733623154", "0.18453964097831570709183254",
            "0.25837438768632204729397911", "0.29501172360931029887096624",
            "-0.60550853383003451169892108",
        ),
        _KAHAN_LI + ", s17odr8a" + _HLW,
    ),
    (8, "mclachlan"): CompositionScheme(
        8, 15,
        (
            "0.74167036435061295344822780", "-0.40910082580003159399730010",
            "0.19075471029623837995387626", "-0.57386247111608226665638773",
            "0.29906418130365592384446354", "0.33462491824529818378495798",
            "0.31529309239676659663205666", "-0.79688793935291635401978884",
        ),
        _MCLACHLAN + ", s15odr8" + _HLW,
    ),
    (8, "triple_jump"): CompositionScheme(8, 27, None, _YOSHIDA + ", recursive triple jump"),
    (10, "sofroniou_spaletta"): CompositionScheme(
        10, 35,
        (
            "0.07879572252168641926390768", "0.31309610341510852776481247",
            "0.02791838323507806610952027", "-0.22959284159390709415121340",
            "0.13096206107716486317465686", "-0.26973340565451071434460973",
            "0.07497334315589143566613711", "0.11199342399981020488957508",
            "0.36613344954622675119314812", "-0.39910563013603589787862981",
            "0.10308739852747107731580277", "0.41143087395589023782070412",
            "-0.00486636058313526176219566", "-0.39203335370863990644808194",
            "0.05194250296244964703718290", "0.05066509075992449633587434",
            "0.04967437063972987905456880", "0.04931773575959453791768001",
        ),
        _SOFSPA + ", s35odr10",
    ),
    (10, "triple_jump"): CompositionScheme(10, 81, None, _YOSHIDA + ", recursive triple jump"),
}  # fmt: skip

#: the scheme ``Composition(order)`` takes: of each order's schemes, the one with the
#: smallest error at an equal number of force evaluations on Kepler and Henon-Heiles
#: (benchmarks/composition_schemes.py)
DEFAULT_SCHEMES = {
    2: "verlet",
    4: "blanes_moan",
    6: "blanes_moan",
    8: "kahan_li",
    10: "sofroniou_spaletta",
}

#: of each order's compositions of Störmer–Verlet (kicks not free), the one with the
#: smallest error per force evaluation: the choice where a splitting is refused
VERLET_SCHEMES = {
    2: "verlet",
    4: "suzuki",
    6: "kahan_li",
    8: "kahan_li",
    10: "sofroniou_spaletta",
}


def _triple_jump(order: int) -> list:
    r"""Yoshida's recursion: :math:`\Psi^{[p+2]}_h = \Psi^{[p]}_{x_1 h}\circ\Psi^{[p]}_{x_0 h}
    \circ\Psi^{[p]}_{x_1 h}` with :math:`x_1 = 1/(2 - 2^{1/(p+1)})`, :math:`x_0 = 1 - 2x_1`."""
    gamma = [mpmath.mpf(1)]
    for p in range(2, order, 2):
        root = mpmath.mpf(2) ** (mpmath.mpf(1) / (p + 1))
        x1 = 1 / (2 - root)
        x0 = -root * x1
        gamma = [x1 * g for g in gamma] + [x0 * g for g in gamma] + [x1 * g for g in gamma]
    return gamma


def _suzuki() -> list:
    r"""Suzuki's fractal: :math:`\gamma_{1,2,4,5} = 1/(4 - 4^{1/3})`,
    :math:`\gamma_3 = 1 - 4\gamma_1`."""
    g = 1 / (4 - mpmath.cbrt(4))
    return [g, g, 1 - 4 * g, g, g]


def _closed_form(order: int, name: str) -> list:
    if name == "suzuki":
        return _suzuki()
    return _triple_jump(order)


def _palindrome(free: tuple[str, ...], count: int) -> list:
    """The ``count`` palindromic coefficients summing to 1 whose first half starts with
    ``free``; the one after them (the middle one when ``count`` is odd) takes the rest."""
    head = [mpmath.mpf(x) for x in free]
    if count % 2:
        return head + [1 - 2 * mpmath.fsum(head)] + head[::-1]
    head.append(mpmath.mpf(1) / 2 - mpmath.fsum(head))
    return head + head[::-1]


def exact_coefficients(order: int, name: str, digits: int = _DIGITS) -> tuple:
    r"""The scheme's drifts :math:`a_i` (a composition of Störmer–Verlet: its
    :math:`\gamma_i`) as mpmath numbers at ``digits`` digits (a tabulated scheme is
    exact to its published digits only)."""
    return exact_splitting(order, name, digits)[0]


@lru_cache(maxsize=32)
def exact_splitting(order: int, name: str, digits: int = _DIGITS) -> tuple[tuple, tuple]:
    r"""The scheme's drifts :math:`(a_1, \dots, a_m)` and kicks :math:`(b_1, \dots, b_{m+1})`
    as mpmath numbers at ``digits`` digits (module docstring). A composition of
    Störmer–Verlet has :math:`a_i = \gamma_i` and :math:`b_i = (\gamma_{i-1} + \gamma_i)/2`
    (:math:`\gamma_0 = \gamma_{m+1} = 0`)."""
    scheme = SCHEMES[(order, name)]
    with mpmath.workdps(digits):
        if scheme.splitting:
            return (
                tuple(_palindrome(scheme.half, scheme.stages)),
                tuple(_palindrome(scheme.kicks, scheme.stages + 1)),
            )
        if scheme.half is None:
            gamma = list(_closed_form(order, name))
        else:
            half = [mpmath.mpf(x) for x in scheme.half]
            gamma = half + half[-2::-1]
        padded = [mpmath.mpf(0), *gamma, mpmath.mpf(0)]
        kicks = [(padded[i] + padded[i + 1]) / 2 for i in range(len(gamma) + 1)]
        return tuple(gamma), tuple(kicks)


class Composition:
    r"""A symmetric composition of Störmer–Verlet, or splitting, of order 2–10 (module
    docstring).

    Parameters
    ----------
    order : int
        2, 4, 6, 8 or 10.
    scheme : str, optional
        Which published coefficients (the module's table); default the order's
        :data:`DEFAULT_SCHEMES` entry (the splittings of Blanes and Moan for orders 4
        and 6, which refuse a gyroscopic term varying with time:
        :data:`VERLET_SCHEMES` lists the compositions of Störmer–Verlet that take it).

    Attributes
    ----------
    order : int
        The order p of the composition.
    scheme : str
        The scheme's name; :attr:`stages` (the number :math:`m` of drifts, one force
        evaluation each), :attr:`reference` (its source), :attr:`splitting`,
        :attr:`coefficients` (the drifts :math:`a_i`, for a composition of
        Störmer–Verlet its :math:`\gamma_i`), :attr:`kicks` (the :math:`b_i`) and
        :attr:`nodes` follow from it.

    Notes
    -----
    Runs take the ``"explicit"`` loop (:mod:`galerkin_vi.loops.explicit`) and need a
    separable Lagrangian with constant mass matrix and no constraints, contacts
    or velocity-dependent forces. The dense output is the Hermite interpolant of
    :mod:`galerkin_vi.run.dense` through :math:`\lfloor p/2\rfloor + 1` nodes, of
    the method's order :math:`p` in positions and velocities.

    Examples
    --------
    >>> from galerkin_vi import Composition
    >>> Composition(8).stages
    17
    >>> float(Composition(4, "suzuki").coefficients.sum())
    1.0
    >>> Composition(6).scheme, Composition(6).stages, len(Composition(6).kicks)
    ('blanes_moan', 11, 12)
    """

    def __init__(self, order: int, scheme: str | None = None) -> None:
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
            raise TypeError(f"order must be an int, got {type(order).__name__}")
        order = int(order)
        if order not in DEFAULT_SCHEMES:
            raise ValueError(f"order must be one of {sorted(DEFAULT_SCHEMES)}, got {order}")
        scheme = DEFAULT_SCHEMES[order] if scheme is None else scheme
        if not isinstance(scheme, str):
            raise TypeError(f"scheme must be a str, got {type(scheme).__name__}")
        if (order, scheme) not in SCHEMES:
            names = sorted(name for p, name in SCHEMES if p == order)
            raise ValueError(f"scheme for order {order} must be one of {names}, got {scheme!r}")
        self.order = order
        self.scheme = scheme

    @property
    def stages(self) -> int:
        """Drifts per step (force evaluations per step)."""
        return SCHEMES[(self.order, self.scheme)].stages

    @property
    def reference(self) -> str:
        """The source of the coefficients."""
        return SCHEMES[(self.order, self.scheme)].reference

    @property
    def splitting(self) -> bool:
        """Whether the kicks are free coefficients (a splitting), not those of a
        composition of Störmer–Verlet steps."""
        return SCHEMES[(self.order, self.scheme)].splitting

    @property
    def coefficients(self) -> NDArray[np.float64]:
        r"""The drifts :math:`a_i` (a composition of Störmer–Verlet: its :math:`\gamma_i`),
        each rounded once from 40 digits (a new array per call)."""
        return _rounded(self.order, self.scheme).drift.copy()

    @property
    def kicks(self) -> NDArray[np.float64]:
        r"""The kicks :math:`b_1, \dots, b_{m+1}`, each rounded once from 40 digits."""
        return _rounded(self.order, self.scheme).kicks.copy()

    @property
    def nodes(self) -> NDArray[np.float64]:
        r"""The drifts' ends :math:`c_i = \sum_{j \le i} a_j` (summed at 40 digits, rounded
        once; the last is exactly 1)."""
        return _rounded(self.order, self.scheme).nodes.copy()

    def substeps(self) -> SubSteps:
        """The explicit loop's tables (:class:`SubSteps`, read-only arrays)."""
        return _rounded(self.order, self.scheme)

    def __repr__(self) -> str:
        return f"Composition(order={self.order}, scheme={self.scheme!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Composition):
            return NotImplemented
        return (self.order, self.scheme) == (other.order, other.scheme)

    def __hash__(self) -> int:
        return hash(("Composition", self.order, self.scheme))


class SubSteps(NamedTuple):
    r"""A step as the explicit loop takes it: :math:`m` sub-steps, each a kick, a drift
    and a kick,

    .. math::

        \bar p = p + \beta^-_i h F(\tau_{i-1}, q),\quad q' = q + a_i h M^{-1}\bar p,\quad
        p' = \bar p + \beta^+_i h F(\tau_i, q'),

    with :math:`\tau_i = t_k + c_i h`. Consecutive kicks add up to the scheme's:
    :math:`\beta^-_1 = b_1`, :math:`\beta^+_i + \beta^-_{i+1} = b_{i+1}`,
    :math:`\beta^+_m = b_{m+1}`. A composition of Störmer–Verlet splits each kick
    evenly (:math:`\beta^\pm_i = \gamma_i/2`, its own sub-steps); a splitting puts each
    whole kick after the drift before it (:math:`\beta^-_i = 0` for :math:`i > 1`).
    """

    drift: NDArray[np.float64]
    kick_before: NDArray[np.float64]
    kick_after: NDArray[np.float64]
    nodes: NDArray[np.float64]
    kicks: NDArray[np.float64]

    @property
    def loop_tables(self) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """``(drift, kick_before, kick_after, nodes)`` in the loops' argument order."""
        return self.drift, self.kick_before, self.kick_after, self.nodes


@lru_cache(maxsize=32)
def _rounded(order: int, name: str) -> SubSteps:
    drifts, kicks = exact_splitting(order, name)
    with mpmath.workdps(_DIGITS):
        ends = [mpmath.fsum(drifts[: i + 1]) for i in range(len(drifts))]
    drift = np.array([float(a) for a in drifts])
    kick = np.array([float(b) for b in kicks])
    nodes = np.array([float(c) for c in ends])
    nodes[-1] = 1.0
    if SCHEMES[(order, name)].splitting:
        before = np.zeros_like(drift)
        before[0] = kick[0]
        after = kick[1:].copy()
    else:
        before = np.array([float(a / 2) for a in drifts])
        after = before.copy()
    tables = SubSteps(drift, before, after, nodes, kick)
    for array in tables:
        array.setflags(write=False)
    return tables


#: Störmer–Verlet, ``Galerkin(1)``: one sub-step, the kick split evenly
VERLET_SUBSTEPS = _rounded(2, "verlet")
