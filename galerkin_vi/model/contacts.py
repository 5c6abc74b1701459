r"""Contacts: unilateral constraints declared with a system.

A contact is a gap :math:`\varphi(q) \ge 0` (apart while positive), an impact
law and a friction law:

- **restitution** :math:`e \in [0, 1]`, Newton's law on the normal velocity
  :math:`u = \nabla\varphi(q)\cdot v`: an impact with :math:`u^- < 0` leaves
  :math:`u^+ = -e\,u^-` (e = 1 elastic, e = 0 plastic);
- **friction** :math:`\mu \ge 0`, Coulomb's law: the tangential impulse lies in
  the cone :math:`\|\Lambda_t\| \le \mu \Lambda_n` and opposes the slip;
- **slip**: the tangential slip velocities :math:`w(q, v)`, linear in v (one
  expression for contact in a plane, two in space); needed when
  :math:`\mu > 0`.

This module only declares and checks; :mod:`galerkin_vi.contact` integrates.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

__all__ = ["Contact", "check_contacts"]


@dataclass(frozen=True)
class Contact:
    r"""A unilateral contact :math:`\varphi(q) \ge 0` with restitution and friction.

    Parameters
    ----------
    gap : sympy.Expr
        :math:`\varphi(q)`, positive while apart, in the positions (and the
        time and parameters), not the velocities.
    restitution : float
        Newton's coefficient e in [0, 1].
    friction : float
        Coulomb's coefficient :math:`\mu \ge 0`.
    slip : sequence of sympy.Expr, optional
        The tangential slip velocities, linear in v: one (planar contact) or
        two (spatial). Required when ``friction > 0``.

    Examples
    --------
    A ball above the floor y = 0, bouncing with e = 0.8:

    >>> import sympy as sp
    >>> import galerkin_vi as gvi
    >>> y = sp.Symbol("y")
    >>> gvi.Contact(y, restitution=0.8)
    Contact(gap=y, restitution=0.8, friction=0.0, slip=None)
    """

    gap: sp.Expr
    restitution: float = 0.0
    friction: float = 0.0
    slip: tuple[sp.Expr, ...] | None = None

    def __post_init__(self) -> None:
        gap = _expression(self.gap, "gap")
        where = f"Contact(gap={gap})"
        e = _real(self.restitution, f"{where}: restitution")
        if not 0.0 <= e <= 1.0:
            raise ValueError(f"{where}: restitution must be in [0, 1], got {self.restitution!r}")
        mu = _real(self.friction, f"{where}: friction")
        if mu < 0.0:
            raise ValueError(f"{where}: friction must be >= 0, got {self.friction!r}")
        slip = self.slip
        if slip is not None:
            if isinstance(slip, (sp.Basic, numbers.Number)):
                slip = (slip,)
            slip = tuple(_expression(w, f"{where}: slip") for w in slip)
            if len(slip) not in (1, 2):
                raise ValueError(
                    f"{where}: slip must hold one (planar) or two (spatial) slip velocities, "
                    f"got {len(slip)}"
                )
        object.__setattr__(self, "gap", gap)
        object.__setattr__(self, "restitution", e)
        object.__setattr__(self, "friction", mu)
        object.__setattr__(self, "slip", slip)


def check_contacts(
    contacts: Sequence[Contact] | None,
    q: Sequence[sp.Symbol],
    v: Sequence[sp.Symbol],
    t: sp.Symbol | None,
    params: Sequence[sp.Symbol],
) -> tuple[Contact, ...]:
    """The system's contacts, checked against its symbols; errors name the contact.

    The gap may depend on q, t and the parameters only; the slip velocities on
    (q, v, t, parameters), linearly in v; friction needs slip velocities.
    """
    if contacts is None:
        return ()
    if isinstance(contacts, Contact):
        contacts = [contacts]
    out = []
    positions = set(q) | ({t} if t is not None else set()) | set(params)
    velocities = set(v)
    for j, contact in enumerate(contacts):
        if not isinstance(contact, Contact):
            raise TypeError(f"contacts[{j}] must be a galerkin_vi.Contact, got {contact!r}")
        where = f"contacts[{j}] (gap {contact.gap})"
        if contact.gap.free_symbols & velocities:
            used = ", ".join(sorted(str(s) for s in contact.gap.free_symbols & velocities))
            raise ValueError(f"{where}: a gap depends on the positions only, not on {used}")
        unknown = contact.gap.free_symbols - positions
        if unknown:
            raise ValueError(f"{where}: the gap contains undeclared symbols {_names(unknown)}")
        if not contact.gap.free_symbols & set(q):
            raise ValueError(f"{where}: the gap does not depend on the positions")
        if contact.friction > 0.0 and contact.slip is None:
            raise ValueError(
                f"{where}: friction = {contact.friction} needs the slip velocities "
                "(slip=[...], expressions in q and v)"
            )
        for w in contact.slip or ():
            unknown = w.free_symbols - positions - velocities
            if unknown:
                raise ValueError(f"{where}: slip {w} contains undeclared symbols {_names(unknown)}")
            if any(sp.diff(w, a, b) != 0 for a in v for b in v):
                raise ValueError(f"{where}: slip {w} must be linear in the velocities")
        out.append(contact)
    return tuple(out)


def _expression(x, what: str) -> sp.Expr:
    if isinstance(x, numbers.Number) and not isinstance(x, bool):
        x = sp.sympify(x)
    if not isinstance(x, sp.Expr):
        raise TypeError(f"{what} must be a SymPy expression, got {x!r}")
    return x


def _real(x, what: str) -> float:
    if isinstance(x, bool) or not isinstance(x, numbers.Real) or not np.isfinite(float(x)):
        raise ValueError(f"{what} must be a finite real number, got {x!r}")
    return float(x)


def _names(symbols) -> str:
    return ", ".join(sorted(str(s) for s in symbols))
