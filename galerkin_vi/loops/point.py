r"""Calls of a system's point functions by address, from compiled loops.

The time loops are compiled once per machine; what differs between systems
are only the point functions (:math:`L_q + f`, :math:`L_v`, the second
derivatives, the constraints), which :mod:`galerkin_vi.codegen` compiles per
system as C-callable functions. A loop receives their addresses as int64
values in the array ``fn`` (slots below) and calls them through the
intrinsics here: an ``inttoptr`` and a call. Since no argument type names the
function, numba's disk cache of a loop holds for every system.

Signatures (every array argument is a ``double *`` to the first element of a
C-contiguous float64 array; the functions are called with numba's calling
convention, see :func:`_emit_call`; the slot numbers are those of :mod:`.abi`):

=====================  ===================================================================
slot                   function
=====================  ===================================================================
``GRADIENT``           ``void(double t, q, v, prm, Lq, Lv)``
``HESSIAN``            ``void(double t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)``
``LAGRANGIAN``         ``double(double t, q, v, prm)``
``CONSTRAINT``         ``void(double t, q, prm, g)``
``CONSTRAINT_JAC``     ``void(double t, q, prm, Gq)``
``CONSTRAINT_RATE``    ``void(double t, q, prm, gt)``
``CONSTRAINT_HESS``    ``void(double t, q, lam, prm, Hg)``
``MASS``               ``void(double t, q, v, prm, Lq, Lv, Lqv, Lvv)``
``VELOCITY``           ``void(double t, q, p, prm, F, V)``
``CONTACT``            ``void(double t, q, v, prm, cg, cG, cH)``
``SLIP``               ``void(double t, q, v, prm, w, Wq, Wv, Wvq)``
=====================  ===================================================================

Entries that are identically zero are never written: the loops zero those
arrays once. An address of 0 marks a function the loop does not need.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ._jit import kernel
from .abi import (
    CONSTRAINT,
    CONSTRAINT_HESS,
    CONSTRAINT_JAC,
    CONSTRAINT_RATE,
    CONTACT,
    GRADIENT,
    HESSIAN,
    LAGRANGIAN,
    MASS,
    N_SLOTS,
    SLIP,
    VELOCITY,
)

__all__ = [
    "CONSTRAINT",
    "CONSTRAINT_HESS",
    "CONSTRAINT_JAC",
    "CONSTRAINT_RATE",
    "CONTACT",
    "GRADIENT",
    "HESSIAN",
    "LAGRANGIAN",
    "MASS",
    "N_SLOTS",
    "SLIP",
    "VELOCITY",
    "point_constraint",
    "point_constraint_hessian",
    "point_constraint_jacobian",
    "point_constraint_rate",
    "point_contact",
    "point_gradient",
    "point_gradient_row",
    "point_hessian",
    "point_mass_row",
    "point_slip",
    "point_velocity_row",
]


def _check_arrays(arrays) -> None:
    for array in arrays:
        if not (
            isinstance(array, types.Array)
            and array.dtype == types.float64
            and array.ndim == 1
            and array.layout == "C"
        ):
            raise TypingError(f"point functions take C-contiguous float64 vectors, got {array}")


def _emit_call(context, builder, signature, args, returns_double: bool):
    """``f(&result, &error, t, data(a1), ..., data(ak))`` with ``f`` the function at ``args[0]``.

    ``f`` is the compiled body of a numba ``cfunc``, called with numba's own
    calling convention (a status as result, the return value through the first
    pointer, exception information through the second), not through the C
    wrapper around it: the wrapper would be a second call per evaluation (it
    does not inline the body), a few per cent of a step of a small system. The
    point functions raise no exceptions (NumPy's error model: NaN and inf flow
    into the loops' finiteness checks), so the status is not read.
    """
    address, t, *arrays = args
    pointers = []
    for array_type, value in zip(signature.args[2:], arrays, strict=True):
        pointers.append(context.make_array(array_type)(context, builder, value).data)
    loaded = _call_pointers(builder, address, t, pointers, returns_double)
    return loaded if returns_double else context.get_dummy_value()


def _call_pointers(builder, address, t, pointers, returns_double: bool):
    """Emit ``f(&result, &error, t, *pointers)``; the loaded result, or None."""
    double = ir.DoubleType()
    opaque = ir.IntType(8).as_pointer()
    result = cgutils.alloca_once(builder, double)
    error = cgutils.alloca_once(builder, opaque)
    function_type = ir.FunctionType(
        ir.IntType(32),
        [double.as_pointer(), opaque.as_pointer(), double] + [double.as_pointer()] * len(pointers),
    )
    function = builder.inttoptr(address, function_type.as_pointer())
    builder.call(function, [result, error, t, *pointers])
    return builder.load(result) if returns_double else None


def _typer(address, t, arrays, returns_double=False):
    """Signature and code generator of ``call(address, t, *arrays)``."""
    if not isinstance(address, types.Integer):
        raise TypingError(f"a point function's address is an integer, got {address}")
    _check_arrays(arrays)
    result = types.float64 if returns_double else types.void
    signature = result(address, types.float64, *arrays)

    def codegen(context, builder, sig, args):
        t_value = context.cast(builder, args[1], sig.args[1], types.float64)
        return _emit_call(context, builder, sig, [args[0], t_value, *args[2:]], returns_double)

    return signature, codegen


def _is_table(array) -> bool:
    return (
        isinstance(array, types.Array)
        and array.dtype == types.float64
        and array.ndim == 2
        and array.layout == "C"
    )


def _row_call_typer(address, t, q, v, prm, G, Gv, row, extra):
    """Signature and code generator of a call that writes L_q + f into row ``row`` of ``G``.

    ``Gv`` is a table (its row ``row`` receives L_v) or a vector; ``extra``
    holds further output vectors, passed after them (the mass call's L_vv).
    """
    if not _is_table(G):
        raise TypingError(f"the force table is a C-contiguous 2-D float64 array, got {G}")
    if not isinstance(row, types.Integer):
        raise TypingError(f"a row index is an integer, got {row}")
    if not isinstance(address, types.Integer):
        raise TypingError(f"a point function's address is an integer, got {address}")
    _check_arrays((q, v, prm, *extra))
    if not _is_table(Gv):
        _check_arrays((Gv,))
    signature = types.void(address, t, q, v, prm, G, Gv, *extra, row)

    def codegen(context, builder, sig, args):
        address_value, t_value, q_value, v_value, prm_value, table, table_v = args[:7]
        extra_values = args[7:-1]
        t_value = context.cast(builder, t_value, sig.args[1], types.float64)
        pointers = [
            context.make_array(array_type)(context, builder, value).data
            for array_type, value in ((q, q_value), (v, v_value), (prm, prm_value))
        ]
        index = context.cast(builder, args[-1], row, types.intp)
        zero = context.get_constant(types.intp, 0)
        for array_type, value in ((G, table), (Gv, table_v)):
            struct = context.make_array(array_type)(context, builder, value)
            if array_type.ndim == 2:
                pointers.append(
                    cgutils.get_item_pointer(context, builder, array_type, struct, [index, zero])
                )
            else:
                pointers.append(struct.data)
        for array_type, value in zip(extra, extra_values, strict=True):
            pointers.append(context.make_array(array_type)(context, builder, value).data)
        _call_pointers(builder, address_value, t_value, pointers, returns_double=False)
        return context.get_dummy_value()

    return signature, codegen


@intrinsic
def _call_gradient_row(typingctx, address, t, q, v, prm, G, Gv, row):
    """The gradient call with :math:`L_q + f` written into row ``row`` of the 2-D ``G``,
    and :math:`L_v` into row ``row`` of ``Gv`` (2-D) or into ``Gv`` (a vector)."""
    return _row_call_typer(address, t, q, v, prm, G, Gv, row, ())


@intrinsic
def _call_mass_row(typingctx, address, t, q, v, prm, G, Gv, Lqv, Lvv, row):
    """The mass call: as :func:`_call_gradient_row`, then :math:`L_{qv} + f_v` into
    ``Lqv`` and :math:`L_{vv}` into ``Lvv``."""
    return _row_call_typer(address, t, q, v, prm, G, Gv, row, (Lqv, Lvv))


# numba's @intrinsic reads the parameter names: one explicit definition per arity
@intrinsic
def _call3(typingctx, address, t, a1, a2, a3):
    return _typer(address, t, (a1, a2, a3))


@intrinsic
def _call3_double(typingctx, address, t, a1, a2, a3):
    return _typer(address, t, (a1, a2, a3), returns_double=True)


@intrinsic
def _call4(typingctx, address, t, a1, a2, a3, a4):
    return _typer(address, t, (a1, a2, a3, a4))


@intrinsic
def _call5(typingctx, address, t, a1, a2, a3, a4, a5):
    return _typer(address, t, (a1, a2, a3, a4, a5))


@intrinsic
def _call6(typingctx, address, t, a1, a2, a3, a4, a5, a6):
    return _typer(address, t, (a1, a2, a3, a4, a5, a6))


@intrinsic
def _call7(typingctx, address, t, a1, a2, a3, a4, a5, a6, a7):
    return _typer(address, t, (a1, a2, a3, a4, a5, a6, a7))


@intrinsic
def _call9(typingctx, address, t, a1, a2, a3, a4, a5, a6, a7, a8, a9):
    return _typer(address, t, (a1, a2, a3, a4, a5, a6, a7, a8, a9))


@kernel
def point_gradient(fn, t, q, v, prm, Lq, Lv):
    """Write :math:`L_q + f` into ``Lq`` and :math:`L_v` into ``Lv`` at (t, q, v)."""
    _call5(fn[GRADIENT], t, q, v, prm, Lq, Lv)


@kernel
def point_gradient_row(fn, t, q, v, prm, G, Gv, row):
    """As :func:`point_gradient`, with :math:`L_q + f` written into ``G[row, :]`` and
    :math:`L_v` into ``Gv[row, :]`` (``Gv`` a table) or ``Gv`` (a vector).

    The loops keep the gradients of their quadrature points as the rows of
    tables; writing them in place saves a copy per point and sweep.
    """
    _call_gradient_row(fn[GRADIENT], t, q, v, prm, G, Gv, row)


@kernel
def point_hessian(fn, t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv):
    """The gradient and the flat second derivatives (:math:`L_{qq} + f_q`, :math:`L_{qv}`,
    :math:`L_{vv}`, and :math:`f_v` when the forces depend on v)."""
    _call9(fn[HESSIAN], t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)


@kernel
def point_mass_row(fn, t, q, v, prm, G, Lv, Lqv, Lvv, row):
    r""":math:`L_q + f` into ``G[row, :]``, :math:`L_v` into ``Lv``, and flat dense
    :math:`L_{qv} + f_v` (``Lqv[a n + b]`` :math:`= \partial (L_q + f)_a/\partial v_b`) and
    :math:`L_{vv}` into ``Lqv``, ``Lvv``: what a sweep of the varying-mass loop needs, no
    :math:`L_{qq}`."""
    _call_mass_row(fn[MASS], t, q, v, prm, G, Lv, Lqv, Lvv, row)


@kernel
def point_velocity_row(fn, t, q, p, prm, F, V, row):
    r"""The velocity :math:`v = M^{-1}(p - a)` at (t, q, p) into ``V[row, :]`` and
    :math:`(L_q + f)(t, q, v)` into ``F[row, :]``: a Gauss stage of the varying-mass
    loop from its position and momentum, when the system has ``point_velocity``."""
    _call_gradient_row(fn[VELOCITY], t, q, p, prm, F, V, row)


@kernel
def lagrangian(fn, t, q, v, prm):
    """Return :math:`L(t, q, v)`."""
    return _call3_double(fn[LAGRANGIAN], t, q, v, prm)


@kernel
def point_constraint(fn, t, q, prm, g):
    """Write the constraint values :math:`g_j(t, q)` into ``g``."""
    _call3(fn[CONSTRAINT], t, q, prm, g)


@kernel
def point_constraint_jacobian(fn, t, q, prm, Gq):
    r"""Write :math:`\partial g_j/\partial q_a` into ``Gq[j n + a]``."""
    _call3(fn[CONSTRAINT_JAC], t, q, prm, Gq)


@kernel
def point_constraint_rate(fn, t, q, prm, gt):
    r"""Write :math:`\partial g_j/\partial t` into ``gt``."""
    _call3(fn[CONSTRAINT_RATE], t, q, prm, gt)


@kernel
def point_constraint_hessian(fn, t, q, lam, prm, Hg):
    r"""Write :math:`\sum_j \lambda_j \partial^2 g_j/\partial q_a\partial q_b` into
    ``Hg[a n + b]``."""
    _call4(fn[CONSTRAINT_HESS], t, q, lam, prm, Hg)


@kernel
def point_contact(fn, t, q, v, prm, cg, cG, cH):
    r"""Write the gaps :math:`\varphi_j` into ``cg``, their gradients into ``cG[j n + a]``
    and their Hessians into ``cH[(j n + a) n + b]``."""
    _call6(fn[CONTACT], t, q, v, prm, cg, cG, cH)


@kernel
def point_slip(fn, t, q, v, prm, w, Wq, Wv, Wvq):
    r"""Write the stacked slip velocities :math:`w_k` into ``w`` and
    :math:`\partial w_k/\partial q_a`, :math:`\partial w_k/\partial v_a`,
    :math:`\partial^2 w_k/\partial v_a \partial q_b` into ``Wq[k n + a]``,
    ``Wv[k n + a]``, ``Wvq[(k n + a) n + b]``."""
    _call7(fn[SLIP], t, q, v, prm, w, Wq, Wv, Wvq)
