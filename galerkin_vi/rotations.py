r"""Rotations of 3-D space: unit quaternions and rotation matrices, symbolic and numeric.

Conventions (used everywhere in :mod:`galerkin_vi.multibody`):

- a rotation :math:`R \in SO(3)` maps body coordinates to space coordinates,
  :math:`x_{\text{space}} = x + R\,r_{\text{body}}`;
- quaternions are scalar first, :math:`\mathsf q = (e_0, e_1, e_2, e_3) = (e_0, \varepsilon)`, and

  .. math::

      R(\mathsf q) = (e_0^2 - \varepsilon^\top\varepsilon)\,I + 2\,\varepsilon\varepsilon^\top
      + 2 e_0\,\hat\varepsilon ,

  which is a rotation for :math:`|\mathsf q| = 1` (and :math:`|\mathsf q|^2` times one otherwise);
- :math:`\hat w` is the skew matrix with :math:`\hat w\,r = w \times r`;
- the body and space angular velocities of :math:`R(t)` are :math:`\hat\omega = R^\top\dot R`
  and :math:`\hat\omega_s = \dot R R^\top = \widehat{R\omega}`. For quaternions,
  :math:`\omega = 2\,G(\mathsf q)\,\dot{\mathsf q}` and
  :math:`\omega_s = 2\,E(\mathsf q)\,\dot{\mathsf q}` with

  .. math::

      G = \begin{pmatrix} -e_1 & e_0 & e_3 & -e_2\\ -e_2 & -e_3 & e_0 & e_1\\
      -e_3 & e_2 & -e_1 & e_0\end{pmatrix},\qquad
      E = \begin{pmatrix} -e_1 & e_0 & -e_3 & e_2\\ -e_2 & e_3 & e_0 & -e_1\\
      -e_3 & -e_2 & e_1 & e_0\end{pmatrix};

  both have orthonormal rows orthogonal to :math:`\mathsf q` when :math:`|\mathsf q| = 1`, so
  :math:`\dot{\mathsf q} = \tfrac12 G^\top\omega = \tfrac12 E^\top\omega_s` on the unit sphere.
"""

from __future__ import annotations

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "body_rates_matrix",
    "hat",
    "orthonormal_complement",
    "matrix_to_quaternion",
    "quaternion_rate",
    "quaternion_to_matrix",
    "space_rates_matrix",
    "symbolic_hat",
    "symbolic_quaternion_matrix",
    "symbolic_vector",
    "symbolic_vee",
]


def symbolic_vector(x, name: str) -> sp.Matrix:
    """``x`` as a 3x1 SymPy column; ValueError naming ``name`` if it is not a 3-vector."""
    m = sp.Matrix(x)
    if m.shape not in ((3, 1), (1, 3)):
        raise ValueError(f"{name} must be a 3-vector, got shape {m.shape}")
    return m.reshape(3, 1)


