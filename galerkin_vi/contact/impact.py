r"""The impact law: the momentum jump of an impact with restitution and Coulomb friction.

At an impact of contact j at :math:`(t, q)` the positions stay and the
momentum jumps by the impulse along the contact's directions,

.. math::

    p^+ = p^- + \Lambda_n \nabla\varphi(q) + T(q)^{\mathsf T}\Lambda_t,
    \qquad L_v(t, q, v^\pm) = p^\pm,

with :math:`T = \partial w/\partial v` the rows of the slip velocities
:math:`w = T v + w_0`. Newton's law fixes the normal part,
:math:`u^+ = -e\,u^-` with :math:`u = \nabla\varphi\cdot v`; Coulomb's law the
tangential part: the contact **sticks** (:math:`w^+ = 0`) when the impulse
that stops the slip lies in the cone :math:`\|\Lambda_t\| \le \mu\Lambda_n`, and
otherwise **slides** with :math:`\Lambda_t = -\mu\Lambda_n\, w^+/\|w^+\|`, the
impulse of maximum dissipation (the direction of the post-impact slip is
found by fixed-point iteration, exact in the plane).

The unknowns :math:`(v^+, \Lambda)` solve these equations by Newton's method
with the exact Jacobian :math:`\begin{pmatrix} L_{vv} & -G^{\mathsf T} \\ G & 0
\end{pmatrix}`; for L quadratic in v one iteration is exact. Without friction
and with e = 1 the energy :math:`H(q, p)` is the same before and after (the
velocity is reflected in the metric :math:`L_{vv}`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import NDArray

__all__ = [
    "ContactFunctions",
    "Impact",
    "impulse",
    "inverse_impulse",
    "irreversible_contacts",
    "simultaneous_impulse",
    "stop_slip",
]

_NEWTON_ITERATIONS = 30
#: sweeps of a simultaneous impact's Gauss-Seidel at most
SWEEPS = 500
#: the largest change of an impulse in a sweep, relative to the largest impulse, at
#: which a simultaneous impact is settled
SETTLED = 1e-13
#: the change relative to the impulses' size below which a simultaneous impact's
#: sticking contacts are solved at once (:func:`_polished`)
POLISH = 1e-6
#: normal speeds below this, relative to the velocities' size, are round-off: no impact
GRAZING = 1e-13
_DIRECTION_SWEEPS = 3


@dataclass(frozen=True)
class Impact:
    """One impact of a run.

    Attributes
    ----------
    t : float
        Its time.
    contact : int
        The index of the contact in ``system.contacts``.
    normal_impulse : float
        :math:`\\Lambda_n \\ge 0`.
    tangential_impulse : ndarray, shape (k,)
        :math:`\\Lambda_t` (empty without friction).
    mode : str
        ``"frictionless"``, ``"stick"`` or ``"slide"``.
    normal_velocity : tuple of float
        :math:`(u^-, u^+)`.
    energy_lost : float
        :math:`H(q, p^-) - H(q, p^+)`.
    """

    t: float
    contact: int
    normal_impulse: float
    tangential_impulse: NDArray[np.float64]
    mode: str
    normal_velocity: tuple[float, float]
    energy_lost: float


class ContactFunctions:
    r"""Numeric gaps, their derivatives and the slips of a system's contacts (from SymPy, exact).

    One lambdified function per kind for all contacts at once, each taking
    ``(t, *q, *v, *params)``: the gaps (contacts,), gradients (contacts, n),
    Hessians (contacts, n, n), and for the frictional contacts the slip
    velocities :math:`w = T v + w_0` stacked (rows, see :attr:`slip_rows`) with
    :math:`\partial w/\partial q`, :math:`T = \partial w/\partial v` and
    :math:`\partial^2 w/\partial v\,\partial q`. The impact law uses them at
    one state, the time-stepping at every quadrature point.
    """

    def __init__(self, system) -> None:
        t = system.t if system.t is not None else sp.Dummy("t")
        args = (t, *system.q, *system.v, *system.params)
        q, v = system.q, system.v
        gaps = [c.gap for c in system.contacts]
        self.system = system
        self.gaps = sp.lambdify(args, gaps, "numpy")
        self.gradients = sp.lambdify(args, [[sp.diff(g, a) for a in q] for g in gaps], "numpy")
        self.hessians = sp.lambdify(
            args, [[[sp.diff(g, a, b) for b in q] for a in q] for g in gaps], "numpy"
        )
        slips: list = []
        #: each contact's rows among the stacked slips (None without friction)
        self.slip_rows: list[slice | None] = []
        for contact in system.contacts:
            if contact.friction > 0.0:
                self.slip_rows.append(slice(len(slips), len(slips) + len(contact.slip)))
                slips += list(contact.slip)
            else:
                self.slip_rows.append(None)
        self.slips = None
        if slips:
            self.slips = tuple(
                sp.lambdify(args, e, "numpy")
                for e in (
                    slips,
                    [[sp.diff(w, a) for a in q] for w in slips],
                    [[sp.diff(w, a) for a in v] for w in slips],
                    [[[sp.diff(w, b, a) for a in q] for b in v] for w in slips],
                )
            )

    def at(self, f, t: float, q, v, prm) -> NDArray[np.float64]:
        """``f`` (one of the functions above) at one state."""
        return np.asarray(f(t, *q, *v, *prm), dtype=float)

    def gap(self, j: int, t: float, q, prm) -> float:
        return float(self.at(self.gaps, t, q, np.zeros_like(q), prm)[j])

    def gaps_at(self, j: int, t: NDArray, q: NDArray, prm) -> NDArray[np.float64]:
        """The gap of contact j at rows ``q`` (m, n) and times ``t`` (m,)."""
        out = self.gaps(t, *q.T, *np.zeros_like(q).T, *prm)[j]
        return np.broadcast_to(np.asarray(out, dtype=float), t.shape)

    def gradient(self, j: int, t: float, q, prm) -> NDArray[np.float64]:
        return self.at(self.gradients, t, q, np.zeros_like(q), prm)[j]

    def slip_matrix(self, j: int, t: float, q, prm):
        """(T, w0) of contact j's slips :math:`w = T v + w_0`, or None without friction."""
        rows = self.slip_rows[j]
        if rows is None:
            return None
        zero = np.zeros_like(q)
        T = self.at(self.slips[2], t, q, zero, prm)[rows]
        return T, self.at(self.slips[0], t, q, zero, prm)[rows]


