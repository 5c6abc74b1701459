r"""Closed-form reference solutions for rigid bodies (issue 29).

Pure NumPy/SciPy: nothing here depends on :mod:`galerkin_vi.multibody`, so these
formulas serve as independent references for the rigid-body integrators.

- The torque-free (Euler–Poinsot) asymmetric body: the body angular velocity
  :math:`\omega(t)` in Jacobi elliptic functions (:func:`free_body_angular_velocity`),
  its period (:func:`free_body_period`), and the attitude :math:`R(t)`
  (:func:`free_body_rotation`) [LL76, §37], [CFSZ08].
- The tennis-racket (Dzhanibekov) flip near the intermediate axis
  (:func:`tennis_racket_period`, :func:`tennis_racket_flip_time`).
- The symmetric heavy (Lagrange) top: conserved momenta, nutation bounds and
  period, and :math:`\theta(t)` (:func:`lagrange_top_nutation`,
  :func:`lagrange_top_theta`) [Gol02, §5.7], [LL76, §35].
- The small oscillations of a body hanging from a ball joint
  (:func:`ball_joint_frequencies`).

Conventions: :math:`R` maps body to space coordinates; the body angular velocity
is :math:`\omega = (R^\top\dot R)^\vee`, so :math:`\dot R = R\,\hat\omega`; Euler's
equations are :math:`J\dot\omega = (J\omega)\times\omega` for the principal
moments :math:`J = \mathrm{diag}(J_1, J_2, J_3)`. Every function of ``t`` is
vectorised: ``t`` of any shape gives results of shape ``t.shape + (3,)``,
``t.shape + (3, 3)`` or ``t.shape``.

References
----------
.. [CFSZ08] E. Celledoni, F. Fassò, N. Säfström, A. Zanna, *The exact computation
   of the free rigid body motion and its use in splitting methods*, SIAM J. Sci.
   Comput. 30 (2008) 2084–2112.
.. [LL76] L. D. Landau, E. M. Lifshitz, *Mechanics*, 3rd ed., Pergamon 1976,
   §§35–37.
.. [Gol02] H. Goldstein, C. Poole, J. Safko, *Classical Mechanics*, 3rd ed.,
   Addison-Wesley 2002, §5.7.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "LagrangeTopNutation",
    "ball_joint_frequencies",
    "free_body_angular_velocity",
    "free_body_period",
    "free_body_rotation",
    "lagrange_top_nutation",
    "lagrange_top_theta",
    "tennis_racket_flip_time",
    "tennis_racket_period",
]

# relative distance to the separatrix M^2 = 2 E J_2 below which the elliptic modulus is 1
# to round-off and the elliptic solution does not exist
SEPARATRIX_RTOL = 64 * np.finfo(float).eps
# Gauss–Legendre nodes per subinterval and the longest subinterval (in the elliptic
# argument) for the precession angle; the integrand is analytic in a strip of half-width
# at least K(k') >= pi/2 about the real axis, so 24 nodes on unit intervals converge
# far below round-off
PRECESSION_NODES = 24
PRECESSION_MAX_STEP = 1.0


# ------------------------------------------------------------------ helpers
def _principal_moments(inertia: ArrayLike) -> NDArray[np.float64]:
    moments = np.asarray(inertia, dtype=float)
    if moments.shape != (3,):
        raise ValueError(
            f"inertia must be the 3 principal moments (J1, J2, J3), got shape {moments.shape}"
        )
    if not np.all(np.isfinite(moments)) or np.any(moments <= 0):
        raise ValueError(f"inertia must hold 3 positive finite moments, got {moments}")
    return moments


def _vector3(value: ArrayLike, name: str) -> NDArray[np.float64]:
    vector = np.asarray(value, dtype=float)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise ValueError(f"{name} must be a finite 3-vector, got {value!r}")
    return vector


def _rotation_matrix(value: ArrayLike, name: str) -> NDArray[np.float64]:
    matrix = np.asarray(value, dtype=float)
    if matrix.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 rotation matrix, got shape {matrix.shape}")
    if not np.allclose(matrix.T @ matrix, np.eye(3), atol=1e-12) or np.linalg.det(matrix) <= 0:
        raise ValueError(f"{name} must be a rotation matrix (R^T R = I, det R = 1)")
    return matrix


def _hat(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """The skew matrices :math:`\\hat w` with :math:`\\hat w x = w \\times x`, over leading axes."""
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def _axis_rotation(axis: NDArray[np.float64], angle: NDArray[np.float64]) -> NDArray[np.float64]:
    r"""Rodrigues: :math:`I + \sin\alpha\,\hat n + (1 - \cos\alpha)\,\hat n^2` for a unit ``axis``."""
    n_hat = _hat(axis)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * n_hat + (1.0 - c) * (n_hat @ n_hat)


def _aligning_rotation(n: NDArray[np.float64], m: NDArray[np.float64]) -> NDArray[np.float64]:
    r"""The rotation of least angle taking the unit vector ``n`` to the unit vectors ``m``.

    :math:`S = I + \hat a + \hat a^2/(1 + c)` with :math:`a = n\times m`, :math:`c = n\cdot m`,
    regular wherever :math:`m \ne -n`.
    """
    a = np.cross(n, m)
    c = m @ n
    a_hat = _hat(a)
    return np.eye(3) + a_hat + (a_hat @ a_hat) / (1.0 + c)[..., None, None]


def _times(t: ArrayLike) -> NDArray[np.float64]:
    times = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(times)):
        raise ValueError("t must be finite")
    return times


# ------------------------------------------------------------------ free rigid body
@dataclass(frozen=True)
class _EulerPoinsot:
    r"""The elliptic solution of Euler's equations written about the axis ``c``.

    :math:`\omega_a = A_a\,\mathrm{cn}(u)`, :math:`\omega_b = A_b\,\mathrm{sn}(u)`,
    :math:`\omega_c = A_c\,\mathrm{dn}(u)`, :math:`u = \lambda t + u_0`, modulus
    :math:`k^2` = ``m``; ``b`` is the intermediate axis, ``c`` the axis the body
    turns about (the largest or the smallest moment).
    """

    axes: tuple[int, int, int]
    amplitudes: tuple[float, float, float]
    rate: float
    m: float
    u0: float
    energy: float  # 2E = omega . J omega
    momentum: float  # |M| = |J omega|
    moments: tuple[float, float, float]

    @property
    def quarter_period(self) -> float:
        """The complete elliptic integral :math:`K(k)`."""
        from scipy.special import ellipk  # here: SciPy adds 35 MB to every process

        return float(ellipk(self.m))

    def omega(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        from scipy.special import ellipj

        sn, cn, dn, _ = ellipj(self.rate * t + self.u0, self.m)
        a, b, c = self.axes
        out = np.empty(t.shape + (3,))
        out[..., a] = self.amplitudes[0] * cn
        out[..., b] = self.amplitudes[1] * sn
        out[..., c] = self.amplitudes[2] * dn
        return out


def _permutation_sign(a: int, b: int, c: int) -> int:
    """+1 if (a, b, c) is a cyclic permutation of (0, 1, 2), -1 otherwise."""
    return int(np.sign((b - a) * (c - a) * (c - b)))


@cache
def _euler_poinsot(moments: tuple[float, ...], omega0: tuple[float, ...]) -> _EulerPoinsot:
    r"""Write the motion from ``omega0`` in elliptic functions ([LL76] §37, [CFSZ08] §2).

    With :math:`2E = \sum J_i\omega_i^2`, :math:`M^2 = \sum J_i^2\omega_i^2` and the
    intermediate moment :math:`J_b`, the body turns about the axis :math:`c` of the
    largest moment if :math:`M^2 > 2EJ_b` and of the smallest if :math:`M^2 < 2EJ_b`;
    :math:`a` is the remaining axis. Then

    .. math::

        A_a^2 = \frac{2EJ_c - M^2}{J_a(J_c - J_a)},\quad
        A_b^2 = \frac{2EJ_c - M^2}{J_b(J_c - J_b)},\quad
        A_c^2 = \frac{M^2 - 2EJ_a}{J_c(J_c - J_a)},

        \lambda^2 = \frac{(J_c - J_b)(M^2 - 2EJ_a)}{J_aJ_bJ_c},\quad
        k^2 = \frac{(J_b - J_a)(2EJ_c - M^2)}{(J_c - J_b)(M^2 - 2EJ_a)},

    all quotients positive in both cases. Euler's equations about the axes
    :math:`(a, b, c)` read :math:`J_a\dot\omega_a = \epsilon(J_b - J_c)\omega_b\omega_c`
    and cyclically, :math:`\epsilon` the sign of the permutation; with
    :math:`\mathrm{sn}' = \mathrm{cn}\,\mathrm{dn}`, :math:`\mathrm{cn}' = -\mathrm{sn}\,\mathrm{dn}`,
    :math:`\mathrm{dn}' = -k^2\mathrm{sn}\,\mathrm{cn}` they hold for :math:`\lambda > 0`,
    :math:`A_a > 0`, :math:`\mathrm{sign} A_c = \mathrm{sign}\,\omega_c(0)` (constant: dn > 0)
    and :math:`\mathrm{sign} A_b = \epsilon\,\mathrm{sign}(J_c - J_b)\,\mathrm{sign} A_c`.
    The phase :math:`u_0 = F(\varphi_0 \mid k^2)` has
    :math:`(\cos\varphi_0, \sin\varphi_0) \propto (\omega_a(0)/A_a, \omega_b(0)/A_b)`.
    Equal moments give :math:`k = 0` (the symmetric top written about its symmetry
    axis); a sphere, or :math:`\omega_0 = 0`, gives a constant :math:`\omega`
    (``rate`` 0).
    """
    from scipy.special import ellipkinc

    J = np.array(moments)
    w = np.array(omega0)
    two_e = float(J @ w**2)
    m_sq = float((J * w) @ (J * w))
    lo, mid, hi = (int(i) for i in np.argsort(J, kind="stable"))
    if m_sq == 0.0 or J[lo] == J[hi]:
        return _EulerPoinsot((lo, mid, hi), (w[lo], w[mid], w[hi]), 0.0, 0.0, 0.0, two_e,
                             np.sqrt(m_sq), moments)
    if J[lo] == J[mid]:
        about_largest = True
    elif J[mid] == J[hi]:
        about_largest = False
    else:
        gap = (m_sq - two_e * J[mid]) / m_sq
        if abs(gap) <= SEPARATRIX_RTOL:
            raise ValueError(
                "omega0 lies on the separatrix M^2 = 2 E J2 of the intermediate axis "
                f"(relative gap {gap:.1e}): the elliptic modulus is 1 and the motion is "
                "a heteroclinic orbit, not periodic"
            )
        about_largest = gap > 0
    a, b, c = (lo, mid, hi) if about_largest else (hi, mid, lo)
    ja, jb, jc = J[a], J[b], J[c]
    # clipped at 0: a rotation about a principal axis makes a numerator vanish to round-off
    amp_a = np.sqrt(max((two_e * jc - m_sq) / (ja * (jc - ja)), 0.0))
    amp_b = np.sqrt(max((two_e * jc - m_sq) / (jb * (jc - jb)), 0.0))
    amp_c = np.sqrt(max((m_sq - two_e * ja) / (jc * (jc - ja)), 0.0))
    rate = np.sqrt((jc - jb) * (m_sq - two_e * ja) / (ja * jb * jc))
    m = min(max((jb - ja) * (two_e * jc - m_sq) / ((jc - jb) * (m_sq - two_e * ja)), 0.0), 1.0)
    sign_c = 1.0 if w[c] >= 0 else -1.0
    sign_b = _permutation_sign(a, b, c) * np.sign(jc - jb) * sign_c
    amp_c *= sign_c
    amp_b *= sign_b
    if amp_a == 0.0 and amp_b == 0.0:
        u0 = 0.0
    else:
        cos_phi = w[a] / amp_a if amp_a > 0 else 0.0
        sin_phi = w[b] / amp_b if amp_b != 0 else 0.0
        u0 = float(ellipkinc(np.arctan2(sin_phi, cos_phi), m))
    return _EulerPoinsot((a, b, c), (amp_a, amp_b, amp_c), float(rate), float(m), u0, two_e,
                         float(np.sqrt(m_sq)), moments)


def _free_body(inertia: ArrayLike, omega0: ArrayLike) -> _EulerPoinsot:
    moments = _principal_moments(inertia)
    w0 = _vector3(omega0, "omega0")
    return _euler_poinsot(tuple(float(x) for x in moments), tuple(float(x) for x in w0))


def free_body_angular_velocity(
    inertia: ArrayLike, omega0: ArrayLike, t: float | ArrayLike
) -> NDArray[np.float64]:
    r"""Body angular velocity of the torque-free rigid body in Jacobi elliptic functions.

    Solves Euler's equations :math:`J\dot\omega = (J\omega)\times\omega`,
    :math:`\omega(0) = \omega_0`, exactly ([LL76] §37, [CFSZ08] §2). With the
    invariants :math:`2E = \sum_i J_i\omega_i^2` and :math:`M^2 = \sum_i J_i^2\omega_i^2`
    and the intermediate moment :math:`J_b`, the body turns about the axis :math:`c`
    of the largest moment when :math:`M^2 > 2EJ_b` and of the smallest when
    :math:`M^2 < 2EJ_b` (:math:`a` the remaining axis), and

    .. math::

        \omega_a = A_a\,\mathrm{cn}(\lambda t + u_0 \mid k^2),\quad
        \omega_b = A_b\,\mathrm{sn}(\lambda t + u_0 \mid k^2),\quad
        \omega_c = A_c\,\mathrm{dn}(\lambda t + u_0 \mid k^2),

    .. math::

        A_a^2 = \frac{2EJ_c - M^2}{J_a(J_c - J_a)},\quad
        A_b^2 = \frac{2EJ_c - M^2}{J_b(J_c - J_b)},\quad
        A_c^2 = \frac{M^2 - 2EJ_a}{J_c(J_c - J_a)},\quad
        \lambda^2 = \frac{(J_c - J_b)(M^2 - 2EJ_a)}{J_aJ_bJ_c},\quad
        k^2 = \frac{(J_b - J_a)(2EJ_c - M^2)}{(J_c - J_b)(M^2 - 2EJ_a)}.

    The signs: :math:`A_a > 0`, :math:`A_c` has the (constant) sign of
    :math:`\omega_c(0)`, :math:`A_b = \epsilon\,\mathrm{sign}(J_c - J_b)\,\mathrm{sign}(A_c)|A_b|`
    with :math:`\epsilon = \pm 1` the parity of the permutation :math:`(a, b, c)`; the
    phase is :math:`u_0 = F(\varphi_0 \mid k^2)` with
    :math:`\cos\varphi_0 = \omega_a(0)/A_a`, :math:`\sin\varphi_0 = \omega_b(0)/A_b`.
    The moments may come in any order; two equal moments give :math:`k = 0` (the
    symmetric top), three equal a constant :math:`\omega`.

    Parameters
    ----------
    inertia : array_like, shape (3,)
        The principal moments :math:`(J_1, J_2, J_3)` (the body frame is the principal frame).
    omega0 : array_like, shape (3,)
        The body angular velocity at :math:`t = 0`.
    t : float or array_like
        Times.

    Returns
    -------
    ndarray, shape ``t.shape + (3,)``
        :math:`\omega(t)` in the body frame.

    Raises
    ------
    ValueError
        If the moments are not 3 positive numbers, or :math:`\omega_0` lies on the
        separatrix :math:`M^2 = 2EJ_b` (:math:`k = 1`; the heteroclinic motion towards
        the unstable rotation about the intermediate axis, including that rotation itself).
        Near the separatrix, :math:`1 - k^2 < 10^{-9}`, SciPy's ``ellipj`` loses accuracy.
    """
    times = _times(t)
    return _free_body(inertia, omega0).omega(times)


def free_body_period(inertia: ArrayLike, omega0: ArrayLike) -> float:
    r"""The period :math:`T = 4K(k)/\lambda` of the body angular velocity :math:`\omega(t)`.

    In the notation of :func:`free_body_angular_velocity`, cn and sn have the period
    :math:`4K(k)` (dn has :math:`2K(k)`), so :math:`\omega(t + T) = \omega(t)` with
    :math:`T = 4K(k)/\lambda`, the complete elliptic integral
    :math:`K(k) = \int_0^{\pi/2}(1 - k^2\sin^2\varphi)^{-1/2}\,d\varphi`. For a
    symmetric body (:math:`k = 0`) this is :math:`2\pi/\lambda`, the period of the
    precession of :math:`\omega` about the symmetry axis; for a permanent rotation
    about the largest or smallest axis it is the period of the nearby motions.
    The attitude :math:`R(t)` is in general not periodic.

    Returns
    -------
    float
        The period, ``inf`` when :math:`\omega` is constant for every :math:`\omega_0`
        (three equal moments) or :math:`\omega_0 = 0`.

    Raises
    ------
    ValueError
        As :func:`free_body_angular_velocity` (on the separatrix the period is infinite).
    """
    solution = _free_body(inertia, omega0)
    if solution.rate == 0.0:
        return float("inf")
    return 4.0 * solution.quarter_period / solution.rate


def tennis_racket_period(inertia: ArrayLike, omega0: ArrayLike) -> float:
    r"""The period of the tennis-racket (Dzhanibekov) motion: two flips.

    For a body set spinning close to its intermediate axis :math:`b`, the component
    :math:`\omega_b = A_b\,\mathrm{sn}(\lambda t + u_0 \mid k^2)` stays near
    :math:`\pm|A_b|` for long stretches (:math:`k \to 1`) and reverses its sign quickly
    between them: the flip. sn has the zeros :math:`2jK(k)`, so the sign reversals are
    exactly :math:`2K(k)/\lambda` apart (:func:`tennis_racket_flip_time`) and one period
    of :math:`\omega(t)`,

    .. math:: T = \frac{4K(k)}{\lambda}
              = 4K(k)\sqrt{\frac{J_aJ_bJ_c}{(J_c - J_b)(M^2 - 2EJ_a)}},

    contains two flips (there and back), after which :math:`\omega_b` returns to its
    initial value. The same as :func:`free_body_period`; the statement holds for every
    :math:`\omega_0` off the separatrix, the flips being sharp near the intermediate axis.
    As :math:`\omega_0 \to \omega e_b` with a small transverse part, :math:`T` grows like
    :math:`(2/\lambda)\ln(16/(1 - k^2))`.
    """
    return free_body_period(inertia, omega0)


def tennis_racket_flip_time(inertia: ArrayLike, omega0: ArrayLike) -> float:
    r"""The time :math:`2K(k)/\lambda` between two successive flips (half of
    :func:`tennis_racket_period`): the spacing of the zeros of the intermediate
    component :math:`\omega_b(t)`."""
    return tennis_racket_period(inertia, omega0) / 2.0


def _precession_integrand(solution: _EulerPoinsot, u: NDArray[np.float64]) -> NDArray[np.float64]:
    r""":math:`\dot\psi` at the elliptic argument ``u``: :math:`(2E + |M|\,|\omega_c|)/(|M| +
    J_c|\omega_c|)` with :math:`|\omega_c| = |A_c|\,\mathrm{dn}(u)`."""
    from scipy.special import ellipj

    _, _, dn, _ = ellipj(u, solution.m)
    spin = abs(solution.amplitudes[2]) * dn
    j_c = solution.moments[solution.axes[2]]
    return (solution.energy + solution.momentum * spin) / (solution.momentum + j_c * spin)


def _precession_primitive(solution: _EulerPoinsot, u: NDArray[np.float64]) -> NDArray[np.float64]:
    r""":math:`G(u) = \int_0^u \dot\psi(\tau)\,d\tau` (per unit :math:`\lambda`).

    The integrand has the period :math:`2K` of dn: :math:`G(u) = n\,G(2K) + G(r)`,
    :math:`u = 2Kn + r`, and :math:`G(r)` by Gauss–Legendre on
    ``ceil(2K / PRECESSION_MAX_STEP)`` equal subintervals of :math:`[0, r]`.
    """
    period = 2.0 * solution.quarter_period
    n_sub = max(1, int(np.ceil(period / PRECESSION_MAX_STEP)))
    nodes, weights = np.polynomial.legendre.leggauss(PRECESSION_NODES)

    def partial(r: NDArray[np.float64]) -> NDArray[np.float64]:
        step = r / n_sub
        total = np.zeros_like(r)
        for j in range(n_sub):
            tau = step[..., None] * (j + (nodes + 1.0) / 2.0)
            total += _precession_integrand(solution, tau) @ weights * step / 2.0
        return total

    turns = np.floor(u / period)
    full = partial(np.array(period))
    return turns * full + partial(u - turns * period)


def free_body_rotation(
    inertia: ArrayLike, omega0: ArrayLike, R0: ArrayLike, t: float | ArrayLike
) -> NDArray[np.float64]:
    r"""Attitude :math:`R(t)` (body to space) of the torque-free rigid body.

    Solves :math:`\dot R = R\,\hat\omega` with :math:`\omega(t)` from
    :func:`free_body_angular_velocity`, :math:`R(0) = R_0`, after [CFSZ08] §2 and
    [LL76] §37: the space angular momentum :math:`R\,m` (:math:`m = J\omega`) is
    constant, so with any rotations :math:`S(t)` taking a fixed unit vector :math:`n`
    to :math:`\hat m(t) = m(t)/|M|`,

    .. math:: R(t) = R_0\,S(0)\,\exp(\psi(t)\,\hat n)\,S(t)^\top,\qquad
              \dot\psi = \omega\cdot\hat m - (S\dot S^\top)^\vee\cdot\hat m .

    Here :math:`n = \mathrm{sign}(\omega_c)\,e_c` (the axis :math:`c` the body turns
    about, which :math:`\hat m` never leaves the hemisphere of) and :math:`S` the
    rotation of least angle from :math:`n` to :math:`\hat m`,
    :math:`S = I + \hat a + \hat a^2/(1 + n\cdot\hat m)`, :math:`a = n\times\hat m`. Then
    :math:`\omega\cdot\hat m = 2E/|M|`, :math:`\dot{\hat m} = \hat m\times\omega`, and

    .. math:: \dot\psi = \frac{2E + |M|\,|\omega_c|}{|M| + J_c|\omega_c|},\qquad
              |\omega_c| = |A_c|\,\mathrm{dn}(\lambda t + u_0 \mid k^2),

    a smooth positive function of period :math:`2K(k)/\lambda`. Its integral is an
    incomplete elliptic integral of the third kind, which SciPy lacks; it is computed
    as :math:`\psi(t) = (G(\lambda t + u_0) - G(u_0))/\lambda` with
    :math:`G(u) = \int_0^u`, a whole number of periods times the integral over one
    plus a remainder, each by 24-point Gauss–Legendre on subintervals of length
    :math:`\le 1` in :math:`u`. The integrand is analytic in a strip of half-width
    :math:`\ge K(k') \ge \pi/2` about the real axis, so these rules are exact to
    round-off.

    Parameters
    ----------
    inertia : array_like, shape (3,)
        The principal moments (the body frame is the principal frame).
    omega0 : array_like, shape (3,)
        The body angular velocity at :math:`t = 0`.
    R0 : array_like, shape (3, 3)
        The attitude at :math:`t = 0`, a rotation matrix.
    t : float or array_like
        Times.

    Returns
    -------
    ndarray, shape ``t.shape + (3, 3)``
        :math:`R(t)`.

    Raises
    ------
    ValueError
        As :func:`free_body_angular_velocity`, or if ``R0`` is not a rotation matrix.
    """
    times = _times(t)
    rotation0 = _rotation_matrix(R0, "R0")
    solution = _free_body(inertia, omega0)
    if solution.rate == 0.0:  # constant omega: R0 exp(t hat(omega0))
        w0 = _vector3(omega0, "omega0")
        speed = np.linalg.norm(w0)
        if speed == 0.0:
            return np.broadcast_to(rotation0, times.shape + (3, 3)).copy()
        return rotation0 @ _axis_rotation(w0 / speed, speed * times)
    moments = np.asarray(solution.moments)
    c = solution.axes[2]
    n = np.zeros(3)
    n[c] = np.sign(solution.amplitudes[2]) or 1.0
    m_hat0 = moments * solution.omega(np.array(0.0)) / solution.momentum
    m_hat = moments * solution.omega(times) / solution.momentum
    u = solution.rate * times + solution.u0
    psi = (_precession_primitive(solution, u) - _precession_primitive(solution, np.array(
        solution.u0))) / solution.rate
    return (
        rotation0
        @ _aligning_rotation(n, m_hat0 / np.linalg.norm(m_hat0))
        @ _axis_rotation(n, psi)
        @ np.swapaxes(_aligning_rotation(n, m_hat / np.linalg.norm(m_hat, axis=-1,
                                                                   keepdims=True)), -1, -2)
    )
