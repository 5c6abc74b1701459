r"""From the point-wise SymPy pieces of a system to kernel source text.

Stages (each a pure function of the previous one's output):

1. :func:`kernel_spec` collects the expressions of :math:`L`, :math:`L_q`,
   :math:`L_v`, :math:`L_{qq}`, :math:`L_{qv}`, :math:`L_{vv}`, drops the
   entries that are identically zero and renames the user's symbols to array
   slots ``q[a]``, ``v[a]``, ``prm[j]``.
2. :func:`signature` hashes the spec with the generator version and the
   sources of the time loop, naming the cache entry.
3. :func:`render_module` runs one joint common-subexpression elimination per
   point function, prints it strictly (an unsupported function fails here, not
   at run time) and appends the time loop of :mod:`.backends.kernel_template`.

This module only prints; compiling and caching are the backends' job.
"""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from importlib import resources
from typing import TYPE_CHECKING

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

if TYPE_CHECKING:
    from .system import LagrangianSystem

__all__ = [
    "GENERATOR_VERSION",
    "KernelSpec",
    "kernel_spec",
    "render_module",
    "signature",
    "unsupported_functions",
]

GENERATOR_VERSION = "2"
_KERNEL_MARKER = "\n# ---- kernel ----\n"
_END_MARKER = "\n# ---- end kernel ----\n"


@dataclass(frozen=True)
class KernelSpec:
    """Language-neutral description of one system's point functions.

    Each ``*_entries`` is a tuple of ``(target, expression)`` with target an
    array slot such as ``"Lqq[0, 1]"``; identically zero entries are absent.
    """

    n: int
    n_params: int
    autonomous: bool
    has_Lqv: bool
    lagrangian: sp.Expr
    gradient_entries: tuple[tuple[str, sp.Expr], ...]
    hessian_entries: tuple[tuple[str, sp.Expr], ...]


def kernel_spec(system: LagrangianSystem) -> KernelSpec:
    """Collect the expressions of ``system`` with symbols renamed to array slots."""
    n = system.n
    rename: dict[sp.Symbol, sp.Symbol] = {}
    for a, s in enumerate(system.q):
        rename[s] = sp.Symbol(f"q[{a}]", real=True)
    for a, s in enumerate(system.v):
        rename[s] = sp.Symbol(f"v[{a}]", real=True)
    for j, s in enumerate(system.params):
        rename[s] = sp.Symbol(f"prm[{j}]", real=True)
    if system.t is not None:
        rename[system.t] = sp.Symbol("t", real=True)
    p = system.pieces

    def entries(name: str, matrix: sp.Matrix, two_d: bool) -> list[tuple[str, sp.Expr]]:
        out = []
        for idx, expr in enumerate(matrix):
            expr = expr.xreplace(rename)
            if expr == 0:
                continue
            slot = f"{name}[{idx // n}, {idx % n}]" if two_d else f"{name}[{idx}]"
            out.append((slot, expr))
        return out

    gradient = entries("Lq", p.Lq, False) + entries("Lv", p.Lv, False)
    has_lqv = not system.structure.zero_Lqv
    hessian = (
        gradient
        + entries("Lqq", p.Lqq, True)
        + (entries("Lqv", p.Lqv, True) if has_lqv else [])
        + entries("Lvv", p.Lvv, True)
    )
    return KernelSpec(
        n=n,
        n_params=len(system.params),
        autonomous=system.structure.autonomous,
        has_Lqv=has_lqv,
        lagrangian=p.L.xreplace(rename),
        gradient_entries=tuple(gradient),
        hessian_entries=tuple(hessian),
    )


def _loop_sources() -> str:
    pkg = resources.files("galerkin_vi")
    return (pkg / "newton.py").read_text() + (pkg / "backends" / "kernel_template.py").read_text()


def signature(spec: KernelSpec, backend: str, backend_version: str) -> str:
    """SHA-256 naming the cache entry of ``spec`` for ``backend``."""
    h = hashlib.sha256()
    for part in (
        GENERATOR_VERSION,
        backend,
        backend_version,
        sys.version,
        repr((spec.n, spec.n_params, spec.autonomous, spec.has_Lqv)),
        sp.srepr(spec.lagrangian),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.hessian_entries),
        _loop_sources(),
    ):
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()


