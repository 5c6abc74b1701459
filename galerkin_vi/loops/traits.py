"""How the loops learn a system's structure: run-time traits and compiled switches.

Loops are compiled once for every system, so what used to be constants of a
generated module is data, in two kinds:

- *switches*, arguments that are either data or ``None``: ``pattern`` (the
  sparsity pattern of banded storage; ``None``: dense), the stage form's
  ``mass_diagonal`` and the explicit loop's ``Minv_diagonal`` (``None``: a
  full mass matrix), the explicit loop's ``periodic`` (``None``: no angles)
  and ``time_dependent`` (``None``: autonomous), the general loop's
  ``couplings`` (``None``: neither :math:`L_{qv}` nor :math:`f_v`; else the
  pair of flags). numba compiles one variant per combination of types (each
  cached once per machine) and drops the dead branches. Measured on the
  pendulum against the loops with these as run-time tests: 40 % per step
  (diagonal mass, stage form), 12 % (dense against banded storage), 25 %
  (angles and time, explicit loop), 10-20 % (couplings, general loop);
- *traits*, a tuple of ints with the slots below, and the angle mask
  ``periodic`` of the implicit loops, tested once per block or per step, where
  a test costs nothing measurable; they add no compiled variants.

:mod:`galerkin_vi.tools.warmup` compiles every variant.
"""

from __future__ import annotations

__all__ = ["AUTONOMOUS", "BAND", "HAS_FV", "HAS_LQV", "N_TRAITS"]

#: coordinate half-bandwidth w of banded storage (-1 with dense storage)
BAND = 0
#: 1 when d2L/dq dv is not identically zero
HAS_LQV = 1
#: 1 when the forces depend on v (df/dv is written into Fv)
HAS_FV = 2
#: 1 when neither L nor the forces depend on t
AUTONOMOUS = 3
N_TRAITS = 4