def impulse(
    system, functions: ContactFunctions, j: int, t: float, q, p, prm, target: float | None = None
) -> tuple:
    """The momentum after an impact of contact ``j`` at ``(t, q)`` with momentum ``p``.

    Returns ``(p_plus, impact)`` with ``impact`` an :class:`Impact`. ``target`` is the
    normal velocity after the impact, :math:`-e\\,u^-` unless given (the law of a
    simultaneous impact, :func:`simultaneous_impulse`, sets it from the velocity
    before the whole impact).

    Raises
    ------
    ValueError
        When the contact is not approaching (:math:`u^- \\ge 0`, or not below
        ``target``): no impact.
    """
    contact = system.contacts[j]
    params = dict(zip(system.params, prm, strict=True))
    q, p = np.asarray(q, dtype=float), np.asarray(p, dtype=float)
    v_minus = system.inverse_legendre(q, p, t, params)
    g = functions.gradient(j, t, q, prm)
    u_minus = float(g @ v_minus)
    if not u_minus < (0.0 if target is None else target):
        raise ValueError(f"contact {j} at t = {t}: not approaching (normal velocity {u_minus})")
    goal = -contact.restitution * u_minus if target is None else target
    slip = functions.slip_matrix(j, t, q, prm)
    if slip is None:
        D, targets = _with_constraints(system, t, q, prm, g[None], [goal])
        v_plus, lam = _solve(system, t, q, p, v_minus, prm, D, D, targets)
        mode, tangential = "frictionless", np.zeros(0)
        p_plus = p + D.T @ lam
    else:
        rows, w0 = slip
        k = 1 + rows.shape[0]
        # sticking: the slip stopped as well
        G, targets = _with_constraints(system, t, q, prm, np.vstack([g, rows]), [goal, *(-w0)])
        v_plus, lam = _solve(system, t, q, p, v_minus, prm, G, G, targets)
        if np.linalg.norm(lam[1:k]) <= contact.friction * lam[0]:
            mode, tangential = "stick", lam[1:k]
            p_plus = p + G.T @ lam
        else:
            mode = "slide"
            v_plus, normal, tangential, reaction = _sliding(
                system, t, q, p, v_minus, prm, g, rows, w0, goal, contact.friction, lam[1:k]
            )
            p_plus = p + normal * g + rows.T @ tangential + reaction
            lam = np.array([normal])
    H = system.hamiltonian(np.vstack([q, q]), np.vstack([p, p_plus]), t, params)
    impact = Impact(
        t=float(t),
        contact=j,
        normal_impulse=float(lam[0]),
        tangential_impulse=np.asarray(tangential, dtype=float),
        mode=mode,
        normal_velocity=(u_minus, float(g @ v_plus)),
        energy_lost=float(H[0] - H[1]),
    )
    return p_plus, impact


