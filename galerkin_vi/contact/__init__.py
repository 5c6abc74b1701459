"""Contact: integration between and through impacts.

The contacts themselves are declared with the system
(:class:`galerkin_vi.Contact`, :mod:`galerkin_vi.model.contacts`). Here:
:mod:`.impact` (the impact law: restitution and the Coulomb impulse; the
contacts' numeric functions), :mod:`.time_stepping` (persistent contact: a
complementarity problem per step by an interior point) and :mod:`.runs`
(isolated impacts located on the step and applied, the variational collision
integrator at the method's order, and the switching between the two).
:meth:`galerkin_vi.Integrator.integrate` calls :mod:`.runs` for a
system with contacts.
"""

from __future__ import annotations

from .impact import Impact

__all__ = ["Impact"]
