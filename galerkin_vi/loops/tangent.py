r"""The tangent map of the position–momentum step and its transpose (the discrete adjoint).

A step of :mod:`.general` solves the stage equations :math:`R(Z; x_k, \theta) = 0`
for the control points :math:`Z = (q^1, \dots, q^s)` (:math:`q^0 = q_k`) and sets

.. math::

    R^\nu = G^\nu + \delta_{\nu 0}\,p_k \ (0 \le \nu < s),\qquad
    q_{k+1} = q^s,\qquad p_{k+1} = p_k + h \sum_i b_i (L_q + f)^{(i)},

with :math:`G^\nu = \sum_i b_i [h \Phi_{i\nu} (L_q + f)^{(i)} + D_{i\nu} L_v^{(i)}]`
and :math:`(\cdot)^{(i)}` the value at quadrature point :math:`i`, where
:math:`Q_i = \sum_\mu \Phi_{i\mu} q^\mu`, :math:`V_i = \sum_\mu D_{i\mu} q^\mu / h`.
By the implicit function theorem, with :math:`K = \partial R/\partial Z` the
exact stage Jacobian at the converged :math:`Z` (:func:`.general.assemble_newton`),
a variation :math:`(\delta q_k, \delta p_k, \delta\theta)` gives

.. math::

    K\,\delta Z = -\Big(\sum_i b_i \big[h\Phi_{i\nu}\,\delta(L_q + f)^{(i)}_0
        + D_{i\nu}\,\delta L_v^{(i)}_0\big] + \delta_{\nu0}\,\delta p_k\Big)_{\nu<s},

where the subscript 0 marks the variation of the point values through
:math:`q^0 = q_k` and :math:`\theta` only (:math:`\delta Q_i = \Phi_{i0}\delta q_k`,
:math:`\delta V_i = D_{i0}\delta q_k / h`), and

.. math::

    \delta q_{k+1} = \delta q^s,\qquad \delta p_{k+1} = \delta p_k
        + h \sum_i b_i\,\delta (L_q + f)^{(i)},

the last with the full :math:`\delta Q_i, \delta V_i` of all control points.
The point variations are :math:`\delta(L_q + f) = (L_{qq} + f_q)\delta Q +
(L_{qv} + f_v)\delta V + (L_{q\theta} + f_\theta)\delta\theta` and
:math:`\delta L_v = L_{qv}^T\delta Q + L_{vv}\delta V + L_{v\theta}\delta\theta`,
products with the point Hessians kept per quadrature point (dense, or in the
banded pattern of the system). So each direction costs one solve with the
factors of :math:`K` and a few point products; the factorisation is one per
step, at the converged control points. The transpose of the same chain,
applied to a cotangent :math:`\lambda_{k+1}`, is one solve with :math:`K^T`
(:func:`galerkin_vi.newton.lu_solve_transpose`): the reverse pass of the
discrete adjoint (:func:`adjoint_sweep`).

The tangent loop solves the stage equations by simplified Newton with the
factors of the previous step's Jacobian (or, after a slowly contracting step,
of one at the first iterate, as :func:`.general.general_loop` does), then
assembles and factorises the Jacobian once at the solution (exact there, as
the tangent map needs) and propagates the directions; those factors are the
next step's iteration matrix. Without directions (the adjoint's record, which
the reverse pass linearises itself) it iterates as the general loop. With
``renormalize_every`` :math:`m > 0` it orthonormalises the frame every
:math:`m` steps by modified Gram–Schmidt (Benettin et al. 1980), accumulating
:math:`\log r_{jj}`, and keeps the MEGNO sums of the frame's first column
(Cincotta & Simó 2000):

.. math::

    Y_N = \frac{2}{t_N - t_0} \sum_{k<N} (t_{k+1} - t_0)
        \log\frac{\|\delta_{k+1}\|}{\|\delta_k\|},\qquad
    \bar Y_N = \frac1N \sum_{k=1}^N Y_k .
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from .. import newton
from ._jit import kernel
from .common import (
    STATUS_NEWTON_FAILED,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_SINGULAR,
    advance_position,
    compensated_add,
    extrapolate,
    first_guess,
    interpolate,
    save_row,
    wrap_angles,
)
from .general import SIMPLIFIED_CONTRACTION, STALE_RETRY
from .linalg import (
    CONTINUE,
    CONVERGED,
    add_block,
    band_half_width,
    block_size,
    factor_jacobian,
    new_jacobian,
    newton_status,
    solve_jacobian,
    unknown,
)
from .on_demand import driver
from .point import point_gradient, point_hessian
from .traits import BAND, HAS_FV, HAS_LQV

__all__ = ["adjoint_sweep", "tangent_loop"]

lu_solve_transpose = kernel(newton.lu_solve_transpose)
band_lu_solve_transpose = kernel(newton.band_lu_solve_transpose)

#: slots of the carried chaos sums after the r log-growths: W (MEGNO's weighted sum)
#: and the sum of Y
MEGNO_W, MEGNO_YSUM = 0, 1


@kernel
def point_product(M, x, y, w, pattern, n):
    """y += w M x for a flat point matrix M (dense ``a n + c``, or banded ``pattern``)."""
    if pattern is None:
        for a in range(n):
            acc = 0.0
            for cc in range(n):
                acc += M[a * n + cc] * x[cc]
            y[a] += w * acc
    else:
        for k in range(pattern.shape[0]):
            y[pattern[k, 0]] += w * M[k] * x[pattern[k, 1]]


@kernel
def point_product_transpose(M, x, y, w, pattern, n):
    """y += w M^T x for a flat point matrix M (as :func:`point_product`)."""
    if pattern is None:
        for a in range(n):
            xa = w * x[a]
            for cc in range(n):
                y[cc] += M[a * n + cc] * xa
    else:
        for k in range(pattern.shape[0]):
            y[pattern[k, 1]] += w * M[k] * x[pattern[k, 0]]


@kernel
def solve_transpose(K, piv, s, R, traits, pattern):
    """Overwrite R with K^{-T} R from :func:`.linalg.factor_jacobian`'s factors."""
    if pattern is not None:
        kb = band_half_width(s, traits[BAND])
        band_lu_solve_transpose(K, piv, kb, kb, R)
    else:
        lu_solve_transpose(K, piv, R)