def simultaneous_impulse(
    system, functions: ContactFunctions, hit: list[int], t: float, q, p, prm
) -> tuple:
    r"""The momentum after contacts ``hit`` are hit at once at ``(t, q)`` (a face landing flat).

    Newton's law for contacts hit together, in complementarity form: with
    :math:`u_j^-` the normal velocities before the impact,

    .. math::

        0 \le \Lambda_{n,j} \perp u_j^+ + e_j u_j^- \ge 0,

    each contact's friction as in :func:`impulse`. Several contacts' laws applied one
    after another would turn a body landing flat; here each contact's law is solved in
    turn with the others' impulses held, its own taken back first, and the sweeps go on
    until no impulse changes (Moreau's nonsmooth Gauss–Seidel; for frictionless
    contacts it minimises the kinetic energy after the impact over the admissible
    velocities, whose minimiser is unique although a face's corner impulses are not).
    The sweeps converge linearly, slowly on a stack's redundant faces; once they
    change the impulses by less than POLISH of their size with every contact that
    takes one sticking, the velocity after is solved at once from those contacts'
    equations (:func:`_polished`), and the records keep the sweeps' impulses.

    Returns ``(p_plus, impacts)``: the :class:`Impact` of each contact that takes an
    impulse, the energy lost by the whole impact listed at the first (none when the
    contacts approach at round-off, below GRAZING).

    Raises
    ------
    ConvergenceError
        When the sweeps do not settle in SWEEPS.
    """
    from ..errors import ConvergenceError

    params = dict(zip(system.params, prm, strict=True))
    q, p = np.asarray(q, dtype=float), np.asarray(p, dtype=float)
    p_minus = p.copy()
    v_minus = system.inverse_legendre(q, p, t, params)
    normals = {j: functions.gradient(j, t, q, prm) for j in hit}
    u_minus = {j: float(normals[j] @ v_minus) for j in hit}
    goals = {j: -system.contacts[j].restitution * min(u_minus[j], 0.0) for j in hit}
    if max(-u for u in u_minus.values()) <= GRAZING * max(1.0, float(np.abs(v_minus).max())):
        return p, []  # approaching at round-off: no impact
    taken = {j: np.zeros_like(p) for j in hit}
    laws: dict[int, Impact] = {}
    for _ in range(SWEEPS):
        change = 0.0
        for j in hit:
            without = p - taken[j]
            v = system.inverse_legendre(q, without, t, params)
            if normals[j] @ v >= goals[j]:
                new, law = without, None
            else:
                new, law = impulse(system, functions, j, t, q, without, prm, target=goals[j])
            change = max(change, float(np.abs(new - without - taken[j]).max()))
            taken[j], p = new - without, new
            laws[j] = law
        size = max(float(np.abs(d).max()) for d in taken.values())
        if change <= SETTLED * max(size, np.finfo(float).tiny):
            break
        if change <= POLISH * size:
            polished = _polished(system, functions, t, q, p_minus, prm, hit, laws, goals)
            if polished is not None:
                p = polished
                break
    else:
        raise ConvergenceError(
            f"contacts {hit} hit at once at t = {t}: their impulses did not settle in "
            f"{SWEEPS} sweeps (last change {change:.3g} of {size:.3g})",
            step=-1, t=t, residual=change,
        )  # fmt: skip
    v_plus = system.inverse_legendre(q, p, t, params)
    H = system.hamiltonian(np.vstack([q, q]), np.vstack([p_minus, p]), t, params)
    impacts = []
    for j in hit:
        if laws[j] is None:
            continue
        impacts.append(
            Impact(
                t=float(t),
                contact=j,
                normal_impulse=laws[j].normal_impulse,
                tangential_impulse=laws[j].tangential_impulse,
                mode=laws[j].mode,
                normal_velocity=(u_minus[j], float(normals[j] @ v_plus)),
                energy_lost=float(H[0] - H[1]) if not impacts else 0.0,
            )
        )
    return p, impacts


