"""The figure of docs/architecture.md: the stages of a run and what each owns.

Draws ``docs/_static/run_pipeline.png`` from the table below (no run needed).
Run from the repository root::

    python docs/_scripts/run_pipeline.py
"""

# ruff: noqa: E501 - the table of boxes keeps one box a line

from __future__ import annotations

from pathlib import Path

OUTPUT = Path(__file__).resolve().parents[1] / "_static" / "run_pipeline.png"

#: (column, row, folder or module, what it owns); columns are the layers, top to bottom
# fmt: off
BOXES = [
    (0, 0, "model/", "LagrangianSystem: validation,\nstructure, derived-data cache;\nContact declarations"),
    (1, 0, "method/", "Galerkin tables, quadrature,\nstage-form and\nvelocity-stage tables"),
    (2, 0, "codegen/", "point functions: SymPy ->\nCSE'd source -> compiled,\ncached per system"),
    (3, 0, "loops/", "time loops, compiled once\nper machine; one calling\nconvention (loops/abi.py)"),
    (0, 1, "run/plan.py", "RunPlan: h, n_steps,\nt0, save_every"),
    (1, 1, "run/start.py", "Legendre start,\nconstraint projection"),
    (2, 1, "run/spec.py\nrun/segment.py", "RunSpec (frozen): loop,\naddresses, tables;\none compiled call"),
    (3, 1, "run/chunks.py", "chunks, progress,\nCtrl-C, terminal stop"),
    (0, 2, "run/trust.py\nrun/failures.py", "explosive growth,\ninstability warning,\non_failure"),
    (1, 2, "run/dense.py\nrun/piecewise.py", "dense output (Hermite),\npiecewise across impacts"),
    (2, 2, "run/events.py\nrun/outputs.py", "events, t_eval rows,\nsave_every rows"),
    (3, 2, "run/smooth.py\nrun/ensemble.py", "a run without contacts;\nensembles, stream"),
    (0, 3, "contact/", "impacts, complementarity\nsteps; their run options\nthrough run/"),
    (1, 3, "action/", "BVPs, periodic orbits,\noptimal control"),
    (2, 3, "integrator.py\nadaptive.py", "front doors: Integrator,\nAdaptiveIntegrator"),
    (3, 3, "tools/  testing.py", "verification, choice,\nbenchmarks, CLI, warm-up"),
]
# fmt: on
LAYERS = ["stages of the model", "a run, stage by stage", "what a run returns", "solvers and doors"]


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

    fig, ax = plt.subplots(figsize=(13, 7.5))
    ax.set_xlim(-0.2, 4.1)
    ax.set_ylim(-0.6, 4.0)
    ax.invert_yaxis()
    ax.axis("off")
    colours = ["#dbe9f6", "#e6f4e1", "#fdf0d5", "#f3e1ef"]
    for col, row, name, owns in BOXES:
        x, y = 0.05 + col, 0.1 + row
        box = FancyBboxPatch(
            (x, y), 0.9, 0.8, boxstyle="round,pad=0.02", fc=colours[row], ec="#555555"
        )
        ax.add_patch(box)
        ax.text(x + 0.45, y + 0.17, name, ha="center", va="center", fontsize=9.5,
                fontweight="bold", family="monospace")  # fmt: skip
        ax.text(x + 0.45, y + 0.55, owns, ha="center", va="center", fontsize=8.5)
        if col < 3:
            ax.add_patch(FancyArrowPatch((x + 0.92, y + 0.4), (x + 1.03, y + 0.4),
                                         arrowstyle="-|>", mutation_scale=20, lw=1.5))  # fmt: skip
    for row, label in enumerate(LAYERS):
        ax.text(4.02, 0.5 + row, label, rotation=270, ha="center", va="center", fontsize=9,
                color="#444444")  # fmt: skip
    ax.text(0.05, -0.35, "Data flow, left to right and top to bottom: a module imports only from "
            "the stages before it (above it, or to its left in its row)", fontsize=10)  # fmt: skip
    fig.tight_layout()
    fig.savefig(OUTPUT, dpi=110)
    print(f"wrote {OUTPUT}")


if __name__ == "__main__":
    main()