@kernel
def linearize(
    fn, fnp, tk, h, qk, C, prm, b, c, Phi, D, Q, V, F, FV, HQQ, HQV, HVV, HFV, TQ, TV, K,
    traits, pattern, couplings,
):  # fmt: skip
    """Point values, point Hessians (and parameter derivatives) at every quadrature point
    of the control points ``C``, and the stage Jacobian K assembled from them."""
    r = b.shape[0]
    s1, n = C.shape
    s = s1 - 1
    inv_h = 1.0 / h
    K[:, :] = 0.0
    for i in range(r):
        interpolate(i, inv_h, qk, C, Phi, D, Q, V)
        ti = tk + c[i] * h
        point_hessian(fn, ti, Q, V, prm, F[i], FV[i], HQQ[i], HQV[i], HVV[i], HFV[i])
        if TQ.shape[1] > 0:
            point_gradient(fnp, ti, Q, V, prm, TQ[i], TV[i])
        for nu in range(s):
            for mu in range(1, s1):
                add_block(
                    K, nu, mu, s, n, b[i] * D[i, nu] * D[i, mu] / h, HVV[i],
                    b[i] * h * Phi[i, nu] * Phi[i, mu], HQQ[i],
                    b[i] * Phi[i, nu] * D[i, mu], b[i] * D[i, nu] * Phi[i, mu],
                    HQV[i], HFV[i], traits, pattern, couplings,
                )  # fmt: skip


@kernel
def point_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, j, dLq, dLv, with_v, traits, pattern):
    r"""dLq = (L_qq + f_q) dQ + (L_qv + f_v) dV (+ column j of the parameter derivatives),
    and, with ``with_v``, dLv = L_qv^T dQ + L_vv dV (+ its column j) at point i."""
    n = dQ.shape[0]
    has_lqv = traits[HAS_LQV] != 0
    has_fv = traits[HAS_FV] != 0
    dLq[:] = 0.0
    point_product(HQQ[i], dQ, dLq, 1.0, pattern, n)
    if has_lqv:
        point_product(HQV[i], dV, dLq, 1.0, pattern, n)
    if has_fv:
        point_product(HFV[i], dV, dLq, 1.0, pattern, n)
    if with_v:
        dLv[:] = 0.0
        point_product(HVV[i], dV, dLv, 1.0, pattern, n)
        if has_lqv:
            point_product_transpose(HQV[i], dQ, dLv, 1.0, pattern, n)
    if j >= 0:
        P = TQ.shape[1] // n
        for a in range(n):
            dLq[a] += TQ[i, a * P + j]
            if with_v:
                dLv[a] += TV[i, a * P + j]


