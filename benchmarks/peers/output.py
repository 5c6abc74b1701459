"""Writers of the peer benchmark: results.md (tables), results.json and PNG plots."""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence

from galerkin_vi.tools import benchmark as bm

from .cases import CHAIN_BETA
from .workprecision import best_peer_ratios, chain_growth

__all__ = ["markdown", "write_outputs"]


def _fmt_ratio(x: float | None) -> str:
    return "—" if x is None else f"{x:.3g}"


_SUMMARY_PEERS = ("DOP853", "numbalsoda", "hand-written", "IAS15", "WHFast")


def _summary_lines(results: dict) -> list[str]:
    """One table over all problems: the best galerkin_vi time and each peer family's ratio."""
    if not results["problems"]:
        return []
    lines = [
        "## Summary: best galerkin_vi configuration against the peers",
        "",
        "Peer time / best galerkin_vi time at the same final error (> 1: galerkin_vi is "
        "faster). For the hand-written kernels the fastest of them is named. Empty: the "
        "peer does not apply to the problem or is not installed; —: the peer or galerkin_vi "
        "did not reach the target within its sweep.",
        "",
        "| problem | target | best galerkin_vi (s) | scipy DOP853 | numbalsoda DOP853 | "
        "best hand-written | REBOUND IAS15 | REBOUND WHFast |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, entry in results["problems"].items():
        for target, best in entry["best_galerkin_vi"].items():
            peers = best_peer_ratios(entry, target)
            cells = []
            for key in _SUMMARY_PEERS:
                if key not in peers:
                    cells.append("")
                elif peers[key] is None:
                    cells.append("—")
                elif key == "hand-written":
                    label, ratio = peers[key]
                    cells.append(f"{ratio:.3g} ({label.removeprefix('hand-written ')})")
                else:
                    cells.append(f"{peers[key][1]:.3g}")
            gvi_cell = (
                "—"
                if best is None
                else f"{best['config'].removeprefix('galerkin_vi ')}: {bm.format_time(best)}"
            )
            lines.append(
                f"| {entry.get('title', name)} | {target} | {gvi_cell} | "
                + " | ".join(cells)
                + " |"
            )
    lines.append("")
    return lines


def _chain_cost_lines(rows: Sequence[dict]) -> list[str]:
    """The cost-per-step table of the spring chain against N."""
    if not rows:
        return []
    lines = [
        "## Spring chain: cost per step against N",
        "",
        f"galerkin_vi s = 2 Gauss(2) on the FPU-beta chain (beta = {CHAIN_BETA:g}, velocity "
        f"pulse) at h = {rows[0]['h']:g}, {rows[0]['n_steps']} steps for every N, against the "
        "hand-written 2-stage Gauss (fixed-point iteration, cost linear in N) and "
        "Störmer–Verlet. galerkin_vi's ns/step leave out the fixed cost of its `integrate` "
        "call (column call: a 1-step call). Growth: ns/step over that of the previous N.",
        "",
        "| N | galerkin_vi ns/step | growth | Newton its | banded | call (ms) | hw 2-stage Gauss "
        "(fixed point) ns/step | growth | its | hw Verlet ns/step | galerkin_vi / hw Gauss |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        growth = r.get("growth_from_previous")
        hw_growth = r.get("hw_gauss2_growth_from_previous")
        lines.append(
            f"| {r['n_masses']} | {r['gvi_ns_per_step']:.0f} | "
            f"{'' if growth is None else f'{growth:.2f}×'} | {r['gvi_newton_iterations']:.2f} | "
            f"{r['gvi_banded']} | {r.get('gvi_call_ms', float('nan')):.2f} | "
            f"{r['hw_gauss2_fixed_point_ns_per_step']:.0f} | "
            f"{'' if hw_growth is None else f'{hw_growth:.2f}×'} | "
            f"{r['hw_gauss2_fixed_point_iterations']:.2f} | {r['hw_verlet_ns_per_step']:.0f} | "
            f"{r['gvi_ns_per_step'] / r['hw_gauss2_fixed_point_ns_per_step']:.2f} |"
        )
    growth = chain_growth(rows)
    if growth is not None:
        lines += ["", f"Growth N = 100 → 1000: **{growth:.1f}×** (issue 3 target: ≤ 15×)."]
    lines.append("")
    return lines


def markdown(results: dict) -> str:
    """The results as Markdown tables."""
    meta = results["meta"]
    m = meta["machine"]
    lines = [
        "# galerkin_vi benchmark" + (" (quick)" if meta["quick"] else ""),
        "",
        f"{meta['date']}; {m['cpu']} ({m['cpus']} cores, shared); Python {m['python']}, "
        f"numpy {m['numpy']}, scipy {m['scipy']}, numba {m['numba']}; "
        f"load average {meta['load_average_start']} → {meta.get('load_average_end')}; "
        f"total {meta.get('elapsed_seconds', 0):.0f} s.",
        "",
        f"Times: {meta['timer']}. Error: {meta['error']}. Energy error: {meta['energy_error']}.",
        "",
    ]
    lines += _summary_lines(results)
    if results["per_step"]:
        lines += [
            "## Per step: galerkin_vi / hand-written kernel of the same method",
            "",
            "Same h, same Newton tolerance (1e-14, then until the increment stops decreasing), "
            "same initial guess (previous step's polynomial extrapolated); "
            "`save_every = n_steps`.",
            "",
            "| problem | method | h | steps | galerkin_vi ns/step | hand-written ns/step | "
            "ratio | Newton its gvi / hw | hw simplified Newton ns/step | "
            "hw fixed point ns/step |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in results["per_step"]:
            simp = r["hw_simplified_ns_per_step"]
            fixed = r.get("hw_fixed_point_ns_per_step")
            lines.append(
                f"| {r['problem']} | {r['pair']} | {r['h']:.4g} | {r['n_steps']} | "
                f"{r['gvi_ns_per_step']:.1f} | {r['hw_ns_per_step']:.1f} | "
                f"**{r['ratio']:.2f}** | {r['gvi_newton_iterations']:.2f} / "
                f"{r['hw_newton_iterations']:.2f} | {'—' if simp is None else f'{simp:.1f}'} | "
                f"{'—' if fixed is None else f'{fixed:.1f}'} |"
            )
        overheads = [r["gvi_call_overhead_us"] for r in results["per_step"]]
        lines += [
            "",
            f"galerkin_vi's fixed cost per `integrate` call (1 step): "
            f"{min(overheads):.0f}–{max(overheads):.0f} µs.",
            "",
        ]
    lines += _chain_cost_lines(results.get("chain_cost", []))
    for name, entry in results["problems"].items():
        targets = list(next(iter(entry["time_to_error"].values())).keys())
        setting = entry.get("setting") or f"T = {entry['t_final']:.6g}"
        lines += [
            f"## {entry.get('title', name)}: time to reach a final relative error (seconds)",
            "",
            f"{setting}; reference: {entry['reference']}.",
        ]
        if entry["reference_checks"]:
            checks = ", ".join(f"{k} = {v:.1e}" for k, v in entry["reference_checks"].items())
            lines.append(f"Reference cross-checks: {checks}.")
        lines += [
            "",
            "| curve | " + " | ".join(targets) + " |",
            "|---|" + "---|" * len(targets),
        ]
        for label, tte in entry["time_to_error"].items():
            lines.append(
                f"| {label} | " + " | ".join(bm.format_time(tte[t]) for t in targets) + " |"
            )
        lines += [
            "",
            "Best galerkin_vi configuration and peer time / best galerkin_vi time "
            "(> 1: galerkin_vi is faster; — : the peer or galerkin_vi did not reach the target "
            "within its sweep):",
            "",
            "| | " + " | ".join(targets) + " |",
            "|---|" + "---|" * len(targets),
        ]
        best = entry["best_galerkin_vi"]
        lines.append(
            "| best galerkin_vi | "
            + " | ".join(
                "—" if best[t] is None else f"{best[t]['config']}: {bm.format_time(best[t])} s"
                for t in targets
            )
            + " |"
        )
        peers = list(next(iter(entry["ratio_peer_over_best"].values())).keys())
        for peer in peers:
            lines.append(
                f"| {peer} | "
                + " | ".join(_fmt_ratio(entry["ratio_peer_over_best"][t][peer]) for t in targets)
                + " |"
            )
        lines.append("")
    lines += ["## All points", ""]
    for name, entry in results["problems"].items():
        lines += [f"### {name}", "", *bm.points_lines(entry["curves"]), ""]
    return "\n".join(lines)


_STYLES = {
    "galerkin_vi": "-",
    "hand-written": "--",
    "scipy": ":",
    "numbalsoda": ":",
    "REBOUND": "-.",
}


def _plots(results: dict, folder: str) -> list[str] | None:
    """PNG plots per problem; None when matplotlib cannot be imported."""
    written: list[str] = []
    for name, entry in results["problems"].items():
        title = entry.get("title", name)
        paths = bm.plot(entry, folder, name, title=title, styles=_STYLES)
        if paths is None:
            return None
        written += paths
    return written


def write_outputs(results: dict, folder: str, log: Callable[[str], None] = print) -> list[str]:
    """Write results.json, results.md and (if matplotlib is importable) PNG plots."""
    os.makedirs(folder, exist_ok=True)
    written = []
    path = os.path.join(folder, "results.json")
    with open(path, "w") as fh:
        json.dump(bm.jsonable(results), fh, indent=1)
    written.append(path)
    path = os.path.join(folder, "results.md")
    with open(path, "w") as fh:
        fh.write(markdown(results) + "\n")
    written.append(path)
    pngs = _plots(results, folder)
    if pngs is None:
        log("matplotlib is not installed: PNG plots skipped (pip install matplotlib to get them)")
    else:
        written += pngs
    return written
