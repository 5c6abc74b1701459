"""Contact: integration between and through impacts.

The contacts themselves are declared with the system
(:class:`galerkin_vi.Contact`, :mod:`galerkin_vi.unilateral`). Here:
:mod:`.impact` (the impact law: restitution and the Coulomb impulse) and
:mod:`.event_driven` (isolated impacts located on the step and applied, the
variational collision integrator at the method's order).
:meth:`galerkin_vi.Integrator.integrate` calls :mod:`.event_driven` for a
system with contacts.
"""

from __future__ import annotations

from .impact import Impact

__all__ = ["Impact"]
