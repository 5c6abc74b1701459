r"""MuJoCo peers of the rigid-body benchmarks: a free tumbling body, a chain of ball-jointed links.

Both models are built from XML strings with explicit ``<inertial>`` elements (mass, centre of
mass, ``diaginertia`` in the body frame, ``inertiafromgeom="false"``), so that galerkin_vi can
run exactly the same bodies (:class:`ChainSpec` and :func:`chain_initial_poses` give the data).

Conventions (checked with ``mj_objectVelocity``):

* free joint: ``qpos = (x, y, z, q_w, q_x, q_y, q_z)`` (scalar-first quaternion of the body
  to world rotation); ``qvel = (v, \omega)`` with the linear velocity :math:`v` of the body
  origin **in the world frame** and the angular velocity :math:`\omega` **in the body (local)
  frame**, i.e. the body angular velocity of Euler's equations;
* ball joint: ``qpos`` the quaternion of the child relative to the parent, ``qvel`` the
  relative angular velocity in the child's frame.

Integrators: MuJoCo's names ``"Euler"`` (semi-implicit), ``"RK4"``, ``"implicit"`` (implicit in
velocity with the full derivative of the bias forces), ``"implicitfast"`` (without the
Coriolis/gyroscopic derivative) and, when the installed MuJoCo has it (4.x), ``"discrete"``.
Runs call ``mj_step(m, d, nstep=save_every)`` so that the step loop stays in C; CPU time is
``time.process_time`` around those calls. Energies are computed at the saves only (the energy
flag is switched on for one ``mj_forward`` there and off while stepping).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

__all__ = [
    "ChainRun",
    "ChainSpec",
    "FreeBodyRun",
    "INTEGRATORS",
    "available_integrators",
    "chain_initial_poses",
    "chain_xml",
    "free_body_xml",
    "run_chain",
    "run_free_body",
]

#: MuJoCo's integrators compared here (``"discrete"`` only where the installed MuJoCo has it)
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast", "discrete")


def available_integrators() -> tuple[str, ...]:
    """The names of :data:`INTEGRATORS` that the installed MuJoCo accepts."""
    names = {
        "Euler": "mjINT_EULER",
        "RK4": "mjINT_RK4",
        "implicit": "mjINT_IMPLICIT",
        "implicitfast": "mjINT_IMPLICITFAST",
        "discrete": "mjINT_DISCRETE",
    }
    members = mujoco.mjtIntegrator.__members__
    return tuple(name for name in INTEGRATORS if names[name] in members)


def _check_integrator(integrator: str) -> None:
    if integrator not in available_integrators():
        raise ValueError(f"integrator must be one of {available_integrators()}, got {integrator!r}")


def _vec(values: np.ndarray | list[float] | tuple[float, ...]) -> str:
    return " ".join(repr(float(x)) for x in np.asarray(values, dtype=float).ravel())


# ------------------------------------------------------------------------------------ free body
@dataclass
class FreeBodyRun:
    """A MuJoCo run of the free body.

    Attributes
    ----------
    t : ndarray, shape (rows,)
    quaternion : ndarray, shape (rows, 4)
        Body to world rotation, scalar first (``qpos[3:7]``).
    omega : ndarray, shape (rows, 3)
        Body-frame angular velocity (``qvel[3:6]``).
    cpu_time : float
        CPU seconds of the ``mj_step`` calls.
    steps : int
    success, status, message
        ``status`` -1 when MuJoCo flagged the simulation unstable (``mjWARN_BADQACC``; it then
        resets the state, so the run stops and keeps the rows saved before) or it turned
        non-finite.
    """

    t: np.ndarray
    quaternion: np.ndarray
    omega: np.ndarray
    cpu_time: float
    steps: int
    success: bool
    status: int
    message: str

    @property
    def ns_per_step(self) -> float:
        return 1e9 * self.cpu_time / max(self.steps, 1)


def free_body_xml(inertia: np.ndarray | list[float], mass: float, h: float, integrator: str) -> str:
    """XML of one body on a free joint, gravity off, principal moments ``inertia`` on its axes."""
    _check_integrator(integrator)
    return f"""<mujoco model="free_body">
  <compiler inertiafromgeom="false"/>
  <option gravity="0 0 0" timestep="{float(h)!r}" integrator="{integrator}">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="body">
      <freejoint/>
      <inertial pos="0 0 0" mass="{float(mass)!r}" diaginertia="{_vec(inertia)}"/>
    </body>
  </worldbody>
