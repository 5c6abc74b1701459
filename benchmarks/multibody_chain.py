"""Cost per step of chains of rigid bodies against their length: band and dense steps.

A chain of N links (quaternion or rotation-matrix bodies on spherical joints, the
first hanging from the ground) released from a bent pose. For each N the same
run twice, in one process: the constrained step in band storage (the default,
chosen from the sparsity; galerkin_vi/run/constrained_band.py) and in dense
storage (the band switched off), with the final states compared and the Newton
iterations per step beside the time per step. The band's cost grows linearly
with N, the dense one's as N^3.

    python benchmarks/multibody_chain.py --links 5 10 20 40 --rotation quaternion
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import galerkin_vi as gvi


def chain(n_links: int, rotation: str) -> tuple[list, gvi.Multibody]:
    links = [
        gvi.RigidBody(f"l{i}", 1.0, [0.1, 0.1, 0.02], rotation=rotation) for i in range(n_links)
    ]
    joints = [gvi.joints.Spherical(None, links[0], point_b=[0, 0, 0.5])]
    joints += [
        gvi.joints.Spherical(links[i], links[i + 1], point_a=[0, 0, -0.5], point_b=[0, 0, 0.5])
        for i in range(n_links - 1)
    ]
    return links, gvi.Multibody(links, joints=joints, gravity=[0, 0, -9.81])


def bent(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def timed(integrator, q0, v0, h: float, n_steps: int, repeats: int):
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        traj = integrator.integrate(q0, v0=v0, h=h, n_steps=n_steps, save_every=n_steps)
        best = min(best, time.perf_counter() - start)
    return best / n_steps, traj


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--links", type=int, nargs="+", default=[5, 10, 20])
    parser.add_argument("--rotation", choices=["quaternion", "matrix"], default="quaternion")
    parser.add_argument("--degree", type=int, default=2)
    parser.add_argument("--h", type=float, default=1e-3)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"# {args.rotation} links, Galerkin({args.degree}), h = {args.h}, {args.steps} steps")
    print("| N | n | m | build s | band µs/step | its/step | dense µs/step | its/step | "
          "dense / band | max |q_band - q_dense| |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n_links in args.links:
        start = time.perf_counter()
        links, mb = chain(n_links, args.rotation)
        q0, v0 = mb.state(rotations={link.name: bent(0.8) for link in links})
        band = gvi.Integrator(mb.system, gvi.Galerkin(args.degree))
        band.integrate(q0, v0=v0, h=args.h, n_steps=2)
        build = time.perf_counter() - start
        dense = gvi.Integrator(mb.system, gvi.Galerkin(args.degree))
        object.__setattr__(dense.run_spec, "band", None)  # the dense step, for comparison
        rows = [timed(x, q0, v0, args.h, args.steps, args.repeats) for x in (band, dense)]
        (tb, trb), (td, trd) = rows
        assert band.run_spec.band is not None, "the chain was not stored banded"
        print(
            f"| {n_links} | {mb.system.n} | {mb.system.m} | {build:.1f} | {tb * 1e6:.0f} | "
            f"{trb.mean_newton_iterations:.2f} | {td * 1e6:.0f} | {trd.mean_newton_iterations:.2f} "
            f"| {td / tb:.1f} | {np.abs(trb.q[-1] - trd.q[-1]).max():.1e} |"
        )


if __name__ == "__main__":
    main()