def _polished(system, functions, t, q, p_minus, prm, hit, laws, goals):
    r"""The momentum after a simultaneous impact whose contacts stick or take nothing:
    :math:`L_v(v^+) = p^- + D^{\mathsf T}\Lambda` with :math:`D v^+` = the targets
    (normal velocities :math:`-e u^-`, slips stopped, the constraints' rates), by
    least squares (a face's corner rows are redundant: :math:`v^+` is unique, the
    impulses are not). None when a contact slides, the equations are not met to
    round-off, or a contact that takes nothing ends approaching."""
    if any(law is not None and law.mode == "slide" for law in laws.values()):
        return None
    params = dict(zip(system.params, prm, strict=True))
    rows, targets = [], []
    for j in hit:
        if laws[j] is None:
            continue
        rows.append(functions.gradient(j, t, q, prm)[None])
        targets.append(goals[j])
        slip = functions.slip_matrix(j, t, q, prm)
        if slip is not None:
            rows.append(slip[0])
            targets.extend(-slip[1])
    D, targets = _with_constraints(system, t, q, prm, np.vstack(rows), targets)
    targets = np.asarray(targets, dtype=float)
    n, k = system.n, D.shape[0]
    v = system.inverse_legendre(q, p_minus, t, params)
    lam = np.zeros(k)
    for _ in range(_NEWTON_ITERATIONS):
        Lv = system.evaluate("Lv", t, q, v, prm)
        Lvv = system.evaluate("Lvv", t, q, v, prm).reshape(n, n)
        residual = np.concatenate([Lv - p_minus - D.T @ lam, D @ v - targets])
        K = np.block([[Lvv, -D.T], [D, np.zeros((k, k))]])
        step = np.linalg.lstsq(K, -residual, rcond=None)[0]
        v, lam = v + step[:n], lam + step[n:]
        if np.max(np.abs(step)) <= 1e-15 * max(1.0, np.max(np.abs(v)), np.max(np.abs(lam))):
            break
    scale = max(1.0, float(np.abs(v).max()))
    if np.abs(D @ v - targets).max() > 1e-12 * scale:
        return None
    for j in hit:
        if laws[j] is None and functions.gradient(j, t, q, prm) @ v < goals[j] - 1e-12 * scale:
            return None
    return system.evaluate("Lv", t, q, v, prm)


def irreversible_contacts(system) -> list[str]:
    r"""Why each contact's impact law cannot be run backwards in time (empty: all can).

    Newton's law :math:`u^+ = -e\,u^-` gives :math:`u^- = -u^+/e` only for
    e > 0; Coulomb friction maps a range of pre-impact slips to one sticking
    post-impact state, so the law has no inverse with friction.
    """
    reasons = []
    for j, contact in enumerate(system.contacts):
        where = f"contacts[{j}] (gap {contact.gap})"
        if contact.restitution == 0.0:
            reasons.append(
                f"{where}: restitution e = 0 (a plastic impact forgets the pre-impact "
                "normal velocity: u- = -u+/e is undefined)"
            )
        elif contact.friction > 0.0:
            reasons.append(
                f"{where}: friction mu = {contact.friction} (a sticking impact forgets the "
                "pre-impact slip: Coulomb's law has no inverse)"
            )
    return reasons