@kernel
def propagate(
    dq, dp, j, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ, TV, K, piv, rhs, dQ, dV, dLq, dLv,
    traits, pattern,
):  # fmt: skip
    r"""One direction through the step: (dq, dp) <- (dq', dp') in place (module docstring).

    ``j >= 0`` adds the derivative with respect to parameter ``j`` (a sensitivity column).
    """
    r = b.shape[0]
    s1 = Phi.shape[1]
    s = s1 - 1
    n = dq.shape[0]
    banded = pattern is not None
    inv_h = 1.0 / h
    for nu in range(s):
        for a in range(n):
            rhs[unknown(nu, a, s, n, banded)] = -dp[a] if nu == 0 else 0.0
    for i in range(r):
        for a in range(n):
            dQ[a] = Phi[i, 0] * dq[a]
            dV[a] = D[i, 0] * dq[a] * inv_h
        point_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, j, dLq, dLv, True, traits, pattern)
        for nu in range(s):
            wq = b[i] * h * Phi[i, nu]
            wv = b[i] * D[i, nu]
            for a in range(n):
                rhs[unknown(nu, a, s, n, banded)] -= wq * dLq[a] + wv * dLv[a]
    solve_jacobian(K, piv, s, rhs, traits, pattern)
    # the full point variations, for the momentum's
    for i in range(r):
        for a in range(n):
            x = Phi[i, 0] * dq[a]
            y = D[i, 0] * dq[a]
            for mu in range(1, s1):
                z = rhs[unknown(mu - 1, a, s, n, banded)]
                x += Phi[i, mu] * z
                y += D[i, mu] * z
            dQ[a] = x
            dV[a] = y * inv_h
        point_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, j, dLq, dLv, False, traits, pattern)
        for a in range(n):
            dp[a] += h * b[i] * dLq[a]
    for a in range(n):
        dq[a] = rhs[unknown(s - 1, a, s, n, banded)]


@kernel
def block_product(M, X, Y, w, pattern, n, transpose):
    """Y += w M X (or w M^T X) for a flat point matrix M and blocks X, Y of shape (n, r):
    every direction at once, the directions innermost."""
    r = X.shape[1]
    if pattern is None:
        for a in range(n):
            for cc in range(n):
                m = w * M[a * n + cc]
                if m != 0.0:
                    if transpose:
                        for j in range(r):
                            Y[cc, j] += m * X[a, j]
                    else:
                        for j in range(r):
                            Y[a, j] += m * X[cc, j]
    else:
        for k in range(pattern.shape[0]):
            m = w * M[k]
            a = pattern[k, 0]
            cc = pattern[k, 1]
            if transpose:
                for j in range(r):
                    Y[cc, j] += m * X[a, j]
            else:
                for j in range(r):
                    Y[a, j] += m * X[cc, j]


@kernel
def block_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, first_theta, dLq, dLv, with_v,
                    traits, pattern):  # fmt: skip
    """:func:`point_variation` for the blocks of all directions (n, r): columns from
    ``first_theta`` on are parameter sensitivities, in the order of the parameters."""
    n, r = dQ.shape
    dLq[:, :] = 0.0
    block_product(HQQ[i], dQ, dLq, 1.0, pattern, n, False)
    if traits[HAS_LQV] != 0:
        block_product(HQV[i], dV, dLq, 1.0, pattern, n, False)
    if traits[HAS_FV] != 0:
        block_product(HFV[i], dV, dLq, 1.0, pattern, n, False)
    if with_v:
        dLv[:, :] = 0.0
        block_product(HVV[i], dV, dLv, 1.0, pattern, n, False)
        if traits[HAS_LQV] != 0:
            block_product(HQV[i], dQ, dLv, 1.0, pattern, n, True)
    P = r - first_theta
    for j in range(P):
        for a in range(n):
            dLq[a, first_theta + j] += TQ[i, a * P + j]
            if with_v:
                dLv[a, first_theta + j] += TV[i, a * P + j]


