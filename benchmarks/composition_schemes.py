"""The default scheme of each composition order: errors at an equal number of force evaluations.

For each order with several schemes (``gvi.Composition(order, scheme)``), the final
position error after the same number of Störmer–Verlet sub-steps (force evaluations)
on Kepler (e = 0.5, exact solution) and Hénon–Heiles (DOP853 reference), run in
mpmath (:class:`galerkin_vi.reference.mpmath.MpComposition`, 20 digits) so that
round-off plays no part. The scheme with the smallest errors is ``Composition(order)``'s
default (:data:`galerkin_vi.method.composition.DEFAULT_SCHEMES`); the splittings of
Blanes and Moan ("blanes_moan") count one force per drift, as the loop evaluates them.

Usage::

    python benchmarks/composition_schemes.py
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import galerkin_vi as gvi
from galerkin_vi.problems.gravitation import kepler
from galerkin_vi.problems.mechanics import henon_heiles
from galerkin_vi.reference.mpmath import MpComposition

#: order -> schemes compared
CANDIDATES = {
    4: ("yoshida", "suzuki", "blanes_moan"),
    6: ("yoshida", "kahan_li", "blanes_moan"),
    8: ("mclachlan", "kahan_li"),
}


def error(problem, method: gvi.Composition, evaluations: int, dps: int) -> tuple[int, float]:
    """Steps and final position error of ``method`` with about ``evaluations`` forces."""
    steps = evaluations // method.stages
    prm = problem.system.parameter_vector(problem.params)
    q, _ = MpComposition(problem.system, method, dps=dps).final_state(
        problem.q0, problem.v0, 0.0, problem.t_final, steps, prm
    )
    reference = problem.reference(problem.t_final)
    return steps, max(abs(float(x) - r) for x, r in zip(q, reference, strict=True))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/composition_schemes.py")
    parser.add_argument("--evaluations", nargs="+", type=int, default=[1260, 2520])
    parser.add_argument("--dps", type=int, default=20)
    args = parser.parse_args(argv)
    width = max(len(schemes) for schemes in CANDIDATES.values())
    cells = " | ".join(["scheme (stages): N, error"] * width)
    print(f"| problem | order | forces | {cells} |")
    print("|---|---:|---:|" + "---|" * width)
    for problem in (kepler(0.5), henon_heiles()):
        for order, schemes in CANDIDATES.items():
            for evaluations in args.evaluations:
                cells = []
                for scheme in schemes:
                    method = gvi.Composition(order, scheme)
                    steps, err = error(problem, method, evaluations, args.dps)
                    cells.append(f"{scheme} ({method.stages}): {steps}, {err:.2e}")
                cells += [""] * (width - len(cells))
                print(f"| {problem.name} | {order} | {evaluations} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
