"""A body's motion read back from a trajectory: pose and angular velocity at every row."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..rotations import matrix_to_quaternion, quaternion_to_matrix
from .body import RigidBody

__all__ = ["BodyMotion", "body_motion"]


@dataclass(frozen=True)
class BodyMotion:
    r"""The motion of one body along a trajectory's rows.

    Attributes
    ----------
    t : ndarray (rows,)
    position : ndarray (rows, 3)
        The centre of mass :math:`x`.
    rotation : ndarray (rows, 3, 3)
        :math:`R` (body → space); from quaternions, normalised.
    quaternion : ndarray (rows, 4)
        Scalar-first unit quaternions of :math:`R` (the coordinates themselves
        for quaternion bodies, with their sign).
    velocity : ndarray (rows, 3)
        :math:`\dot x`.
    angular_velocity, angular_velocity_space : ndarray (rows, 3)
        :math:`\omega` (body frame) and :math:`\omega_s = R\omega`, from the
        velocities :math:`v_k = (\mathbb FL)^{-1}(q_k, p_k)` of the rows.
    """

    t: NDArray[np.float64]
    position: NDArray[np.float64]
    rotation: NDArray[np.float64]
    quaternion: NDArray[np.float64]
    velocity: NDArray[np.float64]
    angular_velocity: NDArray[np.float64]
    angular_velocity_space: NDArray[np.float64]


def body_motion(body: RigidBody, t, q_rows, v_rows) -> BodyMotion:
    r"""The motion of ``body`` from the rows of its own coordinates and velocities.

    For a quaternion :math:`\omega = 2G\dot{\mathsf q}/|\mathsf q|^2`; for a matrix the
    skew part of :math:`R^\top\dot R`.
    """
    q = np.asarray(q_rows, dtype=float)
    v = np.asarray(v_rows, dtype=float)
    x, xd, r, rd = q[:, :3], v[:, :3], q[:, 3:], v[:, 3:]
    if body.embedding == "quaternion":
        R = quaternion_to_matrix(r)
        quat = r / np.linalg.norm(r, axis=1, keepdims=True)
        e0, e1, e2, e3 = r.T
        G = np.stack(
            [
                np.stack([-e1, e0, e3, -e2], -1),
                np.stack([-e2, -e3, e0, e1], -1),
                np.stack([-e3, e2, -e1, e0], -1),
            ],
            axis=1,
        )
        w = 2 * np.einsum("kij,kj->ki", G, rd) / np.sum(r**2, axis=1, keepdims=True)
    else:
        R = r.reshape(-1, 3, 3)
        W = np.einsum("kji,kjl->kil", R, rd.reshape(-1, 3, 3))
        S = (W - np.swapaxes(W, 1, 2)) / 2
        w = np.stack([S[:, 2, 1], S[:, 0, 2], S[:, 1, 0]], axis=1)
        quat = matrix_to_quaternion(R)
    ws = np.einsum("kij,kj->ki", R, w)
    return BodyMotion(np.asarray(t, dtype=float), x, R, quat, xd, w, ws)