def orthonormal_complement(n: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r"""Unit vectors :math:`u, w` with :math:`(n, u, w)` a right-handed orthonormal frame,
    for a unit 3-vector ``n``: :math:`u = n\times e/|n\times e|` with :math:`e` the axis
    least aligned with :math:`n`, :math:`w = n\times u`."""
    a = np.asarray(n, dtype=float).ravel()
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(a, e)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


def symbolic_hat(w) -> sp.Matrix:
    r"""The skew matrix :math:`\hat w` of a 3-vector, :math:`\hat w\, r = w \times r`."""
    x, y, z = w
    return sp.Matrix([[0, -z, y], [z, 0, -x], [-y, x, 0]])


def symbolic_vee(W: sp.Matrix) -> sp.Matrix:
    r"""The vector of the skew part of ``W``: :math:`\tfrac12(W - W^\top) = \hat w`."""
    return sp.Matrix([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2


def symbolic_quaternion_matrix(e) -> sp.Matrix:
    r""":math:`R(\mathsf q) = (e_0^2 - \varepsilon^\top\varepsilon) I + 2\varepsilon\varepsilon^\top
    + 2e_0\hat\varepsilon` (a rotation on the unit sphere)."""
    e0, e1, e2, e3 = e
    eps = sp.Matrix([e1, e2, e3])
    diagonal = (e0**2 - e1**2 - e2**2 - e3**2) * sp.eye(3)
    return diagonal + 2 * eps * eps.T + 2 * e0 * symbolic_hat(eps)


def body_rates_matrix(e) -> sp.Matrix:
    r""":math:`G(\mathsf q)`: :math:`\omega = 2 G \dot{\mathsf q}` is the body angular velocity."""
    e0, e1, e2, e3 = e
    return sp.Matrix([[-e1, e0, e3, -e2], [-e2, -e3, e0, e1], [-e3, e2, -e1, e0]])


def space_rates_matrix(e) -> sp.Matrix:
    r""":math:`E(\mathsf q)`: :math:`\omega_s = 2 E \dot{\mathsf q}`, the space angular velocity."""
    e0, e1, e2, e3 = e
    return sp.Matrix([[-e1, e0, -e3, e2], [-e2, e3, e0, -e1], [-e3, -e2, e1, e0]])


def hat(w: ArrayLike) -> NDArray[np.float64]:
    r""":math:`\hat w` for an array of 3-vectors (shape ``(..., 3)`` → ``(..., 3, 3)``)."""
    w = np.asarray(w, dtype=float)
    out = np.zeros(w.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def quaternion_to_matrix(e: ArrayLike) -> NDArray[np.float64]:
    r"""Rotation matrices of unit quaternions (scalar first), shape ``(..., 4)`` → ``(..., 3, 3)``.

    The quaternions are normalised first, so :math:`R` is orthogonal to round-off.
    """
    e = np.asarray(e, dtype=float)
    if e.shape[-1] != 4:
        raise ValueError(f"quaternions must have 4 components (scalar first), got shape {e.shape}")
    e = e / np.linalg.norm(e, axis=-1, keepdims=True)
    e0, eps = e[..., 0], e[..., 1:]
    out = (e0**2 - np.sum(eps**2, axis=-1))[..., None, None] * np.eye(3)
    out = out + 2 * eps[..., :, None] * eps[..., None, :] + 2 * e0[..., None, None] * hat(eps)
    return out


def matrix_to_quaternion(R: ArrayLike) -> NDArray[np.float64]:
    r"""Unit quaternions (scalar first, :math:`e_0 \ge 0`) of rotation matrices ``(..., 3, 3)``.

    Shepperd's method: the largest of :math:`4e_i^2` (from the trace and the
    diagonal) is taken first, which keeps the division well conditioned.
    """
    R = np.asarray(R, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must have shape (..., 3, 3), got {R.shape}")
    flat = R.reshape(-1, 3, 3)
    out = np.empty((flat.shape[0], 4))
    for k, m in enumerate(flat):
        tr = np.trace(m)
        d = np.array([tr, m[0, 0], m[1, 1], m[2, 2]])
        i = int(np.argmax(d))
        if i == 0:
            s = np.sqrt(1.0 + tr) * 2
            e = [s / 4, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
        else:
            a, b, c = (i - 1, i % 3, (i + 1) % 3)
            s = np.sqrt(1.0 + m[a, a] - m[b, b] - m[c, c]) * 2
            e = np.empty(4)
            e[0] = (m[c, b] - m[b, c]) / s
            e[1 + a] = s / 4
            e[1 + b] = (m[a, b] + m[b, a]) / s
            e[1 + c] = (m[a, c] + m[c, a]) / s
        e = np.asarray(e, dtype=float)
        out[k] = -e if e[0] < 0 else e
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return out.reshape(R.shape[:-2] + (4,))


def quaternion_rate(e: ArrayLike, omega: ArrayLike, frame: str = "body") -> NDArray[np.float64]:
    r""":math:`\dot{\mathsf q} = \tfrac12 G^\top\omega` (body frame) or
    :math:`\tfrac12 E^\top\omega_s` (space frame), for unit quaternions ``(..., 4)``
    and angular velocities ``(..., 3)``."""
    if frame not in ("body", "space"):
        raise ValueError(f"frame must be 'body' or 'space', got {frame!r}")
    e = np.asarray(e, dtype=float)
    w = np.asarray(omega, dtype=float)
    e0, e1, e2, e3 = np.moveaxis(e, -1, 0)
    s = 1.0 if frame == "body" else -1.0
    # G^T and E^T differ only in the sign of the terms of the cross product
    rows = [
        [-e1, -e2, -e3],
        [e0, -s * e3, s * e2],
        [s * e3, e0, -s * e1],
        [-s * e2, s * e1, e0],
    ]
    out = np.stack([sum(r[j] * w[..., j] for j in range(3)) for r in rows], axis=-1)
    return out / 2