</mujoco>"""


def run_free_body(
    inertia: np.ndarray | list[float],
    omega0: np.ndarray | list[float],
    h: float,
    n_steps: int,
    integrator: str = "RK4",
    quaternion0: np.ndarray | list[float] = (1.0, 0.0, 0.0, 0.0),
    mass: float = 1.0,
    save_every: int = 1,
) -> FreeBodyRun:
    """Run the free body ``n_steps`` steps of size ``h`` with one of MuJoCo's integrators.

    Parameters
    ----------
    inertia : array_like, shape (3,)
        Principal moments (body axes = principal axes).
    omega0 : array_like, shape (3,)
        Initial angular velocity in the body frame.
    h : float
        Time step.
    n_steps : int
    integrator : str
        One of :func:`available_integrators`.
    quaternion0 : array_like, shape (4,)
        Initial rotation, scalar first.
    mass : float
    save_every : int
        Save every ``save_every`` steps (row 0 is the initial state).
    """
    if int(save_every) < 1 or int(n_steps) < 0:
        raise ValueError("save_every must be >= 1 and n_steps >= 0")
    model = mujoco.MjModel.from_xml_string(free_body_xml(inertia, mass, h, integrator))
    data = mujoco.MjData(model)
    data.qpos[3:7] = np.asarray(quaternion0, dtype=float)
    data.qvel[3:6] = np.asarray(omega0, dtype=float)
    rows = int(n_steps) // int(save_every) + 1
    quats = np.empty((rows, 4))
    omegas = np.empty((rows, 3))
    quats[0], omegas[0] = data.qpos[3:7], data.qvel[3:6]
    cpu = 0.0
    row = 1
    for row in range(1, rows):
        start = time.process_time()
        mujoco.mj_step(model, data, nstep=int(save_every))
        cpu += time.process_time() - start
        quats[row], omegas[row] = data.qpos[3:7], data.qvel[3:6]
        if _unstable(data) or not np.isfinite(omegas[row]).all():
            # the rows before this save are MuJoCo's last trustworthy ones
            return FreeBodyRun(
                np.arange(row) * h * save_every,
                quats[:row],
                omegas[:row],
                cpu,
                row * int(save_every),
                False,
                -1,
                f"unstable (bad qacc) by step {row * int(save_every)}",
            )
    return FreeBodyRun(
        np.arange(rows) * h * save_every,
        quats,
        omegas,
        cpu,
        (rows - 1) * int(save_every),
        True,
        0,
        "finished",
    )


# ---------------------------------------------------------------------------------------- chain
@dataclass
class ChainSpec:
    r"""A chain of ``n_links`` equal rigid links on ball joints, the first on the world at 0.

    Link ``i`` has its frame at its upper end (the joint), hangs along its body :math:`-z` axis,
    its centre of mass at ``(0, 0, -length/2)`` and the principal inertia ``inertia`` about it
    on the body axes (default: a solid cylinder of radius ``radius``,
    :math:`I_{xx} = I_{yy} = m(3r^2 + \ell^2)/12`, :math:`I_{zz} = m r^2/2`). Link ``i + 1``
    hangs from ``(0, 0, -length)`` of link ``i``. ``tilt[i]`` is the initial rotation of joint
    ``i`` relative to its parent as a rotation vector (axis times angle, radians); the chain
    starts at rest. Contacts are disabled.
    """

    n_links: int = 10
    length: float = 0.5
    radius: float = 0.05
    mass: float = 1.0
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    inertia: tuple[float, float, float] | None = None
    tilt: dict[int, tuple[float, float, float]] = field(
        default_factory=lambda: {0: (1.2, 0.0, 0.0), 4: (0.0, 0.6, 0.0), 7: (0.3, 0.0, 0.4)}
    )

    def principal_inertia(self) -> np.ndarray:
        """The links' principal inertia about their centre of mass."""
        if self.inertia is not None:
            return np.asarray(self.inertia, dtype=float)
        m, r, ell = self.mass, self.radius, self.length
        side = m * (3 * r * r + ell * ell) / 12
        return np.array([side, side, m * r * r / 2])

    def joint_quaternions(self) -> np.ndarray:
        """Initial relative quaternions (scalar first) of the ``n_links`` joints, from ``tilt``."""
        quats = np.tile([1.0, 0.0, 0.0, 0.0], (self.n_links, 1))
        for i, rotvec in self.tilt.items():
            if not 0 <= i < self.n_links:
                raise ValueError(f"tilt names joint {i}, outside 0..{self.n_links - 1}")
            v = np.asarray(rotvec, dtype=float)
            angle = np.linalg.norm(v)
            if angle > 0:
                quats[i] = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * v / angle])
        return quats