def inverse_impulse(system, functions: ContactFunctions, j: int, t: float, q, p, prm) -> tuple:
    r"""The momentum before an impact of contact ``j`` whose post-impact momentum is ``p``.

    The inverse of :func:`impulse` for a frictionless contact with e > 0, for runs
    backwards in time: :math:`p^- = p^+ - \Lambda_n \nabla\varphi(q)` with
    :math:`u^- = -u^+/e`. Returns ``(p_minus, impact)``, the :class:`Impact` in
    physical time (``normal_velocity`` = :math:`(u^-, u^+)`, ``energy_lost`` =
    :math:`H(q, p^-) - H(q, p^+)`, as the forward run reports it).

    Raises
    ------
    ValueError
        When the contact is not separating (:math:`u^+ \le 0`): it was not hit
        forward in time; or when its law has no inverse
        (:func:`irreversible_contacts`).
    """
    contact = system.contacts[j]
    if contact.restitution == 0.0 or contact.friction > 0.0:
        raise ValueError(irreversible_contacts(system)[0])
    params = dict(zip(system.params, prm, strict=True))
    q, p = np.asarray(q, dtype=float), np.asarray(p, dtype=float)
    v_plus = system.inverse_legendre(q, p, t, params)
    g = functions.gradient(j, t, q, prm)
    u_plus = float(g @ v_plus)
    if not u_plus > 0.0:
        raise ValueError(f"contact {j} at t = {t}: not separating (normal velocity {u_plus})")
    D, targets = _with_constraints(system, t, q, prm, g[None], [-u_plus / contact.restitution])
    v_minus, lam = _solve(system, t, q, p, v_plus, prm, D, D, targets)
    p_minus = p + D.T @ lam
    H = system.hamiltonian(np.vstack([q, q]), np.vstack([p_minus, p]), t, params)
    impact = Impact(
        t=float(t),
        contact=j,
        normal_impulse=float(-lam[0]),
        tangential_impulse=np.zeros(0),
        mode="frictionless",
        normal_velocity=(float(g @ v_minus), u_plus),
        energy_lost=float(H[0] - H[1]),
    )
    return p_minus, impact


def stop_slip(system, functions: ContactFunctions, j: int, t: float, q, p, prm):
    r"""The momentum that stops the slip of contact j, the normal velocity kept.

    :math:`L_v(v^+) = p + T^{\mathsf T}\Lambda_t` with :math:`T v^+ + w_0 = 0`: the
    tangential impulse of a contact that sticks (time-stepping applies it at the end
    of a step in which the contact stuck, so that the step's end velocity is the
    sticking one).
    """
    rows, w0 = functions.slip_matrix(j, t, q, prm)
    params = dict(zip(system.params, prm, strict=True))
    v = system.inverse_legendre(q, p, t, params)
    _, lam = _solve(system, t, q, p, v, prm, rows, rows, -w0)
    return p + rows.T @ lam


def _with_constraints(system, t, q, prm, D, targets) -> tuple[NDArray, list]:
    r"""The impulse directions ``D`` and velocity targets with the holonomic constraints'.

    A constrained system's impulse includes the constraints' reactions
    :math:`G^{\mathsf T}\mu` (G = :math:`\partial g/\partial q`), whose size keeps the
    velocity after the impact on the hidden constraint :math:`G v + g_t = 0`.
    """
    if not system.m:
        return D, list(targets)
    jac = system.constraint_jacobian(q, t, prm)
    rate = system.constraint_rate(q, t, prm)
    return np.vstack([D, jac]), [*targets, *(-rate)]


def _solve(system, t, q, p, v0, prm, D, C, targets) -> tuple[NDArray, NDArray]:
    r"""Newton on :math:`L_v(v) = p + D^{\mathsf T}\Lambda`, :math:`C v = \text{targets}`.

    The exact Jacobian :math:`\begin{pmatrix} L_{vv} & -D^{\mathsf T} \\ C & 0
    \end{pmatrix}`; from :math:`v^-`, one iteration when L is quadratic in v.
    """
    n, k = system.n, D.shape[0]
    v, lam = v0.copy(), np.zeros(k)
    targets = np.asarray(targets, dtype=float)
    for _ in range(_NEWTON_ITERATIONS):
        Lv = system.evaluate("Lv", t, q, v, prm)
        Lvv = system.evaluate("Lvv", t, q, v, prm).reshape(n, n)
        residual = np.concatenate([Lv - p - D.T @ lam, C @ v - targets])
        K = np.block([[Lvv, -D.T], [C, np.zeros((k, k))]])
        step = np.linalg.solve(K, -residual)
        v, lam = v + step[:n], lam + step[n:]
        if np.max(np.abs(step)) <= 1e-15 * max(1.0, np.max(np.abs(v)), np.max(np.abs(lam))):
            break
    return v, lam


