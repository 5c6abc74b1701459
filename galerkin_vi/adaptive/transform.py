r"""Time-adaptive steps that stay symplectic: the Poincaré time transformation.

A fixed step in physical time is as small as the fastest part of an orbit
needs (the pericentre of an eccentric orbit, a close encounter). Variable steps
break the symplecticity of the map, and with it the bounded energy error. The
Poincaré transformation keeps both: for an autonomous :math:`H(q, p)` and a
step-size function :math:`g(q) > 0`, the Hamiltonian

.. math::

    K(q, p) = g(q)\,\big(H(q, p) - E\big), \qquad E = H(q_0, p_0),

has, on its level set :math:`K = 0`, the same orbits as :math:`H`, traversed in
a fictitious time :math:`\tau` with :math:`dt/d\tau = g(q)`. A symplectic method
with fixed steps :math:`\Delta\tau` applied to :math:`K` is a symplectic method
for :math:`H` with physical steps :math:`\approx g(q)\,\Delta\tau`, and :math:`K`,
hence :math:`H - E` where :math:`g` is bounded away from 0, stays bounded.

On the Lagrangian side (:math:`w = dq/d\tau`, so :math:`v = w/g`), the Legendre
transform of :math:`K` is

.. math::

    \tilde L(q, w) = g(q)\,\big[L(q, w/g(q)) + E\big],
    \qquad \frac{\partial \tilde L}{\partial w} = L_v = p,

so the momenta are the physical ones. Physical time is a further coordinate
:math:`z`, the clock, with

.. math::

    \hat L(q, z, w, \zeta) = \tilde L(q, w) + \tfrac{c}{2}\,(\zeta - g(q))^2 .

:math:`z` is cyclic, so its momentum :math:`p_z = c\,(\zeta - g)` is a Noether
momentum, which the Galerkin integrator conserves to round-off; it starts at 0,
so :math:`z' = g` and :math:`z = t` (with Gauss quadrature of :math:`s` points
the discrete equations of :math:`z` give :math:`\zeta = g` at every quadrature
point, and :math:`z_{k+1} - z_k = \Delta\tau \sum_i b_i g(q(\tau_k + c_i \Delta\tau))`).
The extended system is generated and compiled like any other: the general loop
runs it, one coordinate larger.

The clock's weight :math:`c > 0` leaves the solution unchanged (:math:`\zeta = g`
at every quadrature point makes the clock term's force
:math:`-c\,(\zeta - g)\,g_q` on q vanish) but not the conditioning of the stage
equations: its Hessian adds :math:`c\, g_q g_q^T` to the q block of the
Jacobian, beside the kinetic block :math:`M/g`. With :math:`c = 1` and light
bodies (the outer solar system: masses down to :math:`10^{-8}` of the Sun's),
that rank-one term swamps the kinetic block, LU loses the light bodies' digits
and the first step does not converge at any step size; the Schur complement of
the clock removes the term exactly, so it is pure round-off. The run sets
:math:`c = g(q_0)\,\min_a M_{aa}(q_0)` (:func:`clock_weight`): proportional to the
lightest mass, so that the term stays below every kinetic block, and among the
scalings tried (:math:`1`, :math:`\min M_{aa}`, :math:`\min M_{aa}/g(q_0)`,
:math:`g(q_0) \min M_{aa}`) the one whose rounding is smallest: on Kepler
e = 0.9 (start at pericentre, Gauss(2)-(4), three periods) the final momenta agree with
a hand-written Gauss kernel on the transformed Hamiltonian to 3e-15 .. 4e-13,
against 3e-13 .. 1e-12 for :math:`c = 1` and 2e-12 .. 1e-11 for
:math:`\min M_{aa}/g(q_0)` (``docs/design-notes.md``, "Adaptive steps: the fixed point
and its chunks").

References: Hairer, Lubich & Wanner, *Geometric Numerical Integration*, 2nd ed.,
Springer 2006, section VIII.2; Hairer, "Variable time step integration with
symplectic methods", Appl. Numer. Math. 25 (1997).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..model.system import LagrangianSystem

__all__ = [
    "CLOCK",
    "CLOCK_RATE",
    "CLOCK_WEIGHT",
    "ENERGY",
    "PoincareTransform",
    "clock_weight",
    "encounter_scaling",
]

#: the extended system's own symbols; names no user model is likely to use
CLOCK = sp.Symbol("t_clock")
CLOCK_RATE = sp.Symbol("t_clock_rate")
ENERGY = sp.Symbol("E_poincare")
CLOCK_WEIGHT = sp.Symbol("c_clock_weight")


def encounter_scaling(distances: Sequence[sp.Expr], alpha: float = 1.5) -> sp.Expr:
    r"""A step-size function for close encounters: :math:`g = (\sum_j d_j^{-\alpha})^{-1}`.

    For one distance this is :math:`d^\alpha`; for several it is at most the
    smallest :math:`d_j^\alpha` and close to it when one distance is much smaller
    than the others, and smooth (a minimum is not). :math:`\alpha = 3/2` matches
    the time scale of a Kepler orbit at distance :math:`d` (Kepler's third law:
    steps of equal fictitious time are about equal fractions of the local
    orbital period); :math:`\alpha = 1` is Sundman's transformation.

    Parameters
    ----------
    distances : sequence of sympy.Expr
        Positive expressions in q, e.g. ``sp.sqrt(x**2 + y**2)``.
    alpha : float
        Positive exponent.
    """
    if isinstance(distances, sp.Expr):
        distances = [distances]
    distances = list(distances)
    if not distances:
        raise ValueError("distances must contain at least one expression")
    if not (isinstance(alpha, numbers.Real) and math.isfinite(alpha) and alpha > 0):
        raise ValueError(f"alpha must be a positive real number, got {alpha!r}")
    a = sp.nsimplify(alpha)
    if len(distances) == 1:
        return sp.sympify(distances[0]) ** a
    return 1 / sum(sp.sympify(d) ** (-a) for d in distances)


@dataclass(frozen=True)
class PoincareTransform:
    r"""The extended Lagrangian :math:`\hat L` of a system and a step-size function.

    Parameters
    ----------
    system : LagrangianSystem
        An autonomous system without constraints or forces.
    g : sympy.Expr
        The step-size function :math:`g(q) > 0` (physical time per unit of
        fictitious time), an expression in the system's q and parameters.

    Attributes
    ----------
    extended : LagrangianSystem
        :math:`\hat L` in coordinates ``(*system.q, t_clock)``, parameters
        ``(*system.params, E_poincare, c_clock_weight)``.
    """

    system: LagrangianSystem
    g: sp.Expr
    extended: LagrangianSystem = field(init=False, repr=False)

    def __post_init__(self) -> None:
        system, g = self.system, self.g
        if not isinstance(system, LagrangianSystem):
            raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
        if system.t is not None:
            raise ValueError(
                "the Poincaré time transformation needs an autonomous system (t=None): "
                "with time in L the energy E of K = g (H - E) is not conserved"
            )
        if system.constraints is not None or system.forces is not None:
            raise ValueError(
                "the Poincaré time transformation is implemented for systems without "
                "constraints or forces"
            )
        if system.contacts:
            raise ValueError(
                "the Poincaré time transformation keeps the energy E of K = g (H - E) "
                "fixed, and an impact with restitution e < 1 or friction changes H: "
                "integrate a system with contacts with Integrator (fixed steps, impacts "
                "located at the method's order)"
            )
        if isinstance(g, numbers.Real):
            g = sp.sympify(g)
        if not isinstance(g, sp.Expr):
            raise TypeError(f"g must be a SymPy expression in q, got {type(g).__name__}")
        allowed = set(system.q) | set(system.params)
        stray = g.free_symbols - allowed
        if stray:
            names = ", ".join(sorted(str(s) for s in stray))
            raise ValueError(f"g may depend on q and the parameters only; it contains {names}")
        own = {CLOCK, CLOCK_RATE, ENERGY, CLOCK_WEIGHT}
        taken = own & (set(system.q) | set(system.v) | set(system.params))
        if taken:
            raise ValueError(f"the system uses the reserved symbols {sorted(map(str, taken))}")
        w = system.v
        L_tilde = g * (system.L.xreplace({v: v / g for v in w}) + ENERGY)
        L_hat = L_tilde + CLOCK_WEIGHT * (CLOCK_RATE - g) ** 2 / 2
        params = dict(zip(system.params, system.param_defaults, strict=True))
        params[ENERGY] = 0.0
        params[CLOCK_WEIGHT] = 1.0
        extended = LagrangianSystem(L_hat, [*system.q, CLOCK], [*w, CLOCK_RATE], params=params)
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "extended", extended)

    def __getstate__(self) -> dict:
        # the lambdified g is rebuilt on first use after unpickling: generated functions
        # do not pickle
        state = dict(self.__dict__)
        state.pop("_g_numeric", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    @cached_property
    def _g_numeric(self):
        return sp.lambdify([self.system.q, self.system.params], self.g, modules="numpy")

    def rate(self, q: ArrayLike, params: NDArray | None = None) -> NDArray:
        """:math:`g(q)`, the physical time per unit of fictitious time (rows of q)."""
        q = np.asarray(q, dtype=float)
        prm = self.system.param_defaults if params is None else params
        value = self._g_numeric(np.moveaxis(q, -1, 0), prm)
        return np.broadcast_to(np.asarray(value, dtype=float), q.shape[:-1]).copy()


def clock_weight(
    system: LagrangianSystem, q0: NDArray, v0: NDArray, prm: NDArray, rate: float
) -> float:
    r"""The clock's weight :math:`c = g(q_0) \min_a M_{aa}(q_0, v_0)` (module docstring).

    Parameters
    ----------
    system : LagrangianSystem
        The physical system; :math:`M = L_{vv}`.
    q0, v0 : ndarray, shape (n,)
        The start of the run.
    prm : ndarray
        The system's parameter vector.
    rate : float
        :math:`g(q_0) > 0`.

    Returns
    -------
    float
        The smallest positive diagonal entry of :math:`L_{vv}` times ``rate``
        (``rate`` if none is positive and finite).
    """
    n = system.n
    mass = np.asarray(system.evaluate("Lvv", 0.0, q0, v0, prm), dtype=float).reshape(n, n)
    diagonal = np.diag(mass)
    usable = diagonal[np.isfinite(diagonal) & (diagonal > 0)]
    return float(usable.min() * rate) if usable.size else float(rate)
