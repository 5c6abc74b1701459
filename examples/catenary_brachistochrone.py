"""Two classics of the calculus of variations as boundary-value problems in which x is "time".

- The **catenary**: the curve y(x) through (-1, cosh 1) and (1, cosh 1) at
  which J[y] = int y sqrt(1 + y'^2) dx is stationary (a hanging chain's
  potential energy for its length) is y = cosh x, with J = 1 + sinh(2)/2 and
  length 2 sinh 1.
- The **brachistochrone**: a bead sliding from rest without friction takes
  the time T[y] = int sqrt((1 + y'^2) / (2 g y)) dx (y measured down from
  where it starts at rest); T is stationary on the cycloid
  x = a (th - sin th), y = a (1 - cos th), on which the arc between the
  parameters th1 and th2 takes sqrt(a/g) (th2 - th1).

Each is a Lagrangian L(x, y, y') with x declared as the time symbol,
solved by ``gvi.solve_bvp`` from a straight line; the script prints the
largest nodal error and the error of the functional against N, with the
slopes (the method's order 6 at degree 3, reached once h resolves the
brachistochrone's curvature), and ``--plot PATH`` draws both curves.

Run::

    python examples/catenary_brachistochrone.py [--plot docs/_static/catenary_brachistochrone.png]
"""

from __future__ import annotations

import argparse

import numpy as np
import sympy as sp

import galerkin_vi as gvi

G, A, TH1, TH2 = 9.81, 1.0, 1.0, 4.0


def catenary():
    x, y, vy = sp.symbols("x y vy")
    system = gvi.LagrangianSystem(y * sp.sqrt(1 + vy**2), [y], [vy], t=x)
    c1 = np.cosh(1.0)

    def solve(N):
        return gvi.solve_bvp(system, gvi.Galerkin(3), [c1], [c1], (-1.0, 1.0), N)

    def exact(x_):
        return np.cosh(x_)

    return solve, exact, 1 + np.sinh(2.0) / 2, sp.sqrt(1 + vy**2)


def cycloid_height(x_: np.ndarray) -> np.ndarray:
    """y on the cycloid at abscissae x_ (Newton on x(th) = x_)."""
    th = np.full_like(x_, 2.0)
    for _ in range(60):
        th -= (A * (th - np.sin(th)) - x_) / (A * (1 - np.cos(th)))
    return A * (1 - np.cos(th))


def brachistochrone():
    x, y, vy = sp.symbols("x y vy")
    system = gvi.LagrangianSystem(sp.sqrt((1 + vy**2) / (2 * G * y)), [y], [vy], t=x)
    ends = (A * (TH1 - np.sin(TH1)), A * (TH2 - np.sin(TH2)))

    def solve(N):
        return gvi.solve_bvp(system, gvi.Galerkin(3), [A * (1 - np.cos(TH1))],
                             [A * (1 - np.cos(TH2))], ends, N)  # fmt: skip

    return solve, cycloid_height, np.sqrt(A / G) * (TH2 - TH1), None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", help="write the figure here (needs matplotlib)")
    args = parser.parse_args()
    results = {}
    for name, (solve, exact, functional, length), ladder in (
        ("catenary", catenary(), (4, 8, 16, 32)),
        ("brachistochrone", brachistochrone(), (32, 64, 128, 256)),
    ):
        print(f"\n{name}, Galerkin(3)")
        print(f"{'N':>5s} {'nodes':>10s} {'functional':>11s} {'its':>4s}")
        errors = []
        for N in ladder:
            res = solve(N)
            nodes = np.abs(res.trajectory.q[:, 0] - exact(res.trajectory.t)).max()
            errors.append(nodes)
            print(f"{N:5d} {nodes:10.2e} {res.action - functional:11.2e} {res.iterations:4d}")
        slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
        print(f"nodal slopes {np.array2string(slopes, precision=2)} (order 6)")
        if length is not None:
            print(f"length {res.path_integral(length):.15f} (2 sinh 1 = {2 * np.sinh(1.0):.15f})")
        results[name] = (res, exact)
    if args.plot:
        _plot(results, args.plot)


def _plot(results, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(8, 3.4))
    for ax, (name, (res, exact)) in zip(axes, results.items(), strict=True):
        t = res.trajectory.t
        x = np.linspace(t[0], t[-1], 300)
        ax.plot(x, res.trajectory.sol(x)[:, 0], lw=1.5, label="solve_bvp")
        ax.plot(x, exact(x), "k--", lw=0.8, label="closed form")
        ax.plot([t[0], t[-1]], res.trajectory.q[[0, -1], 0], "o", color="C3", label="ends")
        ax.set_title(name)
        ax.set_xlabel("x")
        if name == "brachistochrone":
            ax.invert_yaxis()  # y measured down
        ax.legend(fontsize=8)
    axes[0].set_ylabel("y")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
