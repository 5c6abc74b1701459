r"""Square roots and divisions of four doubles in one instruction, for generated code.

A pair potential's force divides by :math:`r^3 = r^2\sqrt{r^2}` at every pair: a
square root and a division, the two arithmetic instructions whose scalar forms
issue a result only every several cycles, so that they, not the additions and
products, bound a small n-body force. The instances of a repeated term are
independent, but LLVM does not put them into vector registers: numba leaves its
straight-line (SLP) vectoriser off. The generated code therefore writes the
instances side by side (:mod:`galerkin_vi.codegen.lanes`) and calls these
intrinsics, which place four operands in one ``<4 x double>`` register and emit
``llvm.sqrt.v4f64`` and one ``fdiv``.

IEEE 754 rounds a square root and a quotient correctly in every lane, so each
result is the scalar ``math.sqrt(x)`` and ``a / b`` bit for bit (no fast-math
flag is set). On a machine without 256-bit registers LLVM splits the operation
into narrower ones, with the same results. The generated modules' cache keys hash
this file (:func:`galerkin_vi.codegen.compiled.fingerprint_sources`), so that a change
here compiles them afresh.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.core.errors import TypingError
from numba.extending import intrinsic, overload

__all__ = ["LANES", "divide4", "sqrt4"]

#: the operands of one call
LANES = 4

_DOUBLES = ir.VectorType(ir.DoubleType(), LANES)


def _typed(name: str, operands: tuple) -> types.UniTuple:
    for operand in operands:
        # float32 would be rounded as a double here but as a float32 by the scalar code
        if operand != types.float64 and not isinstance(operand, (types.Integer, types.Boolean)):
            raise TypingError(f"{name} takes float64, integers or booleans, not {operand}")
    return types.UniTuple(types.float64, LANES)(*operands)


def _packed(context, builder, values, value_types):
    """The ``<4 x double>`` of ``values`` (each converted to float64)."""
    packed = ir.Constant(_DOUBLES, ir.Undefined)
    for lane, (value, value_type) in enumerate(zip(values, value_types, strict=True)):
        double = context.cast(builder, value, value_type, types.float64)
        packed = builder.insert_element(packed, double, ir.Constant(ir.IntType(32), lane))
    return packed


def _unpacked(context, builder, signature, packed):
    lanes = [builder.extract_element(packed, ir.Constant(ir.IntType(32), k)) for k in range(LANES)]
    return context.make_tuple(builder, signature.return_type, lanes)


@intrinsic
def _sqrt4(typingctx, x0, x1, x2, x3):
    signature = _typed("sqrt4", (x0, x1, x2, x3))

    def codegen(context, builder, signature, args):
        packed = _packed(context, builder, args, signature.args)
        # llvmlite's declare_intrinsic names no vector types: declared by its full name
        module, name = builder.module, "llvm.sqrt.v4f64"
        function = module.globals.get(name)
        if function is None:
            function = ir.Function(module, ir.FunctionType(_DOUBLES, [_DOUBLES]), name)
        return _unpacked(context, builder, signature, builder.call(function, [packed]))

    return signature, codegen


@intrinsic
def _divide4(typingctx, a0, a1, a2, a3, b0, b1, b2, b3):
    signature = _typed("divide4", (a0, a1, a2, a3, b0, b1, b2, b3))

    def codegen(context, builder, signature, args):
        numerators = _packed(context, builder, args[:LANES], signature.args[:LANES])
        divisors = _packed(context, builder, args[LANES:], signature.args[LANES:])
        return _unpacked(context, builder, signature, builder.fdiv(numerators, divisors))

    return signature, codegen


def sqrt4(x0, x1, x2, x3):
    """``(sqrt(x0), sqrt(x1), sqrt(x2), sqrt(x3))``, each correctly rounded (a negative
    operand gives NaN, as numba's ``math.sqrt``). Compiled, one vector instruction."""
    with np.errstate(invalid="ignore"):
        return tuple(float(r) for r in np.sqrt(np.array([x0, x1, x2, x3], dtype=np.float64)))


def divide4(a0, a1, a2, a3, b0, b1, b2, b3):
    """``(a0 / b0, a1 / b1, a2 / b2, a3 / b3)``, each correctly rounded (a zero divisor
    gives an infinity or NaN, as numba's ``error_model="numpy"``). Compiled, one
    vector instruction."""
    numerators = np.array([a0, a1, a2, a3], dtype=np.float64)
    with np.errstate(all="ignore"):
        quotients = numerators / np.array([b0, b1, b2, b3], dtype=np.float64)
    return tuple(float(r) for r in quotients)


@overload(sqrt4, jit_options={"error_model": "numpy"})
def _sqrt4_compiled(x0, x1, x2, x3):
    return lambda x0, x1, x2, x3: _sqrt4(x0, x1, x2, x3)


@overload(divide4, jit_options={"error_model": "numpy"})
def _divide4_compiled(a0, a1, a2, a3, b0, b1, b2, b3):
    return lambda a0, a1, a2, a3, b0, b1, b2, b3: _divide4(a0, a1, a2, a3, b0, b1, b2, b3)
