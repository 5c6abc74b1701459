r"""The instances of a repeated term written side by side, their square roots and
divisions four at a time.

A repeated term (a pair potential, a spring of a lattice) is one template
evaluated at many argument tuples. Evaluated one instance after another, every
square root and division waits for the previous one's unit: for the
:math:`1/r^3` of a pair force these two instructions bound the whole force.
Here every square root and every division of the template is lifted into a
statement of its own (an :mod:`ast` rewrite of the printed text, so that each
operation keeps its operands and its rounding), the statements are written for
all instances, statement by statement, and a statement that is a square root or
a division is one call of :func:`galerkin_vi.loops.vector_math.sqrt4` or
:func:`~galerkin_vi.loops.vector_math.divide4` per four instances. The
instances' contributions are then added in their original order, so that every
sum is the one-instance-at-a-time loop's, bit for bit.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass

__all__ = ["IDENTIFIER", "IMPORT", "LANES", "Statement", "lane_lines", "lifted_statements"]

#: instances per call of the intrinsics (:data:`galerkin_vi.loops.vector_math.LANES`)
LANES = 4

#: the import a module using :func:`lane_lines` needs
IMPORT = "from galerkin_vi.loops.vector_math import divide4, sqrt4"

#: a Python name in generated text
IDENTIFIER = re.compile(r"\b[A-Za-z_]\w*\b")


@dataclass(frozen=True)
class Statement:
    """One assignment of a template: ``target = expression`` (``kind`` ``"scalar"``,
    one operand), ``target = math.sqrt(x)`` (``"sqrt"``) or ``target = a / b``
    (``"divide"``), its operands as Python expressions over the template's names."""

    target: str
    kind: str
    operands: tuple[str, ...]


def _is_sqrt(node: ast.AST) -> bool:
    return (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and isinstance(node.func.value, ast.Name)
        and node.func.value.id == "math"
        and node.func.attr == "sqrt"
        and len(node.args) == 1
        and not node.keywords
    )


def _constant(node: ast.AST) -> bool:
    """Whether ``node`` names no variable (Python folds it when compiling)."""
    return not any(isinstance(n, (ast.Name, ast.Subscript)) for n in ast.walk(node))


class _Lift(ast.NodeTransformer):
    """Replace each square root and division (innermost first) by a new name."""

    def __init__(self, statements: list[Statement], seen: dict, prefix: str):
        self.statements = statements
        self.seen = seen
        self.prefix = prefix

    def visit_IfExp(self, node: ast.IfExp) -> ast.AST:
        # a branch not taken is not evaluated: what it divides may be zero there
        return node

    def visit_BoolOp(self, node: ast.BoolOp) -> ast.AST:
        return node

    def visit_Call(self, node: ast.Call) -> ast.AST:
        self.generic_visit(node)
        return self._lift("sqrt", node.args) if _is_sqrt(node) else node

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        if isinstance(node.op, ast.Div) and not (_constant(node.left) and _constant(node.right)):
            return self._lift("divide", [node.left, node.right])
        return node

    def _lift(self, kind: str, operands: list[ast.AST]) -> ast.Name:
        key = (kind, tuple(ast.unparse(operand) for operand in operands))
        if key not in self.seen:
            # every name of a template is assigned once: equal text, equal value
            self.seen[key] = f"{self.prefix}{len(self.seen)}"
            self.statements.append(Statement(self.seen[key], kind, key[1]))
        return ast.Name(self.seen[key], ast.Load())


def lifted_statements(
    assignments: list[tuple[str, str]], prefix: str
) -> list[Statement]:  # fmt: skip
    r"""The assignments ``(target, expression)`` with each square root and division
    as a statement of its own (new names ``prefix0``, ``prefix1``, ...), in an order
    that computes every name before its use.

    A division of two constants (``1/2``) stays: Python folds it. Nothing inside a
    conditional expression or a boolean operation is lifted (a lifted statement is
    always evaluated). Each target is assigned once: a sum written in chunks
    (``x = a``, ``x += b``) is passed as one assignment ``x = (a) + (b)``.
    """
    statements: list[Statement] = []
    seen: dict = {}
    lift = _Lift(statements, seen, prefix)
    for target, expression in assignments:
        tree = lift.visit(ast.parse(expression, mode="eval"))
        body = tree.body
        if isinstance(body, ast.Name) and body.id.startswith(prefix) and statements:
            # the whole expression was lifted: name its statement after the target. Each
            # assignment ends with a statement of its own, so a last statement with the
            # prefix is this expression's outermost lift
            last = statements[-1]
            if last.target == body.id:
                statements[-1] = Statement(target, last.kind, last.operands)
                for key, name in seen.items():
                    if name == body.id:
                        seen[key] = target
                continue
        statements.append(Statement(target, "scalar", (ast.unparse(body),)))
    return statements


def _renamed(text: str, names: frozenset[str], suffix: str) -> str:
    """``text`` with ``suffix`` appended to each of ``names``."""
    return IDENTIFIER.sub(lambda m: m.group(0) + (suffix if m.group(0) in names else ""), text)


def _call_line(statement: Statement, names: frozenset[str], suffixes: list[str]) -> str:
    """One intrinsic call for up to :data:`LANES` instances (the last padded with
    copies of its operands, whose results are discarded)."""
    padded = suffixes + [suffixes[-1]] * (LANES - len(suffixes))
    targets = [statement.target + s for s in suffixes] + ["_pad"] * (LANES - len(suffixes))
    operands = [_renamed(operand, names, s) for operand in statement.operands for s in padded]
    function = "sqrt4" if statement.kind == "sqrt" else "divide4"
    return f"{', '.join(targets)} = {function}({', '.join(operands)})"


def lane_lines(
    statements: list[Statement], names: frozenset[str], suffixes: list[str]
) -> list[str]:
    """Lines computing ``statements`` for every instance, statement by statement.

    Instance ``s`` of ``suffixes`` reads and writes each name of ``names`` with
    ``s`` appended. A square root or division is one intrinsic call per
    :data:`LANES` instances; a remainder of one instance is written as scalar code.
    """
    lines = []
    for statement in statements:
        if statement.kind == "scalar":
            for s in suffixes:
                lines.append(f"{statement.target}{s} = {_renamed(statement.operands[0], names, s)}")
            continue
        for start in range(0, len(suffixes), LANES):
            chunk = suffixes[start : start + LANES]
            if len(chunk) > 1:
                lines.append(_call_line(statement, names, chunk))
                continue
            s = chunk[0]
            ops = [f"({_renamed(operand, names, s)})" for operand in statement.operands]
            value = f"math.sqrt{ops[0]}" if statement.kind == "sqrt" else " / ".join(ops)
            lines.append(f"{statement.target}{s} = {value}")
    return lines