@kernel
def propagate_block(
    W, first_theta, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ, TV, K, piv, RB, dQ, dV, dLq, dLv,
    traits, pattern,
):  # fmt: skip
    r"""Every direction through the step at once: the columns of W (2n, r), the frame's and
    then the sensitivities' (from column ``first_theta``), in place.

    The module docstring's maths: the right-hand sides from the variations of the
    point values through :math:`q^0` (one per direction, the rows of ``RB``), one
    solve each with the factors of K, then the momentum's variation with the full
    point variations. The directions are the innermost loops of the point products.
    """
    r = b.shape[0]
    s1 = Phi.shape[1]
    s = s1 - 1
    n = dQ.shape[0]
    m = W.shape[1]
    banded = pattern is not None
    inv_h = 1.0 / h
    RB[:, :] = 0.0
    for a in range(n):
        for j in range(m):
            RB[j, unknown(0, a, s, n, banded)] = -W[n + a, j]
    for i in range(r):
        for a in range(n):
            for j in range(m):
                dQ[a, j] = Phi[i, 0] * W[a, j]
                dV[a, j] = D[i, 0] * inv_h * W[a, j]
        block_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, first_theta, dLq, dLv, True,
                        traits, pattern)  # fmt: skip
        for nu in range(s):
            wq = b[i] * h * Phi[i, nu]
            wv = b[i] * D[i, nu]
            for a in range(n):
                u = unknown(nu, a, s, n, banded)
                for j in range(m):
                    RB[j, u] -= wq * dLq[a, j] + wv * dLv[a, j]
    for j in range(m):
        solve_jacobian(K, piv, s, RB[j], traits, pattern)
    for i in range(r):
        for a in range(n):
            for j in range(m):
                x = Phi[i, 0] * W[a, j]
                y = D[i, 0] * W[a, j]
                for mu in range(1, s1):
                    z = RB[j, unknown(mu - 1, a, s, n, banded)]
                    x += Phi[i, mu] * z
                    y += D[i, mu] * z
                dQ[a, j] = x
                dV[a, j] = y * inv_h
        block_variation(i, dQ, dV, HQQ, HQV, HVV, HFV, TQ, TV, first_theta, dLq, dLv, False,
                        traits, pattern)  # fmt: skip
        w = h * b[i]
        for a in range(n):
            for j in range(m):
                W[n + a, j] += w * dLq[a, j]
    for a in range(n):
        u = unknown(s - 1, a, s, n, banded)
        for j in range(m):
            W[a, j] = RB[j, u]


@kernel
def pull_back(
    lam, grad, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ, TV, K, piv, W, dQ, dV, uq, uv, acc_q,
    traits, pattern,
):  # fmt: skip
    r"""The transposed step: :math:`\lambda_k = (\partial x_{k+1}/\partial x_k)^T\lambda_{k+1}`
    in place, and :math:`(\partial x_{k+1}/\partial\theta)^T\lambda_{k+1}` added to ``grad``.

    The transpose of :func:`propagate`, read backwards: the momentum's cotangent
    :math:`u_i = h b_i \lambda_p` reaches every control point through the point
    Hessians, :math:`\lambda_q` reaches :math:`q^s`; one solve with :math:`K^T` gives
    the cotangent :math:`\rho` of the stage residuals, which reaches :math:`p_k`
    as :math:`-\rho^0` and :math:`q_k` through the points' dependence on :math:`q^0`.
    ``W`` has s n entries, ``acc_q`` n; the rest are length-n work vectors.
    """
    r = b.shape[0]
    s1 = Phi.shape[1]
    s = s1 - 1
    n = dQ.shape[0]
    banded = pattern is not None
    inv_h = 1.0 / h
    has_lqv = traits[HAS_LQV] != 0
    has_fv = traits[HAS_FV] != 0
    P = TQ.shape[1] // n if n > 0 else 0
    # acc_q: the cotangent of q^0 = q_k; W: of q^1..q^s (unknown order)
    acc_q[:] = 0.0
    W[:] = 0.0
    for a in range(n):
        W[unknown(s - 1, a, s, n, banded)] = lam[a]
    for i in range(r):
        for a in range(n):
            uq[a] = h * b[i] * lam[n + a]
        dQ[:] = 0.0
        dV[:] = 0.0
        point_product_transpose(HQQ[i], uq, dQ, 1.0, pattern, n)
        if has_lqv:
            point_product_transpose(HQV[i], uq, dV, inv_h, pattern, n)
        if has_fv:
            point_product_transpose(HFV[i], uq, dV, inv_h, pattern, n)
        for a in range(n):
            acc_q[a] += Phi[i, 0] * dQ[a] + D[i, 0] * dV[a]
            for mu in range(1, s1):
                W[unknown(mu - 1, a, s, n, banded)] += Phi[i, mu] * dQ[a] + D[i, mu] * dV[a]
        for jj in range(P):
            for a in range(n):
                grad[jj] += TQ[i, a * P + jj] * uq[a]
    solve_transpose(K, piv, s, W, traits, pattern)
    # lambda_p: through p_{k+1} = p_k + ..., and through R^0 = G^0 + p_k
    for a in range(n):
        lam[n + a] -= W[unknown(0, a, s, n, banded)]
    for i in range(r):
        for a in range(n):
            x = 0.0
            y = 0.0
            for nu in range(s):
                rho = W[unknown(nu, a, s, n, banded)]
                x -= b[i] * h * Phi[i, nu] * rho
                y -= b[i] * D[i, nu] * rho
            uq[a] = x
            uv[a] = y
        dQ[:] = 0.0
        dV[:] = 0.0
        point_product_transpose(HQQ[i], uq, dQ, 1.0, pattern, n)
        point_product_transpose(HVV[i], uv, dV, inv_h, pattern, n)
        if has_lqv:
            point_product(HQV[i], uv, dQ, 1.0, pattern, n)
            point_product_transpose(HQV[i], uq, dV, inv_h, pattern, n)
        if has_fv:
            point_product_transpose(HFV[i], uq, dV, inv_h, pattern, n)
        for a in range(n):
            acc_q[a] += Phi[i, 0] * dQ[a] + D[i, 0] * dV[a]
        for jj in range(P):
            for a in range(n):
                grad[jj] += TQ[i, a * P + jj] * uq[a] + TV[i, a * P + jj] * uv[a]
    for a in range(n):
        lam[a] = acc_q[a]


