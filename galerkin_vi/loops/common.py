r"""Pieces every time loop shares: interpolation, compensated sums, angles, saving.

Notation (see the theory page): control points :math:`q^\nu = q_k + C^\nu`
stored as increments :math:`C^\nu` from the step's start (:math:`C^0 = 0`),
quadrature weights :math:`b_i`, tables :math:`\Phi_{i\nu} = \ell_\nu(c_i)` and
:math:`D_{i\nu} = \ell'_\nu(c_i)`. At quadrature point :math:`i`,
:math:`Q_i = q_k + \sum_\nu \Phi_{i\nu} C^\nu` and
:math:`V_i = \tfrac1h\sum_\nu D_{i\nu} C^\nu`.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from ._jit import kernel
from .abi import STATUS_NEWTON_FAILED, STATUS_NONFINITE, STATUS_OK, STATUS_SINGULAR

__all__ = [
    "FREEZE",
    "STATUS_NEWTON_FAILED",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_SINGULAR",
    "advance_position",
    "compensated_add",
    "extrapolate",
    "first_guess",
    "interpolate",
    "save_row",
    "wrap_angles",
]

# below this relative increment Newton has converged to a few ulps after one more step
FREEZE = 1e-8
TWO_PI_HI = 6.283185307179586  # float(2 pi)
TWO_PI_LO = 2.4492935982947064e-16  # 2 pi - TWO_PI_HI


@kernel
def interpolate(i, inv_h, qk, C, Phi, D, Q, V):
    """Q = q_k + sum_nu Phi[i, nu] C[nu] and V = sum_nu D[i, nu] C[nu] / h at quadrature point i.

    ``inv_h`` is 1/h: a multiplication per coordinate, where a division would be
    a noticeable share of the general loop's own time.
    """
    s1, n = C.shape
    for a in range(n):
        qa = 0.0
        va = 0.0
        for nu in range(1, s1):
            if Phi[i, nu] != 0.0:  # collocated nodes: Phi is the identity
                qa += Phi[i, nu] * C[nu, a]
            va += D[i, nu] * C[nu, a]
        Q[a] = qk[a] + qa
        V[a] = va * inv_h


@kernel
def compensated_add(x, x_lost, y):
    """x += y with Kahan compensation; ``x_lost`` carries each rounding error to the next."""
    for a in range(x.shape[0]):
        z = y[a] - x_lost[a]
        total = x[a] + z
        x_lost[a] = (total - x[a]) - z
        x[a] = total


@kernel
def first_guess(C, d, h, v0):
    """Increments q^nu - q_0 = d_nu h v_0 on the first step (no previous polynomial)."""
    s1, n = C.shape
    for nu in range(s1):
        for a in range(n):
            C[nu, a] = d[nu] * h * v0[a]


@kernel
def advance_position(qk, q_lost, C, turns, periodic):
    """q_{k+1} = q_k + C[-1] with compensated (Kahan) summation, angles kept in [-pi, pi).

    ``q_lost`` carries the rounding error of each addition into the next one, so
    that rounding does not accumulate as a drift of the energy over long runs
    (docs/design-notes.md, "Accuracy over long runs").
    """
    s = C.shape[0] - 1
    for a in range(qk.shape[0]):
        y = C[s, a] - q_lost[a]
        total = qk[a] + y
        q_lost[a] = (total - qk[a]) - y
        qk[a] = total
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)


@kernel
def wrap_angles(qk, q_lost, turns, periodic):
    r"""Translate periodic coordinates (angles) by whole turns into :math:`[-\pi, \pi)`.

    :math:`L`, the forces and the constraints are :math:`2\pi`-periodic in
    them, so the map commutes with the shift; evaluating them at a small
    angle keeps the absolute accuracy :math:`\varepsilon`, where an angle of
    :math:`10^4` would lose :math:`10^4\varepsilon` in every sine. The shift
    subtracts :math:`2\pi = ` ``TWO_PI_HI + TWO_PI_LO`` exactly (Sterbenz: the
    high part cancels without rounding, the low part joins ``q_lost``);
    ``turns`` counts the whole turns removed, for the output.
    """
    for a in range(qk.shape[0]):
        if periodic[a]:
            if not -np.pi <= qk[a] < np.pi:
                # many turns at once (a start far out): one rounding of k 2 pi, the
                # precision of such an angle anyway; one turn (every step) is exact
                k = np.floor((qk[a] + np.pi) / TWO_PI_HI)
                qk[a] -= k * TWO_PI_HI
                q_lost[a] += k * TWO_PI_LO
                turns[a] += k
            while qk[a] >= np.pi:
                qk[a] -= TWO_PI_HI
                q_lost[a] += TWO_PI_LO
                turns[a] += 1.0
            while qk[a] < -np.pi:
                qk[a] += TWO_PI_HI
                q_lost[a] -= TWO_PI_LO
                turns[a] -= 1.0


@kernel
def extrapolate(C, C_prev, E):
    """Initial guess: the previous step's polynomial at this step's nodes, re-based.

    On entry C holds the previous step's increments; on exit the guess for this
    step as increments from q_k = q_{k-1} + C_prev[s] (C_prev is work space).
    """
    s1, n = C.shape
    s = s1 - 1
    for nu in range(s1):
        for a in range(n):
            C_prev[nu, a] = C[nu, a]
    for nu in range(s1):
        for a in range(n):
            acc = 0.0
            for mu in range(1, s1):
                acc += E[nu, mu] * C_prev[mu, a]
            C[nu, a] = acc - C_prev[s, a]
    for a in range(n):
        C[0, a] = 0.0


@kernel
def save_row(saved, t, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic):
    r"""Store (t, q, p) in row ``saved`` of the outputs; return the next row.

    Angles are saved as they are kept, in :math:`[-\pi, \pi)` with their
    compensation ``q_lost`` applied, and the whole turns removed so far go to
    ``turns_out`` (the caller adds them back: saving the continuous angle itself
    would round it to the precision of its size). ``periodic`` is the mask of
    the angles, or ``None`` when there are none (a compiled variant of its own).
    """
    t_out[saved] = t
    if periodic is None:
        for a in range(qk.shape[0]):
            q_out[saved, a] = qk[a]
            p_out[saved, a] = pk[a]
        return saved + 1
    for a in range(qk.shape[0]):
        if periodic[a]:
            q_out[saved, a] = qk[a] - q_lost[a]
            turns_out[saved, a] = turns[a]
        else:
            q_out[saved, a] = qk[a]
        p_out[saved, a] = pk[a]
    return saved + 1
