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
    "ball_joint_modes",
    "free_body_angular_velocity",
    "free_body_period",
    "free_body_rotation",
    "lagrange_top_nutation",
    "lagrange_top_theta",
    "tennis_racket_flip_time",
    "tennis_racket_period",
]

# the least complementary modulus 1 - k^2 accepted: the range in which the elliptic
# functions here are verified to round-off (scipy.special.ellipj itself switches to an
# expansion below 1e-10 that fails over a whole period)
MIN_COMPLEMENTARY_MODULUS = 1e-10
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
    r"""Rodrigues: :math:`I + \sin\alpha\,\hat n + (1 - \cos\alpha)\,\hat n^2` (unit n)."""
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


def _jacobi_agm(
    v: NDArray[np.float64], k: float, k_prime: float
) -> tuple[NDArray[np.float64], ...]:
    r"""sn, cn, dn by the arithmetic-geometric mean (Abramowitz–Stegun 16.4), started from
    the given :math:`k` and :math:`k'` so that :math:`k'` keeps its relative accuracy as
    :math:`k \to 1` (``scipy.special.ellipj`` forms :math:`k' = \sqrt{1 - m}` from the
    rounded :math:`m`). :math:`a_0 = 1`, :math:`b_0 = k'`, :math:`c_0 = k`;
    :math:`a_n = (a_{n-1} + b_{n-1})/2`, :math:`b_n = \sqrt{a_{n-1}b_{n-1}}`,
    :math:`c_n = c_{n-1}^2/(4a_n)` until :math:`c_N/a_N < \epsilon/4`;
    :math:`\varphi_N = 2^Na_Nv`,
    :math:`\varphi_{n-1} = (\varphi_n + \arcsin(c_n\sin\varphi_n/a_n))/2`; then
    :math:`\mathrm{sn} = \sin\varphi_0`, :math:`\mathrm{cn} = \cos\varphi_0`,
    :math:`\mathrm{dn} = \cos\varphi_0/\cos(\varphi_1 - \varphi_0)`.
    """
    a, b, c = [1.0], [k_prime], [k]
    while c[-1] > np.finfo(float).eps / 4 * a[-1] and len(a) < 40:
        a_next = (a[-1] + b[-1]) / 2
        b.append(np.sqrt(a[-1] * b[-1]))
        c.append(c[-1] ** 2 / (4 * a_next))
        a.append(a_next)
    n = len(a) - 1
    phi = 2.0**n * a[n] * v
    previous = phi
    for i in range(n, 0, -1):
        previous = phi
        phi = (phi + np.arcsin(c[i] / a[i] * np.sin(phi))) / 2
    if n == 0:  # k = 0: sn = sin, cn = cos, dn = 1
        return np.sin(phi), np.cos(phi), np.ones_like(phi)
    return np.sin(phi), np.cos(phi), np.cos(phi) / np.cos(previous - phi)


def _jacobi(u: NDArray[np.float64], m: float, m1: float) -> tuple[NDArray[np.float64], ...]:
    r"""sn, cn, dn of ``u`` for the parameter :math:`m = k^2 < 1`, :math:`m_1 = 1 - m`.

    The period :math:`4K` and the half-period shift (sn, cn change sign) bring :math:`u`
    to :math:`[-K, K]`; beyond :math:`|u| > K/2`, with :math:`v = K - |u|`,
    :math:`\mathrm{sn} = \mathrm{cn}\,v/\mathrm{dn}\,v`,
    :math:`\mathrm{cn} = k'\,\mathrm{sn}\,v/\mathrm{dn}\,v`,
    :math:`\mathrm{dn} = k'/\mathrm{dn}\,v`, where nothing cancels (cn and dn are small
    near :math:`u = K` as :math:`k \to 1`); :func:`_jacobi_agm` at :math:`|v| \le K/2`.
    ``m1`` is passed where it is known more accurately than the rounded ``1 - m``
    (:math:`K` and :math:`k'` depend on it with the condition number :math:`1/m_1`).
    """
    from scipy.special import ellipkm1

    quarter = float(ellipkm1(m1))
    complementary = np.sqrt(m1)
    r = u - 4.0 * quarter * np.round(u / (4.0 * quarter))
    flip = np.where(np.abs(r) > quarter, -1.0, 1.0)
    r = np.where(np.abs(r) > quarter, r - 2.0 * quarter * np.sign(r), r)
    sign = np.where(r < 0, -1.0, 1.0)
    near = np.abs(r) > quarter / 2
    v = np.where(near, quarter - np.abs(r), np.abs(r))
    sn_v, cn_v, dn_v = _jacobi_agm(v, np.sqrt(m), complementary)
    sn = np.where(near, cn_v / dn_v, sn_v) * sign * flip
    cn = np.where(near, complementary * sn_v / dn_v, cn_v) * flip
    dn = np.where(near, complementary / dn_v, dn_v)
    return sn, cn, dn