def _sliding(system, t, q, p, v_minus, prm, g, rows, w0, target, mu, stuck=None):
    r"""Sliding: :math:`\Lambda_t = -\mu\Lambda_n d` with :math:`d = w^+/|w^+|` the slip
    direction after the impact.

    A few fixed-point sweeps on the direction (from the pre-impact one; exact in the
    plane) give the start of Newton on the whole system

    .. math::

        L_v(v) - p - \Lambda_n\bigl(\nabla\varphi - \mu T^{\mathsf T} d(v)\bigr)
        - \mathcal G^{\mathsf T}\nu = 0,\quad \nabla\varphi\cdot v = u^+,\quad
        \mathcal G v + g_t = 0,

    with :math:`d(v) = (Tv + w_0)/|Tv + w_0|` and the exact Jacobian
    (:math:`\partial d/\partial v = (I - dd^{\mathsf T})T/|w|`), so the velocity
    after slides exactly against its impulse in space as in the plane.

    Returns the velocity after, the normal and tangential impulses and the
    holonomic constraints' reaction impulse :math:`\mathcal G^{\mathsf T}\nu` (zero
    without constraints). Without a slip before the impact (a corner of a face
    landing flat) the sweeps start against ``stuck``, the tangential impulse that
    would have stopped the slip.
    """
    w = rows @ v_minus + w0
    size = np.linalg.norm(w)
    if size <= 1e-12 * max(1.0, float(np.abs(v_minus).max())) and stuck is not None:
        d = -stuck / np.linalg.norm(stuck)
    else:
        d = w / size
    for _ in range(_DIRECTION_SWEEPS):
        direction = (g - mu * (rows.T @ d))[None]
        D, targets = _with_constraints(system, t, q, prm, direction, [target])
        C, _ = _with_constraints(system, t, q, prm, g[None], [target])
        v, lam = _solve(system, t, q, p, v_minus, prm, D, C, targets)
        size = np.linalg.norm(rows @ v + w0)
        if size == 0.0 or rows.shape[0] == 1:
            return v, float(lam[0]), -mu * lam[0] * d, D[1:].T @ lam[1:]
        d = (rows @ v + w0) / size
    n = system.n
    jac = system.constraint_jacobian(q, t, prm) if system.m else np.zeros((0, n))
    rate = system.constraint_rate(q, t, prm) if system.m else np.zeros(0)
    m = jac.shape[0]
    normal, nu = float(lam[0]), lam[1:].copy()

    def equations(v, normal, nu, jacobian: bool):
        slip = rows @ v + w0
        size = np.linalg.norm(slip)
        d = slip / size
        push = g - mu * (rows.T @ d)
        Lv = system.evaluate("Lv", t, q, v, prm)
        r = np.concatenate([Lv - p - normal * push - jac.T @ nu, [g @ v - target], jac @ v + rate])
        if not jacobian:
            return r, None
        K = np.zeros((n + 1 + m, n + 1 + m))
        Lvv = system.evaluate("Lvv", t, q, v, prm).reshape(n, n)
        bend = (np.eye(len(d)) - np.outer(d, d)) / size
        K[:n, :n] = Lvv + mu * normal * rows.T @ bend @ rows
        K[:n, n] = -push
        K[:n, n + 1 :] = -jac.T
        K[n, :n] = g
        K[n + 1 :, :n] = jac
        return r, K

    residual, K = equations(v, normal, nu, True)
    for _ in range(_NEWTON_ITERATIONS):
        step = np.linalg.solve(K, -residual)
        if np.max(np.abs(step)) <= 1e-15 * max(1.0, np.max(np.abs(v)), abs(normal)):
            break
        # backtracking on the residual's norm: the full step can cycle where the
        # slip direction turns fast with v
        alpha, size = 1.0, np.linalg.norm(residual)
        while True:
            trial = (v + alpha * step[:n], normal + alpha * step[n], nu + alpha * step[n + 1 :])
            new, _ = equations(*trial, False)
            if np.linalg.norm(new) < size or alpha < 1e-6:
                break
            alpha /= 2
        v, normal, nu = trial
        residual, K = equations(v, normal, nu, True)
    d = (rows @ v + w0) / np.linalg.norm(rows @ v + w0)
    return v, normal, -mu * normal * d, jac.T @ nu