@kernel
def orthonormalize(T, growth):
    """Modified Gram–Schmidt on the columns of T in place; log r_jj added to growth[j].

    Returns False if a column has no length left (a dependent frame)."""
    m, r = T.shape
    for j in range(r):
        for i in range(j):
            dot = 0.0
            for a in range(m):
                dot += T[a, i] * T[a, j]
            for a in range(m):
                T[a, j] -= dot * T[a, i]
        norm = 0.0
        for a in range(m):
            norm += T[a, j] * T[a, j]
        norm = np.sqrt(norm)
        if not norm > 0.0 or not norm < 1e300:
            return False
        growth[j] += np.log(norm)
        for a in range(m):
            T[a, j] /= norm
    return True


@kernel
def first_column_log_norm(T, growth):
    """log |T[:, 0]| plus its growth removed by the renormalisations so far."""
    acc = 0.0
    for a in range(T.shape[0]):
        acc += T[a, 0] * T[a, 0]
    return 0.5 * np.log(acc) + growth[0]


@kernel
def start_chaos(T, megno, t0, t_origin, h, chaos):
    """The frame's log-growths (a view of ``megno``) and the chaos sums of a call:
    ``[W, sum of Y, log |delta|, Y, mean of Y]``, the first two carried in ``megno``."""
    r = T.shape[1]
    growth = megno[:r]
    sums = np.zeros(5)
    sums[0] = megno[r + MEGNO_W]
    sums[1] = megno[r + MEGNO_YSUM]
    if chaos:
        sums[2] = first_column_log_norm(T, growth)
        if t0 > t_origin:
            sums[3] = 2.0 * sums[0] / (t0 - t_origin)
        steps_before = int(round((t0 - t_origin) / h))
        sums[4] = sums[1] / steps_before if steps_before > 0 else 0.0
    return growth, sums


@kernel
def advance_chaos(T, growth, sums, elapsed, h, renormalize):
    """MEGNO's sums after a step ending ``elapsed`` after the run's start, then the
    renormalisation if due; False if the frame degenerated."""
    log_norm = first_column_log_norm(T, growth)
    sums[0] += elapsed * (log_norm - sums[2])
    sums[2] = log_norm
    sums[3] = 2.0 * sums[0] / elapsed
    sums[1] += sums[3]
    sums[4] = sums[1] / int(round(elapsed / h))
    if renormalize:
        return orthonormalize(T, growth)
    return True


@kernel
def finish_chaos(megno, sums, r):
    """Carry the MEGNO sums to the next call."""
    megno[r + MEGNO_W] = sums[0]
    megno[r + MEGNO_YSUM] = sums[1]


@kernel
def save_variations(row, T, S, growth, sums, T_out, S_out, growth_out, megno_out):
    """Store the frame, the sensitivities and the chaos sums (Y, its mean) in row ``row``."""
    for a in range(T.shape[0]):
        for j in range(T.shape[1]):
            T_out[row, a, j] = T[a, j]
        for j in range(S.shape[1]):
            S_out[row, a, j] = S[a, j]
    if growth_out.shape[0] > 0:
        for j in range(T.shape[1]):
            growth_out[row, j] = growth[j]
        megno_out[row, 0] = sums[3]
        megno_out[row, 1] = sums[4]


