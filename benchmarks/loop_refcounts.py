"""Count numba's reference-count calls inside the step loops of the compiled time loops.

numba's atomic ``NRT_incref``/``NRT_decref`` pairs that its pruning pass cannot remove
cost about a third of a small system's step when they sit inside the step loop. This
script compiles the general and stage-form loops afresh (in a temporary cache, so that
the optimised LLVM IR is at hand), finds the blocks of each function that lie on a cycle
of its control-flow graph (strongly connected components: the loops' bodies) and lists
the reference-count calls in them. Expected output: ``inside loops 0`` for every
compiled variant.

Usage::

    python benchmarks/loop_refcounts.py            # about a minute: compiles two loops
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from collections import defaultdict

# a fresh cache: loops loaded from disk carry machine code, not IR
os.environ["GALERKIN_VI_CACHE_DIR"] = tempfile.mkdtemp(prefix="gvi-refcounts-")
os.environ["GALERKIN_VI_WARMUP_CHILD"] = "1"  # compile only what the two runs need

import numpy as np  # noqa: E402
import sympy as sp  # noqa: E402

import galerkin_vi as gvi  # noqa: E402
from galerkin_vi import loops  # noqa: E402

_REFCOUNT = re.compile(r"call void @NRT_(incref|decref)")
_LABEL = re.compile(r"^([\w.\-]+):")
_TARGET = re.compile(r"label %([\w.\-]+)")


def _blocks(body: str) -> tuple[list[str], dict[str, list[str]]]:
    order, blocks, current = ["entry"], {"entry": []}, "entry"
    for line in body.splitlines()[1:]:
        label = _LABEL.match(line)
        if label:
            current = label.group(1)
            order.append(current)
            blocks[current] = []
        else:
            blocks[current].append(line)
    return order, blocks


def _on_cycles(order: list[str], successors: dict[str, list[str]]) -> set[str]:
    """Blocks in a strongly connected component with a cycle (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cyclic: set[str] = set()
    counter = 0
    for root in order:
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = counter
                counter += 1
                stack.append(node)
                on_stack.add(node)
            children = successors[node]
            if i < len(children):
                work.append((node, i + 1))
                child = children[i]
                if child not in index:
                    work.append((child, 0))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            for child in children:
                if child in on_stack:
                    low[node] = min(low[node], low[child])
            if low[node] == index[node]:
                component = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    component.append(top)
                    if top == node:
                        break
                if len(component) > 1 or node in successors[node]:
                    cyclic.update(component)
    return cyclic


def refcounts_in_loops(ir: str, name: str) -> tuple[int, list[str]]:
    """(all reference-count calls, those inside loops) of function ``name`` in ``ir``."""
    match = re.search(r"define [^\n]*@\"?" + re.escape(name) + r"\"?\(.*?\n\}", ir, re.S)
    order, blocks = _blocks(match.group(0))
    successors = defaultdict(list)
    for block in order:
        for line in blocks[block]:
            stripped = line.strip()
            if stripped.startswith(("br ", "switch ")):
                successors[block] += _TARGET.findall(line)
    cyclic = _on_cycles(order, successors)
    total = sum(1 for b in order for line in blocks[b] if _REFCOUNT.search(line))
    inside = [f"{b}: {ln.strip()}" for b in order if b in cyclic for ln in blocks[b]
              if _REFCOUNT.search(ln)]  # fmt: skip
    return total, inside


def _compile_examples() -> None:
    q1, q2, v1, v2 = sp.symbols("q1 q2 v1 v2")
    double_pendulum = gvi.LagrangianSystem(
        v1**2 + v2**2 / 2 + v1 * v2 * sp.cos(q1 - q2) + 2 * sp.cos(q1) + sp.cos(q2),
        [q1, q2], [v1, v2],
    )  # fmt: skip
    gvi.Integrator(double_pendulum, gvi.Galerkin(2, gvi.gauss_legendre(2))).integrate(
        np.array([0.5, 0.2]), np.zeros(2), h=0.05, n_steps=10
    )
    pendulum = gvi.LagrangianSystem(v1**2 / 2 + sp.cos(q1), [q1], [v1])
    gvi.Integrator(pendulum, gvi.Galerkin(3)).integrate(
        np.array([0.5]), np.zeros(1), h=0.05, n_steps=10
    )


def main() -> int:
    _compile_examples()
    clean = True
    for name in ("general_loop", "stage_form_loop"):
        dispatcher = getattr(loops, name)
        for signature in dispatcher.signatures:
            ir = dispatcher.inspect_llvm(signature)
            defined = re.findall(r"define [^@]*@\"?([^\"(]*" + name + r"[^\"(]*)\"?\(", ir)
            for function in defined:
                if function.startswith("cpython") or "cfunc" in function:
                    continue
                total, inside = refcounts_in_loops(ir, function)
                print(f"{name}: {total} reference-count calls, inside loops {len(inside)}")
                for line in inside:
                    print("    " + line)
                clean = clean and not inside
    return 0 if clean else 1


if __name__ == "__main__":
    sys.exit(main())