class _KernelPrinter(PythonCodePrinter):
    """Python printer with round-trip float literals and strict function support."""

    def __init__(self) -> None:
        super().__init__({"strict": True, "fully_qualified_modules": True})

    def _print_Float(self, expr: sp.Float) -> str:
        return repr(float(expr))

    def _print_Symbol(self, expr: sp.Symbol) -> str:
        return expr.name

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        # half-integer powers (gravity, r**(-3/2)) as sqrt and integer powers:
        # a call to pow costs several times a sqrt and a few multiplications
        exponent = expr.exp
        if isinstance(exponent, sp.Rational) and exponent.q == 2 and abs(exponent.p) <= 9:
            base = self.parenthesize(expr.base, sp.printing.precedence.PRECEDENCE["Pow"])
            whole = (abs(exponent.p) - 1) // 2
            magnitude = f"math.sqrt({self._print(expr.base)})"
            if whole:
                power = base if whole == 1 else f"{base}**{whole}"
                magnitude = f"({power}*{magnitude})"
            return magnitude if exponent.p > 0 else f"(1.0/{magnitude})"
        return super()._print_Pow(expr, rational=rational)


def unsupported_functions(expr: sp.Expr) -> list[str]:
    """Names of the functions in ``expr`` that the kernel printer cannot print."""
    printer = _KernelPrinter()
    names = set()
    for f in expr.atoms(sp.Function):
        try:
            printer.doprint(f)
        except (NotImplementedError, TypeError):
            names.add(type(f).__name__)
    return sorted(names)


def _function_body(entries: list[tuple[str, sp.Expr]], returns: sp.Expr | None = None) -> list[str]:
    printer = _KernelPrinter()
    exprs = [e for _, e in entries] + ([returns] if returns is not None else [])
    temporaries, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("_x"), optimizations="basic")
    lines = [f"    {sym} = {printer.doprint(rhs)}" for sym, rhs in temporaries]
    for (slot, _), expr in zip(entries, reduced[: len(entries)], strict=True):
        lines.append(f"    {slot} = {printer.doprint(expr)}")
    if returns is not None:
        lines.append(f"    return {printer.doprint(reduced[-1])}")
    return lines or ["    pass"]


def _kernel_section(path: str) -> str:
    text = (resources.files("galerkin_vi") / path).read_text()
    body = text.split(_KERNEL_MARKER, 1)[1]
    return body.split(_END_MARKER, 1)[0]


def render_module(
    spec: KernelSpec, key: str, decorator: str = 'njit(cache=True, inline="always")'
) -> str:
    """Source text of the kernel module for ``spec``.

    Parameters
    ----------
    spec : KernelSpec
    key : str
        The cache key; written on the first and last line so that a truncated
        or foreign file is recognised.
    decorator : str
        Expression applied to every kernel function (``"njit(cache=True)"`` for
        the compiled backend).
    """
    head = [
        f"# galerkin_vi generated kernel {key}",
        "# Generated from a SymPy Lagrangian; do not edit (rebuilt when stale).",
        "# ruff: noqa",
        "import math",
        "",
        "import numpy as np",
        "from numba import njit",
        "",
        f"kernel = {decorator}",
        f"N = {spec.n}",
        f"N_PARAMS = {spec.n_params}",
        f"AUTONOMOUS = {spec.autonomous}",
        f"HAS_LQV = {spec.has_Lqv}",
        "",
        "",
        "@kernel",
        "def point_gradient(t, q, v, prm, Lq, Lv):",
        *_function_body(list(spec.gradient_entries)),
        "",
        "",
        "@kernel",
        "def point_hessian(t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv):",
        *_function_body(list(spec.hessian_entries)),
        "",
        "",
        "@kernel",
        "def lagrangian(t, q, v, prm):",
        *_function_body([], returns=spec.lagrangian),
        "",
    ]
    newton = _kernel_section("newton.py")
    loop = _kernel_section("backends/kernel_template.py")
    # newton's helpers are plain functions; the loop calls them from jitted code
    newton = newton.replace("\ndef ", "\n@kernel\ndef ")
    tail = [f"# end of generated kernel {key}", ""]
    return "\n".join(head) + newton + loop + "\n".join(tail)