def chain_xml(spec: ChainSpec, h: float, integrator: str) -> str:
    """The MuJoCo XML of ``spec`` at time step ``h`` with the given integrator."""
    _check_integrator(integrator)
    if spec.n_links < 1:
        raise ValueError(f"n_links must be >= 1, got {spec.n_links}")
    ell = float(spec.length)
    inertia = _vec(spec.principal_inertia())
    body = ""
    for i in reversed(range(spec.n_links)):
        pos = "0 0 0" if i == 0 else f"0 0 {-ell!r}"
        body = f"""<body name="link{i}" pos="{pos}">
  <joint name="ball{i}" type="ball" damping="0"/>
  <inertial pos="0 0 {-ell / 2!r}" mass="{float(spec.mass)!r}" diaginertia="{inertia}"/>
  <geom type="capsule" fromto="0 0 0 0 0 {-ell!r}" size="{float(spec.radius)!r}"/>
  {body}
</body>"""
    return f"""<mujoco model="chain{spec.n_links}">
  <compiler inertiafromgeom="false" angle="radian"/>
  <option gravity="{_vec(spec.gravity)}" timestep="{float(h)!r}" integrator="{integrator}">
    <flag contact="disable"/>
  </option>
  <worldbody>
{body}
  </worldbody>
</mujoco>"""


def _chain_model(
    spec: ChainSpec, h: float, integrator: str
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_string(chain_xml(spec, h, integrator))
    data = mujoco.MjData(model)
    data.qpos[:] = spec.joint_quaternions().ravel()
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    return model, data


def chain_initial_poses(spec: ChainSpec) -> dict[str, np.ndarray]:
    """Absolute initial poses of the links (for building the same chain elsewhere).

    Returns
    -------
    dict
        ``"joint"`` (n, 3): joint positions (link frames' origins); ``"com"`` (n, 3): centres of
        mass; ``"quaternion"`` (n, 4): link to world rotations, scalar first; ``"rotation"``
        (n, 3, 3). All links start at rest.
    """
    model, data = _chain_model(spec, 0.01, "RK4")
    return {
        "joint": data.xpos[1:].copy(),
        "com": data.xipos[1:].copy(),
        "quaternion": data.xquat[1:].copy(),
        "rotation": data.xmat[1:].reshape(-1, 3, 3).copy(),
    }


def _unstable(data: mujoco.MjData) -> bool:
    """Whether MuJoCo flagged a bad acceleration (it then resets the state to qpos0 and goes on)."""
    return data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number > 0


def _energy(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Potential plus kinetic energy now (the energy flag on for one ``mj_forward``)."""
    model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    mujoco.mj_forward(model, data)
    model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    return float(data.energy[0] + data.energy[1])


@dataclass
class ChainRun:
    """A MuJoCo run of the chain.

    Attributes
    ----------
    t : ndarray, shape (rows,)
    energy : ndarray, shape (rows,)
        Potential plus kinetic energy (MuJoCo's ``data.energy``).
    qpos : ndarray, shape (rows, 4 n)
        Ball-joint quaternions.
    cpu_time : float
        CPU seconds of the ``mj_step`` calls.
    steps : int
    success, status, message
        ``status`` -1 when MuJoCo flagged the simulation unstable (see :class:`FreeBodyRun`).
    """

    t: np.ndarray
    energy: np.ndarray
    qpos: np.ndarray
    cpu_time: float
    steps: int
    success: bool
    status: int
    message: str

    @property
    def ns_per_step(self) -> float:
        return 1e9 * self.cpu_time / max(self.steps, 1)

    @property
    def max_energy_error(self) -> float:
        """``max_k |E_k - E_0|`` over the saved rows (absolute, in joules)."""
        return float(np.max(np.abs(self.energy - self.energy[0])))


def run_chain(
    spec: ChainSpec, h: float, n_steps: int, integrator: str = "RK4", save_every: int = 100
) -> ChainRun:
    """Run the hanging chain ``n_steps`` steps; energy at every ``save_every`` steps."""
    if int(save_every) < 1 or int(n_steps) < 0:
        raise ValueError("save_every must be >= 1 and n_steps >= 0")
    model, data = _chain_model(spec, h, integrator)
    rows = int(n_steps) // int(save_every) + 1
    energy = np.empty(rows)
    qpos = np.empty((rows, model.nq))
    energy[0], qpos[0] = _energy(model, data), data.qpos
    cpu = 0.0
    for row in range(1, rows):
        start = time.process_time()
        mujoco.mj_step(model, data, nstep=int(save_every))
        cpu += time.process_time() - start
        energy[row], qpos[row] = _energy(model, data), data.qpos
        if _unstable(data) or not np.isfinite(energy[row]):
            return ChainRun(
                np.arange(row) * h * save_every,
                energy[:row],
                qpos[:row],
                cpu,
                row * int(save_every),
                False,
                -1,
                f"unstable (bad qacc) by step {row * int(save_every)}",
            )
    return ChainRun(
        np.arange(rows) * h * save_every,
        energy,
        qpos,
        cpu,
        (rows - 1) * int(save_every),
        True,
        0,
        "finished",
    )