@kernel
def make_tangent_work(r, s, n, nnz, n_theta):
    """Per-point tables of one step (point values, Hessians, parameter derivatives)."""
    F = np.zeros((r, n))
    FV = np.zeros((r, n))
    HQQ = np.zeros((r, nnz))
    HQV = np.zeros((r, nnz))
    HVV = np.zeros((r, nnz))
    HFV = np.zeros((r, nnz))
    TQ = np.zeros((r, n * n_theta))
    TV = np.zeros((r, n * n_theta))
    return F, FV, HQQ, HQV, HVV, HFV, TQ, TV


@driver
def tangent_loop(
    fn,
    traits,
    pattern,
    periodic,
    couplings,
    fnp,
    q0,
    p0,
    v0,
    t0,
    h,
    n_steps,
    save_every,
    prm,
    b,
    c,
    d,
    Phi,
    D,
    E,
    tol,
    maxiter,
    T,
    S,
    renormalize_every,
    t_origin,
    megno,
    stages_out,
    t_out,
    q_out,
    p_out,
    turns_out,
    T_out,
    S_out,
    growth_out,
    megno_out,
    iterations_out,
    iteration_total,
):
    r"""Run ``n_steps`` steps of the general loop's map with its tangent map.

    The arguments of :func:`.general_loop`, and: ``fnp`` the addresses of the
    parameter derivatives' point function (slot ``GRADIENT``: :math:`L_{q\theta} +
    f_\theta` and :math:`L_{v\theta}`, flat ``a P + j``), ``T`` the frame (2n, r)
    and ``S`` the sensitivities (2n, P), both advanced in place (so a later call
    continues them); ``renormalize_every`` (0: never) and the chaos sums
    ``megno``, ``t_origin`` the run's start time;
    ``stages_out`` (n_steps, s + 1, n) receives each step's control points when
    it has rows (the discrete adjoint's record), else shape (0, s + 1, n).
    Outputs ``T_out`` (rows, 2n, r), ``S_out`` (rows, 2n, P), ``growth_out``
    (rows, r) and ``megno_out`` (rows, 2) (both with 0 rows without
    renormalisation) beside the general loop's. ``megno`` carries
    ``[log-growth of each column (r entries)..., W, sum of Y]`` across calls in
    place: length r + 2. Returns the general loop's 5-tuple.
    """
    n = q0.shape[0]
    s1 = d.shape[0]
    s = s1 - 1
    r = b.shape[0]
    n_dir = T.shape[1]
    n_theta = S.shape[1]
    nnz = block_size(n, pattern)
    F, FV, HQQ, HQV, HVV, HFV, TQ, TV = make_tangent_work(r, s, n, nnz, n_theta)
    K = new_jacobian(s, n, traits, pattern)
    piv = np.zeros(s * n, dtype=np.int64)
    R = np.zeros(s * n)
    Q = np.zeros(n)
    V = np.zeros(n)
    rhs = np.zeros(s * n)
    dq = np.zeros(n)
    dp = np.zeros(n)
    dQ = np.zeros(n)
    dV = np.zeros(n)
    dLq = np.zeros(n)
    dLv = np.zeros(n)
    m_all = n_dir + n_theta
    Wb = np.zeros((2 * n, m_all))  # the frame and the sensitivities, side by side
    RB = np.zeros((m_all, s * n))
    dQb = np.zeros((n, m_all))
    dVb = np.zeros((n, m_all))
    dLqb = np.zeros((n, m_all))
    dLvb = np.zeros((n, m_all))
    chaos = renormalize_every > 0
    growth, sums = start_chaos(T, megno, t0, t_origin, h, chaos)
    banded = pattern is not None
    inv_h = 1.0 / h
    factored = False  # K holds the factors of the Jacobian at the last step's solution
    fresh_for = 0  # steps that start with a Jacobian at their first iterate
    dpk = np.zeros(n)
    p_lost = np.zeros(n)
    C = np.zeros((s1, n))
    C_prev = np.zeros((s1, n))
    qk = q0.copy()
    q_lost = np.zeros(n)
    turns = np.zeros(n)
    if periodic is not None:
        wrap_angles(qk, q_lost, turns, periodic)
    pk = p0.copy()
    first_guess(C, d, h, v0)
    saved = save_row(0, t0, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic)
    save_variations(0, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
    worst = 0.0
    for k in range(n_steps):
        tk = t0 + k * h
        if k > 0:
            extrapolate(C, C_prev, E)
        # simplified Newton with the factors of the Jacobian at the previous step's
        # solution (fresh ones on the first step, and at an iterate where the iteration
        # contracts slowly); then the point tables and K once at the solution: the
        # directions' Jacobian and the next step's iteration matrix
        status = STATUS_NEWTON_FAILED
        its = 0
        increment = np.inf
        residual = np.inf
        previous = np.inf
        fresh = not factored or fresh_for > 0
        if fresh_for > 0:
            fresh_for -= 1
        refreshed = False
        current = False  # the point tables (and K, if fresh) are those at the final C
        while its < maxiter:
            its += 1
            if fresh:
                linearize(
                    fn, fnp, tk, h, qk, C, prm, b, c, Phi, D, Q, V, F, FV, HQQ, HQV, HVV, HFV,
                    TQ, TV, K, traits, pattern, couplings,
                )  # fmt: skip
                factored = factor_jacobian(K, piv, s, traits, pattern)
                if not factored:
                    status = STATUS_SINGULAR
                    break
                refreshed = True
            else:
                for i in range(r):
                    interpolate(i, inv_h, qk, C, Phi, D, Q, V)
                    point_gradient(fn, tk + c[i] * h, Q, V, prm, F[i], FV[i])
            residual = 0.0
            for nu in range(s):
                for a in range(n):
                    val = pk[a] if nu == 0 else 0.0
                    for i in range(r):
                        val += b[i] * (h * Phi[i, nu] * F[i, a] + D[i, nu] * FV[i, a])
                    R[unknown(nu, a, s, n, banded)] = -val
                    if not abs(val) <= residual:
                        residual = abs(val)
            if not residual < 1e300:
                status = STATUS_NONFINITE
                break
            solve_jacobian(K, piv, s, R, traits, pattern)
            increment = 0.0
            scaled = 0.0
            moved = False
            for nu in range(1, s1):
                for a in range(n):
                    delta = R[unknown(nu - 1, a, s, n, banded)]
                    updated = C[nu, a] + delta
                    if qk[a] + updated != qk[a] + C[nu, a]:
                        moved = True
                    C[nu, a] = updated
                    increment = max(increment, abs(delta))
                    scaled = max(scaled, abs(delta) / (1.0 + abs(qk[a]) + abs(updated)))
            if not moved:
                status = STATUS_OK
                current = True
                break
            decision = newton_status(scaled, previous, 1.0, tol, its, maxiter)
            if decision == CONVERGED:
                status = STATUS_OK
                break
            if decision != CONTINUE:
                if refreshed:
                    break
                fresh = True  # factors of an earlier step: retry with the exact Jacobian
                previous = np.inf
                continue
            fresh = its >= 2 and scaled > SIMPLIFIED_CONTRACTION * previous and scaled > tol
            if fresh and not refreshed:
                # the Jacobian drifts too fast for the step: the next steps start with
                # one at their first iterate (as the general loop does)
                fresh_for = STALE_RETRY
            previous = scaled
        if status == STATUS_OK and n_dir + n_theta > 0 and not (current and fresh):
            # the Jacobian at the solution, which the directions need
            linearize(
                fn, fnp, tk, h, qk, C, prm, b, c, Phi, D, Q, V, F, FV, HQQ, HQV, HVV, HFV,
                TQ, TV, K, traits, pattern, couplings,
            )  # fmt: skip
            factored = factor_jacobian(K, piv, s, traits, pattern)
            if not factored:
                status = STATUS_SINGULAR
        elif status == STATUS_OK and not current:
            # no directions (a record for the adjoint, which linearises itself): the
            # gradients at the solution only, for the momentum
            for i in range(r):
                interpolate(i, inv_h, qk, C, Phi, D, Q, V)
                point_gradient(fn, tk + c[i] * h, Q, V, prm, F[i], FV[i])
        slot = k // save_every
        if its > iterations_out[slot]:
            iterations_out[slot] = min(its, 255)
        iteration_total[0] += its
        if status == STATUS_OK:
            for a in range(n):
                acc = 0.0
                for i in range(r):
                    acc += b[i] * F[i, a]
                dpk[a] = h * acc
                if not abs(dpk[a]) < 1e300:
                    status = STATUS_NONFINITE
        if status != STATUS_OK:
            if k % save_every != 0:
                row = saved
                saved = save_row(
                    saved, tk, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out, periodic
                )
                save_variations(row, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
            return status, k, saved, worst, increment
        if residual > worst:
            worst = residual
        if stages_out.shape[0] > 0:
            for nu in range(s1):
                for a in range(n):
                    stages_out[k, nu, a] = C[nu, a]
        if n_dir + n_theta == 1:
            # one direction (MEGNO, a largest exponent): vectors, not blocks of width 1
            for a in range(n):
                dq[a] = T[a, 0] if n_dir == 1 else S[a, 0]
                dp[a] = T[n + a, 0] if n_dir == 1 else S[n + a, 0]
            propagate(
                dq, dp, -1 if n_dir == 1 else 0, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ,
                TV, K, piv, rhs, dQ, dV, dLq, dLv, traits, pattern,
            )  # fmt: skip
            for a in range(n):
                if n_dir == 1:
                    T[a, 0] = dq[a]
                    T[n + a, 0] = dp[a]
                else:
                    S[a, 0] = dq[a]
                    S[n + a, 0] = dp[a]
        elif n_dir + n_theta > 1:
            for a in range(2 * n):
                for j in range(n_dir):
                    Wb[a, j] = T[a, j]
                for j in range(n_theta):
                    Wb[a, n_dir + j] = S[a, j]
            propagate_block(
                Wb, n_dir, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ, TV, K, piv, RB, dQb, dVb, dLqb,
                dLvb, traits, pattern,
            )  # fmt: skip
            for a in range(2 * n):
                for j in range(n_dir):
                    T[a, j] = Wb[a, j]
                for j in range(n_theta):
                    S[a, j] = Wb[a, n_dir + j]
        compensated_add(pk, p_lost, dpk)
        advance_position(qk, q_lost, C, turns, periodic)
        if chaos:
            due = (k + 1) % renormalize_every == 0
            if not advance_chaos(T, growth, sums, tk + h - t_origin, h, due):
                return STATUS_NONFINITE, k + 1, saved, worst, 0.0
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            row = saved
            saved = save_row(
                saved, t0 + (k + 1) * h, qk, q_lost, turns, pk, t_out, q_out, p_out, turns_out,
                periodic,
            )  # fmt: skip
            save_variations(row, T, S, growth, sums, T_out, S_out, growth_out, megno_out)
    finish_chaos(megno, sums, n_dir)
    return STATUS_OK, n_steps, saved, worst, 0.0


@driver
def adjoint_sweep(
    fn, traits, pattern, couplings, fnp, t_rows, q_rows, stages, prm, b, c, Phi, D, h, lam,
    running, grad,
):  # fmt: skip
    r"""The reverse pass over a recorded segment: :math:`\lambda \leftarrow
    (\partial x_{k+1}/\partial x_k)^T\lambda + \nabla\ell_k(x_k)` for k = N-1 .. 0.

    ``t_rows``, ``q_rows`` (N + 1 rows) and ``stages`` (N, s + 1, n) are the
    segment's states and control points as :func:`tangent_loop` records them;
    ``lam`` (2n) enters as the cotangent of :math:`x_N` and leaves as that of
    :math:`x_0`; ``running`` (N, 2n) holds :math:`\nabla\ell_k(x_k)`;
    ``grad`` (P) accumulates :math:`\sum_k (\partial x_{k+1}/\partial\theta)^T
    \lambda_{k+1}`. Returns False if a stage Jacobian is singular.
    """
    N = stages.shape[0]
    s1 = stages.shape[1]
    s = s1 - 1
    n = q_rows.shape[1]
    r = b.shape[0]
    n_theta = grad.shape[0]
    nnz = block_size(n, pattern)
    F, FV, HQQ, HQV, HVV, HFV, TQ, TV = make_tangent_work(r, s, n, nnz, n_theta)
    K = new_jacobian(s, n, traits, pattern)
    piv = np.zeros(s * n, dtype=np.int64)
    W = np.zeros(s * n)
    Q = np.zeros(n)
    V = np.zeros(n)
    dQ = np.zeros(n)
    dV = np.zeros(n)
    uq = np.zeros(n)
    uv = np.zeros(n)
    acc_q = np.zeros(n)
    qk = np.zeros(n)
    C = np.zeros((s1, n))
    for k in range(N - 1, -1, -1):
        for a in range(n):
            qk[a] = q_rows[k, a]
        for nu in range(s1):
            for a in range(n):
                C[nu, a] = stages[k, nu, a]
        linearize(
            fn, fnp, t_rows[k], h, qk, C, prm, b, c, Phi, D, Q, V, F, FV, HQQ, HQV, HVV, HFV,
            TQ, TV, K, traits, pattern, couplings,
        )  # fmt: skip
        if not factor_jacobian(K, piv, s, traits, pattern):
            return False
        pull_back(
            lam, grad, h, b, Phi, D, HQQ, HQV, HVV, HFV, TQ, TV, K, piv, W, dQ, dV, uq, uv,
            acc_q, traits, pattern,
        )  # fmt: skip
        for a in range(2 * n):
            lam[a] += running[k, a]
    return True
