r"""Linear stability of periodic orbits: the monodromy matrix and its Floquet multipliers.

For a periodic orbit :math:`x(t + T) = x(t)` of the discrete flow (N steps of
size :math:`h = T/N`), the monodromy matrix is the tangent map over one period,

.. math::

    M = \Phi_N = \frac{\partial (q_N, p_N)}{\partial (q_0, p_0)},

computed by running the same method from the orbit's :math:`(q_0, p_0)` with
``tangent=True``. Its eigenvalues are the Floquet multipliers. :math:`M` is
symplectic, so they come in quadruples :math:`\mu, \bar\mu, 1/\mu, 1/\bar\mu`;
the orbit is linearly (spectrally) stable when all lie on the unit circle.
For an autonomous system 1 is a double multiplier (the flow direction and the
direction across the energy levels, a Jordan block when the period varies
with the energy), and each further symmetry with its conserved momentum adds
another double 1 (Meyer, Hall, Offin, *Introduction to Hamiltonian Dynamical
Systems*, 2nd ed., Springer 2009, Sec. 4.5).

A Jordan block at 1 is fragile: a perturbation :math:`\varepsilon` of :math:`M`
(round-off, the Newton tolerance of the orbit, the discrete time shift being a
symmetry only up to :math:`O(h^{2s})` effects) splits its multipliers by
:math:`O(\sqrt\varepsilon)`, on or off the unit circle. The tolerance of
:func:`is_linearly_stable` is chosen above that.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "STABILITY_TOLERANCE",
    "StabilityChange",
    "floquet_multipliers",
    "is_linearly_stable",
    "monodromy",
    "stability_changes",
]

#: largest distance ``||mu| - 1|`` of a multiplier counted as on the unit circle
STABILITY_TOLERANCE = 1e-4


def monodromy(orbit: Any) -> NDArray[np.float64]:
    r"""The monodromy matrix (2n, 2n) of a :class:`~galerkin_vi.action.periodic.PeriodicOrbit`.

    The tangent map of N steps of the orbit's method with :math:`h = T/N`, from
    the orbit's :math:`(q_0, p_0)` and with its parameters, with the numba
    backend.

    Raises
    ------
    ValueError
        When the orbit did not converge, or the run over one period fails.
    """
    from ..integrator import Integrator

    if not orbit.success:
        raise ValueError(f"orbit: the periodic orbit did not converge ({orbit.message})")
    traj = orbit.trajectory
    system = traj.system
    params = dict(zip(system.params, traj.params, strict=True))
    N = orbit.control_points.shape[0]
    run = Integrator(system, orbit.method, backend="numba").integrate(
        traj.q[0], p0=traj.p[0], h=orbit.period / N, n_steps=N, params=params,
        save_every=N, tangent=True, on_failure="raise",
    )  # fmt: skip
    return run.tangent[-1].copy()


def floquet_multipliers(matrix: NDArray[np.float64]) -> NDArray[np.complex128]:
    """The eigenvalues of ``matrix`` sorted by modulus, descending (ties by argument)."""
    values = np.linalg.eigvals(np.asarray(matrix, dtype=float))
    order = np.lexsort((np.angle(values), -np.abs(values)))
    return values[order]


def is_linearly_stable(multipliers: NDArray, tol: float = STABILITY_TOLERANCE) -> bool:
    """Whether every multiplier lies on the unit circle to ``tol`` (``| |mu| - 1 | <= tol``)."""
    if not tol > 0:
        raise ValueError(f"tol must be positive, got {tol!r}")
    return bool(np.all(np.abs(np.abs(multipliers) - 1.0) <= tol))


@dataclass(frozen=True)
class StabilityChange:
    """Where the linear stability of a family of periodic orbits changes.

    Attributes
    ----------
    index : int
        The first orbit (index in the family) on the new side: the change lies
        between orbits ``index - 1`` and ``index``.
    energies : tuple of float
        The energies of these two orbits (at node 0).
    stable : bool
        Whether orbit ``index`` is linearly stable (multipliers entered the
        unit circle) or not (they left it).
    """

    index: int
    energies: tuple[float, float]
    stable: bool


def stability_changes(orbits, tol: float = STABILITY_TOLERANCE) -> list[StabilityChange]:
    """The changes of linear stability between consecutive converged orbits of ``orbits``.

    Failed orbits (a family's last one may be) are skipped.
    """
    converged = [(i, orbit) for i, orbit in enumerate(orbits) if orbit.success]
    stable = [orbit.linearly_stable(tol) for _, orbit in converged]
    changes = []
    for (_, before), (j, after), a, b in zip(
        converged[:-1], converged[1:], stable[:-1], stable[1:], strict=True
    ):
        if a != b:
            energies = (float(before.trajectory.energy()[0]), float(after.trajectory.energy()[0]))
            changes.append(StabilityChange(index=j, energies=energies, stable=b))
    return changes