def _elliptic_argument(sn: float, cn: float, m: float, m1: float) -> float:
    r"""An argument :math:`u` with :math:`\mathrm{sn}\,u` = ``sn``, :math:`\mathrm{cn}\,u` = ``cn``.

    :math:`u = F(\varphi \mid m)`, :math:`\varphi = \mathrm{atan2}(\mathrm{sn}, \mathrm{cn})`,
    brought to :math:`|\varphi| \le \pi/2` by the half-period shift; where
    :math:`|u| > K/2` (:math:`|\mathrm{sn}| > (1 + k')^{-1/2}`) it is
    :math:`\pm(K - F(\vartheta \mid m))` with :math:`\vartheta = \mathrm{atan2}(\mathrm{cn},
    k'|\mathrm{sn}|)`, well conditioned where :math:`\varphi \approx \pm\pi/2`.
    """
    from scipy.special import ellipkinc, ellipkm1

    quarter = float(ellipkm1(m1))
    complementary = np.sqrt(m1)
    shift = 0.0
    if cn < 0:
        shift = 2.0 * quarter if sn >= 0 else -2.0 * quarter
        sn, cn = -sn, -cn
    sign = -1.0 if sn < 0 else 1.0
    if abs(sn) <= 1.0 / np.sqrt(1.0 + complementary):
        return shift + sign * float(ellipkinc(np.arctan2(abs(sn), cn), m))
    return shift + sign * (quarter - float(ellipkinc(np.arctan2(cn, complementary * abs(sn)), m)))


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
    m1: float  # 1 - m, from the distance to the separatrix
    u0: float
    energy: float  # 2E = omega . J omega
    momentum: float  # |M| = |J omega|
    moments: tuple[float, float, float]
    omega0: tuple[float, float, float]

    @property
    def quarter_period(self) -> float:
        """The complete elliptic integral :math:`K(k)`."""
        from scipy.special import ellipkm1  # here: SciPy adds 35 MB to every process

        return float(ellipkm1(self.m1))

    def omega(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        if self.rate == 0.0:  # omega constant (a sphere, or at rest)
            return np.broadcast_to(np.array(self.omega0), t.shape + (3,)).copy()
        sn, cn, dn = _jacobi(self.rate * t + self.u0, self.m, self.m1)
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
    :math:`\mathrm{sn}' = \mathrm{cn}\,\mathrm{dn}`,
    :math:`\mathrm{cn}' = -\mathrm{sn}\,\mathrm{dn}`,
    :math:`\mathrm{dn}' = -k^2\mathrm{sn}\,\mathrm{cn}` they hold for :math:`\lambda > 0`,
    :math:`A_a > 0`, :math:`\mathrm{sign} A_c = \mathrm{sign}\,\omega_c(0)` (constant: dn > 0)
    and :math:`\mathrm{sign} A_b = \epsilon\,\mathrm{sign}(J_c - J_b)\,\mathrm{sign} A_c`.
    The phase :math:`u_0 = F(\varphi_0 \mid k^2)` has
    :math:`(\cos\varphi_0, \sin\varphi_0) \propto (\omega_a(0)/A_a, \omega_b(0)/A_b)`.
    Equal moments give :math:`k = 0` (the symmetric top written about its symmetry
    axis); a sphere, or :math:`\omega_0 = 0`, gives a constant :math:`\omega`
    (``rate`` 0).
    """
    J = np.array(moments)
    w = np.array(omega0)
    two_e = float(J @ w**2)
    m_sq = float((J * w) @ (J * w))
    lo, mid, hi = (int(i) for i in np.argsort(J, kind="stable"))
    if m_sq == 0.0 or J[lo] == J[hi]:
        return _EulerPoinsot(
            (lo, mid, hi),
            (0.0, 0.0, 0.0),
            0.0,
            0.0,
            1.0,
            0.0,
            two_e,
            float(np.sqrt(m_sq)),
            moments,
            omega0,
        )

    def excess(k: int) -> float:
        # M^2 - 2 E J_k = sum_i J_i w_i^2 (J_i - J_k) without the term i = k, which cancels:
        # accurate near the rotation about the axis k
        return float(sum(J[i] * w[i] ** 2 * (J[i] - J[k]) for i in range(3) if i != k))

    if J[lo] == J[mid]:
        about_largest = True
    elif J[mid] == J[hi]:
        about_largest = False
    else:
        about_largest = excess(mid) > 0
    a, b, c = (lo, mid, hi) if about_largest else (hi, mid, lo)
    ja, jb, jc = J[a], J[b], J[c]
    over_a, under_c = excess(a), -excess(c)  # M^2 - 2EJ_a and 2EJ_c - M^2, both > 0
    # clipped at 0: a rotation about a principal axis makes a numerator vanish to round-off
    amp_a = np.sqrt(max(under_c / (ja * (jc - ja)), 0.0))
    amp_b = np.sqrt(max(under_c / (jb * (jc - jb)), 0.0))
    amp_c = np.sqrt(max(over_a / (jc * (jc - ja)), 0.0))
    rate = np.sqrt((jc - jb) * over_a / (ja * jb * jc))
    m = min(max((jb - ja) * under_c / ((jc - jb) * over_a), 0.0), 1.0)
    complementary = 1.0 - m
    if J[lo] < J[mid] < J[hi]:
        # 1 - k^2 = (J_c - J_a)(M^2 - 2EJ_b) / ((J_c - J_b)(M^2 - 2EJ_a)): 0 on the separatrix
        complementary = (jc - ja) * excess(b) / ((jc - jb) * over_a)
        if complementary < MIN_COMPLEMENTARY_MODULUS:
            raise ValueError(
                "omega0 lies on or too near the separatrix M^2 = 2 E J2 of the intermediate "
                f"axis: 1 - k^2 = {complementary:.1e} < {MIN_COMPLEMENTARY_MODULUS:.0e}. On it "
                "the motion is a heteroclinic orbit, not periodic; nearer than that the "
                "elliptic functions are not verified"
            )
    sign_c = 1.0 if w[c] >= 0 else -1.0
    sign_b = _permutation_sign(a, b, c) * np.sign(jc - jb) * sign_c
    amp_c *= sign_c
    amp_b *= sign_b
    if amp_a == 0.0 and amp_b == 0.0:
        u0 = 0.0
    else:
        cos_phi = w[a] / amp_a if amp_a > 0 else 0.0
        sin_phi = w[b] / amp_b if amp_b != 0 else 0.0
        u0 = _elliptic_argument(sin_phi, cos_phi, m, complementary)
    return _EulerPoinsot(
        (a, b, c),
        (amp_a, amp_b, amp_c),
        float(rate),
        float(m),
        float(complementary),
        u0,
        two_e,
        float(np.sqrt(m_sq)),
        moments,
        omega0,
    )


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
        the unstable rotation about the intermediate axis, including that rotation itself)
        or so near it that :math:`1 - k^2 = (J_c - J_a)(M^2 - 2EJ_b)/((J_c - J_b)(M^2 -
        2EJ_a)) < 10^{-10}`, beyond the verified range of the elliptic functions (for
        :math:`J = (1, 2, 3)`, :math:`\omega_0 = (\varepsilon, 2, \varepsilon)` with
        :math:`\varepsilon < 3\cdot 10^{-5}`).
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
    _, _, dn = _jacobi(u, solution.m, solution.m1)
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
    psi = (
        _precession_primitive(solution, u) - _precession_primitive(solution, np.array(solution.u0))
    ) / solution.rate
    return (
        rotation0
        @ _aligning_rotation(n, m_hat0 / np.linalg.norm(m_hat0))
        @ _axis_rotation(n, psi)
        @ np.swapaxes(
            _aligning_rotation(n, m_hat / np.linalg.norm(m_hat, axis=-1, keepdims=True)), -1, -2
        )
    )


# ------------------------------------------------------------------ Lagrange top
@dataclass(frozen=True)
class LagrangeTopNutation:
    r"""Conserved quantities and nutation of a symmetric heavy (Lagrange) top.

    Attributes
    ----------
    p_phi : float
        :math:`p_\varphi = I_1\dot\varphi\sin^2\theta + p_\psi\cos\theta`, the angular
        momentum about the vertical.
    p_psi : float
        :math:`p_\psi = I_3(\dot\psi + \dot\varphi\cos\theta) = I_3\omega_3`, the angular
        momentum about the symmetry axis.
    energy : float
        :math:`E = \tfrac12 I_1(\dot\theta^2 + \dot\varphi^2\sin^2\theta)
        + p_\psi^2/(2I_3) + mgl\cos\theta`.
    theta_min, theta_max : float
        The nutation bounds, :math:`\theta_{\min} = \arccos u_2`,
        :math:`\theta_{\max} = \arccos u_1`.
    period : float
        The nutation period :math:`T = 2\int_{u_1}^{u_2} du/\sqrt{f(u)} = 2K(k)/\lambda`
        (the time from :math:`\theta_{\max}` to :math:`\theta_{\max}`).
    roots : tuple of float
        The roots :math:`u_1 \le u_2` in :math:`[-1, 1]` and :math:`u_3 \ge 1` of the
        cubic :math:`f(u)`.
    modulus : float
        :math:`k^2 = (u_2 - u_1)/(u_3 - u_1)`.
    complementary_modulus : float
        :math:`1 - k^2 = (u_3 - u_2)/(u_3 - u_1)`.
    rate : float
        :math:`\lambda = \tfrac12\sqrt{\beta(u_3 - u_1)}`, :math:`\beta = 2mgl/I_1`.
    phase : float
        :math:`w_0`, the elliptic argument at :math:`t = 0`.
    """

    p_phi: float
    p_psi: float
    energy: float
    theta_min: float
    theta_max: float
    period: float
    roots: tuple[float, float, float]
    modulus: float
    complementary_modulus: float
    rate: float
    phase: float

    def theta(self, t: float | ArrayLike) -> NDArray[np.float64]:
        r""":math:`\theta(t) = \arccos(u_1 + (u_2 - u_1)\,\mathrm{sn}^2(\lambda t + w_0 | k^2))`."""
        times = _times(t)
        u1, u2, _ = self.roots
        sn, _, _ = _jacobi(self.rate * times + self.phase, self.modulus, self.complementary_modulus)
        return np.arccos(np.clip(u1 + (u2 - u1) * sn**2, -1.0, 1.0))


def _cubic_roots_about(
    coefficients: tuple[float, float, float, float], right: float, left: float
) -> tuple[float, float, float]:
    r"""The roots :math:`x_1 \le 0 \le x_2 \le x_3` of :math:`f(x) = f_0 + f_1x + f_2x^2 + f_3x^3`,
    :math:`f_0 \ge 0`, :math:`f_3 > 0`, :math:`f(left) \le 0 \ge f(right)`, ``left <= 0 <= right``.

    With :math:`f_0 > 0` the roots in the brackets by Brent's method, :math:`x_3` by
    Vieta (:math:`x_1 + x_2 + x_3 = -f_2/f_3`); with :math:`f_0 = 0`, :math:`x = 0` is a
    root and the others are those of :math:`f_3x^2 + f_2x + f_1` (in the stable form).
    """
    f0, f1, f2, f3 = coefficients
    if f0 > 0.0:
        from scipy.optimize import brentq  # here: scipy.optimize is slow to import

        def f(x: float) -> float:
            return f0 + x * (f1 + x * (f2 + x * f3))

        # the bracket ends are roots or beyond them up to rounding
        x1 = brentq(f, left, 0.0, xtol=1e-300) if f(left) < 0.0 else left
        x2 = brentq(f, 0.0, right, xtol=1e-300) if f(right) < 0.0 else right
        return x1, x2, -f2 / f3 - x1 - x2
    disc = max(f2 * f2 - 4.0 * f3 * f1, 0.0)
    q = -0.5 * (f2 + np.copysign(np.sqrt(disc), f2))
    others = sorted([q / f3, f1 / q if q != 0.0 else 0.0])
    if f1 > 0.0:  # f > 0 to the right of 0: 0 is the lower turning point
        return 0.0, others[0], others[1]
    if f1 < 0.0:
        return others[0], 0.0, others[1]
    return 0.0, 0.0, max(others)  # a double root: steady precession


def lagrange_top_nutation(
    I1: float,
    I3: float,
    m: float,
    g: float,
    l: float,  # noqa: E741 (the textbook's name)
    theta0: float,
    theta_dot0: float,
    phi_dot0: float,
    psi_dot0: float,
) -> LagrangeTopNutation:
    r"""Momenta, energy, nutation bounds and period of the symmetric heavy (Lagrange) top.

    A symmetric body with a fixed point on its symmetry axis (body :math:`z`), the
    centre of mass at the distance :math:`l` above it on that axis, in the Euler
    angles :math:`(\varphi, \theta, \psi)` (precession, nutation, spin;
    :math:`R = R_z(\varphi)R_x(\theta)R_z(\psi)`, so the symmetry axis makes the angle
    :math:`\theta` with the upward vertical) [Gol02, §5.7], [LL76, §35]:

    .. math:: L = \tfrac12 I_1(\dot\theta^2 + \dot\varphi^2\sin^2\theta)
                  + \tfrac12 I_3(\dot\psi + \dot\varphi\cos\theta)^2 - mgl\cos\theta .

    :math:`\varphi` and :math:`\psi` are cyclic (:math:`p_\varphi`, :math:`p_\psi`
    conserved), and :math:`u = \cos\theta` obeys :math:`\dot u^2 = f(u)`,

    .. math:: f(u) = (\alpha - \beta u)(1 - u^2) - (b - au)^2,\quad
              a = \frac{p_\psi}{I_1},\ b = \frac{p_\varphi}{I_1},\
              \alpha = \frac{2E - p_\psi^2/I_3}{I_1},\ \beta = \frac{2mgl}{I_1},

    a cubic with :math:`f(\pm 1) = -(b \mp a)^2 \le 0` and
    :math:`f(\cos\theta_0) = \dot\theta_0^2\sin^2\theta_0 \ge 0`, hence roots
    :math:`-1 \le u_1 \le \cos\theta_0 \le u_2 \le 1 \le u_3`. The roots are found
    in :math:`x = u - \cos\theta_0`, with the coefficients of :math:`f` written in
    the initial data (no cancellation in :math:`E`). With
    :math:`k^2 = (u_2 - u_1)/(u_3 - u_1)` and :math:`\lambda = \tfrac12\sqrt{\beta(u_3 - u_1)}`,

    .. math:: u(t) = u_1 + (u_2 - u_1)\,\mathrm{sn}^2(\lambda t + w_0 \mid k^2),\qquad
              T = 2\int_{u_1}^{u_2}\frac{du}{\sqrt{f(u)}} = \frac{2K(k)}{\lambda}
                = \frac{4K(k)}{\sqrt{\beta(u_3 - u_1)}},

    and :math:`w_0 = \pm F(\arcsin\sqrt{(u_0 - u_1)/(u_2 - u_1)} \mid k^2)` with the
    sign of :math:`\dot u_0 = -\dot\theta_0\sin\theta_0`.

    Parameters
    ----------
    I1 : float
        The moment of inertia about a transverse axis through the fixed point.
    I3 : float
        The moment of inertia about the symmetry axis.
    m, g, l : float
        Mass, gravitational acceleration, distance of the centre of mass from the fixed
        point; :math:`mgl > 0`.
    theta0 : float
        The initial nutation angle, in :math:`(0, \pi)` (the Euler angles are singular
        on the vertical).
    theta_dot0, phi_dot0, psi_dot0 : float
        The initial Euler-angle rates.

    Returns
    -------
    LagrangeTopNutation
        With :meth:`LagrangeTopNutation.theta` for :math:`\theta(t)`.

    Raises
    ------
    ValueError
        If a moment is not positive, :math:`mgl \le 0`, or :math:`\theta_0 \notin (0, \pi)`.
    """
    from scipy.special import ellipkm1

    values = np.array([I1, I3, m, g, l, theta0, theta_dot0, phi_dot0, psi_dot0], dtype=float)
    if not np.all(np.isfinite(values)):
        raise ValueError("the parameters and initial data of the top must be finite")
    if I1 <= 0 or I3 <= 0:
        raise ValueError(f"the moments I1, I3 must be positive, got {I1}, {I3}")
    if m * g * l <= 0:
        raise ValueError(
            f"m g l must be positive (the centre of mass above the pivot when "
            f"theta < pi/2), got m={m}, g={g}, l={l}"
        )
    if not 0.0 < theta0 < np.pi:
        raise ValueError(
            f"theta0 must lie in (0, pi), the Euler angles being singular on "
            f"the vertical; got {theta0}"
        )
    u0, s0 = np.cos(theta0), np.sin(theta0)
    p_psi = I3 * (psi_dot0 + phi_dot0 * u0)
    p_phi = I1 * phi_dot0 * s0**2 + p_psi * u0
    energy = (
        0.5 * I1 * (theta_dot0**2 + (phi_dot0 * s0) ** 2) + p_psi**2 / (2 * I3) + m * g * l * u0
    )
    a, beta = p_psi / I1, 2.0 * m * g * l / I1
    # f(u0 + x) = f0 + f1 x + f2 x^2 + beta x^3 with P = alpha - beta u0, w = b - a u0
    big_p = theta_dot0**2 + (phi_dot0 * s0) ** 2
    w = phi_dot0 * s0**2
    coefficients = (
        (theta_dot0 * s0) ** 2,
        -2.0 * u0 * big_p - beta * s0**2 + 2.0 * a * w,
        -big_p + 2.0 * beta * u0 - a * a,
        beta,
    )
    x1, x2, x3 = _cubic_roots_about(coefficients, 1.0 - u0, -1.0 - u0)
    modulus, complementary = (x2 - x1) / (x3 - x1), (x3 - x2) / (x3 - x1)
    if complementary < MIN_COMPLEMENTARY_MODULUS:
        raise ValueError(
            "the top is on or too near the separatrix of the upright position (u2 = u3 = 1): "
            f"1 - k^2 = {complementary:.1e} < {MIN_COMPLEMENTARY_MODULUS:.0e}"
        )
    rate = 0.5 * np.sqrt(beta * (x3 - x1))
    phase = 0.0
    if x2 > x1:
        # sn^2 w0 = (u0 - u1)/(u2 - u1); w0 in [0, K] while u rises (theta falls), in
        # [-K, 0] while it falls; at rest the start is a turning point, sn^2 w0 = 0 or 1
        direction = -1.0 if theta_dot0 > 0 else 1.0
        sn0 = direction * np.sqrt(max(-x1, 0.0) / (x2 - x1))
        cn0 = np.sqrt(max(x2, 0.0) / (x2 - x1))
        phase = _elliptic_argument(sn0, cn0, modulus, complementary)
    u1, u2, u3 = u0 + x1, u0 + x2, u0 + x3
    return LagrangeTopNutation(
        p_phi=float(p_phi),
        p_psi=float(p_psi),
        energy=float(energy),
        theta_min=float(np.arccos(min(u2, 1.0))),
        theta_max=float(np.arccos(max(u1, -1.0))),
        period=float(2.0 * ellipkm1(complementary) / rate),
        roots=(float(u1), float(u2), float(u3)),
        modulus=float(modulus),
        complementary_modulus=float(complementary),
        rate=float(rate),
        phase=float(phase),
    )


def lagrange_top_theta(
    I1: float,
    I3: float,
    m: float,
    g: float,
    l: float,  # noqa: E741
    theta0: float,
    theta_dot0: float,
    phi_dot0: float,
    psi_dot0: float,
    t: float | ArrayLike,
) -> NDArray[np.float64]:
    r"""The nutation angle :math:`\theta(t)` of the Lagrange top by Jacobi's sn.

    :math:`\cos\theta(t) = u_1 + (u_2 - u_1)\,\mathrm{sn}^2(\lambda t + w_0 \mid k^2)`,
    in the notation and with the arguments of :func:`lagrange_top_nutation`; an array of
    shape ``t.shape``.
    """
    nutation = lagrange_top_nutation(I1, I3, m, g, l, theta0, theta_dot0, phi_dot0, psi_dot0)
    return nutation.theta(t)


# ------------------------------------------------------------------ ball joint
def _inertia_tensor(inertia: ArrayLike) -> NDArray[np.float64]:
    tensor = np.asarray(inertia, dtype=float)
    if tensor.shape == (3,):
        tensor = np.diag(tensor)
    if tensor.shape != (3, 3) or not np.allclose(tensor, tensor.T, rtol=1e-12, atol=0.0):
        raise ValueError(
            f"inertia must be 3 principal moments or a symmetric 3x3 tensor, got {inertia!r}"
        )
    if np.linalg.eigvalsh(tensor)[0] <= 0:
        raise ValueError("inertia must be positive definite")
    return tensor


def _ball_joint_setup(
    mass: float, inertia: ArrayLike, r_cm: ArrayLike, g: float
) -> tuple[float, NDArray[np.float64]]:
    """The stiffness m g l and the inertia about the pivot of the hanging body."""
    tensor = _inertia_tensor(inertia)
    r = _vector3(r_cm, "r_cm")
    length = -r[2]
    if length <= 0 or np.hypot(r[0], r[1]) > 1e-12 * length:
        raise ValueError(
            f"r_cm must be (0, 0, -l) with l > 0 (the centre of mass below the "
            f"joint at rest), got {r_cm!r}"
        )
    if mass <= 0 or g <= 0:
        raise ValueError(f"mass and g must be positive, got mass={mass}, g={g}")
    pivot = tensor + mass * (r @ r * np.eye(3) - np.outer(r, r))
    return mass * g * length, pivot


def ball_joint_modes(
    mass: float, inertia: ArrayLike, r_cm: ArrayLike, g: float = 9.81
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r"""Small-oscillation frequencies and mode shapes of a body hanging from a ball joint.

    The joint is at the origin, the body at rest in the pose :math:`R = I` with the
    centre of mass at the body point :math:`r = (0, 0, -l)` straight below it. For a
    small rotation :math:`R = \exp\hat\vartheta`, the body angular velocity is
    :math:`\dot\vartheta` to first order and the potential
    :math:`V = mg\,e_z\cdot Rr = mg\,e_z\cdot(r + \vartheta\times r
    + \tfrac12\vartheta\times(\vartheta\times r)) + O(\vartheta^3)`, so

    .. math:: L_2 = \tfrac12\dot\vartheta^\top J_O\dot\vartheta
                    - \tfrac12 mgl\,(\vartheta_x^2 + \vartheta_y^2),\qquad
              J_O = J + m(|r|^2 I - rr^\top),

    :math:`J_O` the inertia about the pivot. The generalised eigenproblem
    :math:`mgl\,\mathrm{diag}(1, 1, 0)\,v = \omega^2 J_O v` has :math:`\omega = 0` with
    :math:`v = e_z` (spin about the vertical) and two pendulum modes: :math:`\vartheta_z`
    is cyclic, so eliminating it (zero momentum :math:`e_z^\top J_O\dot\vartheta`) leaves
    the 2x2 problem with the Schur complement
    :math:`S = J_{O,xy} - J_{O,xy\,z}J_{O,zz}^{-1}J_{O,z\,xy}`:
    :math:`\omega_i = \sqrt{mgl/\mu_i}` for the eigenvalues :math:`\mu_i` of :math:`S`,
    :math:`v_z = -J_{O,z\,xy}v_{xy}/J_{O,zz}`. For principal axes
    :math:`\omega = \sqrt{mgl/J_{O,xx}}`, :math:`\sqrt{mgl/J_{O,yy}}`.

    Parameters
    ----------
    mass : float
        The mass :math:`m`.
    inertia : array_like, shape (3,) or (3, 3)
        The inertia tensor :math:`J` about the centre of mass in the body frame (3
        principal moments or a symmetric positive definite tensor).
    r_cm : array_like, shape (3,)
        The centre of mass in the body frame relative to the joint, :math:`(0, 0, -l)`.
    g : float
        The gravitational acceleration (gravity along :math:`-e_z`).

    Returns
    -------
    frequencies : ndarray, shape (3,)
        The angular frequencies in ascending order, the first 0.
    modes : ndarray, shape (3, 3)
        The mode shapes (rotation vectors :math:`\vartheta`) in the columns, in the order
        of ``frequencies``; the pendulum modes are :math:`J_O`-orthonormal.
    """
    stiffness, pivot = _ball_joint_setup(mass, inertia, r_cm, g)
    coupling = pivot[:2, 2]
    schur = pivot[:2, :2] - np.outer(coupling, coupling) / pivot[2, 2]
    mu, vectors = np.linalg.eigh(schur)
    order = np.argsort(-mu)  # the largest inertia the slowest
    modes = np.zeros((3, 3))
    modes[2, 0] = 1.0
    modes[:2, 1:] = vectors[:, order]
    modes[2, 1:] = -coupling @ vectors[:, order] / pivot[2, 2]
    modes[:, 1:] /= np.sqrt(np.einsum("ik,ij,jk->k", modes[:, 1:], pivot, modes[:, 1:]))
    frequencies = np.concatenate([[0.0], np.sqrt(stiffness / mu[order])])
    return frequencies, modes


def ball_joint_frequencies(
    mass: float, inertia: ArrayLike, r_cm: ArrayLike, g: float = 9.81
) -> NDArray[np.float64]:
    r"""The small-oscillation angular frequencies :math:`(0, \omega_1, \omega_2)`, ascending,
    of a body hanging from a ball joint; see :func:`ball_joint_modes` for the formulas."""
    return ball_joint_modes(mass, inertia, r_cm, g)[0]
