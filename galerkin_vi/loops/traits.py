"""How the loops learn a system's structure: run-time traits and compiled switches.

The loops are compiled once for every system, so the structure of a system is
data, in two kinds:

- *switches*, arguments that are either data or ``None``: ``pattern`` (the
  sparsity pattern of banded storage; ``None``: dense), the stage form's
  ``mass_diagonal`` and the explicit loop's ``Minv_diagonal`` (``None``: a
  full mass matrix), the explicit loop's ``periodic`` (``None``: no angles)
  and ``time_dependent`` (``None``: autonomous), the general loop's
  ``couplings`` (``None``: neither :math:`L_{qv}` nor :math:`f_v`; else the
  pair of flags). numba compiles one variant per combination of types (each
  cached once per machine) and drops the dead branches: these tests sit in
  the innermost loops of small systems, where a run-time test costs a large
  share of a step (docs/design-notes.md, "Switches compiled as loop
  variants");
- *traits*, an int64 array with the slots of :mod:`.abi` (re-exported here),
  and the angle mask ``periodic`` of the implicit loops, tested once per block
  or per step, where a test costs nothing measurable; they add no compiled
  variants.

:mod:`galerkin_vi.tools.warmup` compiles every variant.
"""

from __future__ import annotations

from .abi import AUTONOMOUS, BAND, HAS_FV, HAS_LQV, N_TRAITS

__all__ = ["AUTONOMOUS", "BAND", "HAS_FV", "HAS_LQV", "N_TRAITS"]
