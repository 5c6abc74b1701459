"""The ``galerkin-vi`` command line and the order-verification report behind it."""

from __future__ import annotations

import json
import textwrap

import pytest

from galerkin_vi.tools import cli, report


def test_verify_prints_the_order_table_and_passes(capsys):
    status = cli.main(["verify", "--problems", "harmonic_oscillator", "--degrees", "1", "2"])
    out = capsys.readouterr().out
    assert status == 0
    for column in ("predicted", "measured", "max energy err", "max momentum drift", "verdict"):
        assert column in out
    assert out.count("pass") == 4  # 2 degrees x 2 families
    assert "0 of 4 studies fail" in out


def test_verify_exit_status_is_nonzero_when_an_order_misses(capsys, monkeypatch):
    monkeypatch.setattr(report, "ORDER_TOLERANCE", -1.0)  # nothing can pass
    status = cli.main(["verify", "--problems", "pendulum", "--degrees", "1", "--families", "gauss"])
    assert status == 1
    assert "FAIL" in capsys.readouterr().out


def test_verify_rejects_unknown_problem():
    with pytest.raises(SystemExit):
        cli.main(["verify", "--problems", "no_such_problem"])


def test_verify_writes_json_and_convergence_plots(tmp_path, capsys):
    out_dir = tmp_path / "out"
    status = cli.main(
        [
            "verify",
            "--problems",
            "kepler",
            "--degrees",
            "1",
            "--families",
            "gauss",
            "--output",
            str(out_dir),
        ]
    )
    assert status == 0
    data = json.loads((out_dir / "verify.json").read_text())
    (row,) = data["rows"]
    assert row["problem"] == "kepler" and row["predicted"] == 2
    assert abs(row["measured"] - 2.0) <= report.ORDER_TOLERANCE
    # the rotation's momentum map is conserved to round-off (discrete Noether)
    assert row["max_momentum_drift"] <= 1e-12
    assert len(row["errors"]) == len(row["step_sizes"]) == len(row["fitted"])
    png = (out_dir / "kepler_convergence.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"wrote {out_dir / 'kepler_convergence.png'}" in capsys.readouterr().out


def test_verify_runs_a_users_problem(tmp_path, monkeypatch, capsys):
    (tmp_path / "my_models.py").write_text(
        textwrap.dedent(
            """
            import numpy as np
            import sympy as sp
            import galerkin_vi as gvi
            from galerkin_vi.problems import Problem

            q, v = sp.symbols("q v")
            SYSTEM = gvi.LagrangianSystem(v**2 / 2 - q**4 / 4, [q], [v])

            def quartic():
                return Problem("quartic", SYSTEM, np.array([1.0]), np.array([0.0]), 2.0)
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    status = cli.main(["verify", "--problems", "--problem", "my_models:quartic", "--degrees", "2"])
    out = capsys.readouterr().out
    assert status == 0
    assert out.count("quartic") == 2 and out.count("pass") == 2


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("no_colon", "module:attribute"),
        ("no_such_module_xyz:thing", "cannot import"),
        ("galerkin_vi.problems:no_such_thing", "no attribute"),
        ("galerkin_vi:__version__", "must be a galerkin_vi.problems.Problem"),
    ],
)
def test_verify_reports_a_bad_user_problem(spec, message, capsys):
    assert cli.main(["verify", "--problems", "--problem", spec]) == 2
    assert message in capsys.readouterr().err


def test_a_bare_system_is_rejected_with_a_hint(tmp_path, monkeypatch):
    (tmp_path / "bare_models.py").write_text(
        "import sympy as sp\nimport galerkin_vi as gvi\nq, v = sp.symbols('q v')\n"
        "SYSTEM = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v])\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ValueError, match="without initial data"):
        report.load_problem("bare_models:SYSTEM")


def test_bench_runs_a_users_problem(tmp_path, monkeypatch, capsys):
    (tmp_path / "bench_models.py").write_text(
        textwrap.dedent(
            """
            import numpy as np
            import sympy as sp
            import galerkin_vi as gvi
            from galerkin_vi.problems import Problem

            q, v = sp.symbols("q v")
            SYSTEM = gvi.LagrangianSystem(v**2 / 2 - q**4 / 4, [q], [v])

            def quartic():
                return Problem("quartic", SYSTEM, np.array([1.0]), np.array([0.0]), 2.0)
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    out_dir = tmp_path / "out"
    argv = ["bench", "--problem", "bench_models:quartic", "--degrees", "1", "2"]
    argv += ["--families", "gauss", "--time-cap", "0.005", "--repeats", "1"]
    status = cli.main([*argv, "--output", str(out_dir)])
    out = capsys.readouterr().out
    assert status == 0
    assert "# galerkin_vi work-precision: quartic" in out
    assert "galerkin_vi s=1 Gauss(1)" in out and "galerkin_vi s=2 Gauss(2)" in out
    data = json.loads((out_dir / "work_precision.json").read_text())
    assert set(data["quartic"]["curves"]) == {
        "galerkin_vi s=1 Gauss(1)",
        "galerkin_vi s=2 Gauss(2)",
    }
    assert (out_dir / "quartic_precision.png").read_bytes()[:4] == b"\x89PNG"


def test_bench_needs_a_model(capsys):
    assert cli.main(["bench"]) == 2
    assert "--problem MODULE:ATTR" in capsys.readouterr().err
    assert cli.main(["bench", "--problem", "no_such_module_xyz:thing"]) == 2
    assert "cannot import" in capsys.readouterr().err


def test_warmup_compiles_or_loads_every_loop_and_says_where(capsys):
    from galerkin_vi.loops import loop_cache_dir
    from galerkin_vi.loops.readiness import MARKER
    from galerkin_vi.tools.warmup import _runs

    assert cli.main(["warmup"]) == 0
    out = capsys.readouterr().out
    assert str(loop_cache_dir()) in out
    # one line per variant (loaded from the cache here: the session compiled them)
    assert sum(label in out for label, *_ in _runs()) == len(_runs())
    assert "done in" in out
    assert (loop_cache_dir() / MARKER).exists()


def test_verify_with_nothing_selected_is_an_error_not_a_pass(capsys):
    # a CI gate that ran no study must fail (it used to print "0 of 0 studies" and exit 0)
    assert cli.main(["verify", "--problems"]) == 2
    assert "no problem selected" in capsys.readouterr().err
    # a constrained problem runs Lobatto only: Gauss alone selects no study
    argv = ["verify", "--problems", "cartesian_pendulum", "--families", "gauss"]
    assert cli.main(argv) == 2
    assert "no study for the selected families" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ["verify", "--degrees", "0"],
        ["verify", "--degrees", "-1"],
        ["verify", "--degrees", "two"],
        ["verify", "--step-counts", "0"],
        ["bench", "--problem", "m:a", "--degrees", "0"],
        ["bench", "--problem", "m:a", "--repeats", "0"],
    ],
)
def test_bad_counts_are_usage_errors(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "must be at least 1" in err or "is not an integer" in err


def test_the_study_count_in_the_ci_how_to_is_the_tools():
    # docs/howto/verify-orders-in-ci.md states how many studies the default run has
    from pathlib import Path

    page = Path(__file__).resolve().parents[1] / "docs" / "howto" / "verify-orders-in-ci.md"
    args = cli.build_parser().parse_args(["verify"])
    count = cli.study_count(cli._selected(args), args.degrees, args.families)
    assert f"only): {count} studies" in page.read_text()


def test_verify_studies_the_splittings_in_mpmath_where_their_order_shows(capsys):
    # Blanes-Moan's order 4 looks like order 3.4 on Kepler in float64 (its h^4 term is
    # small by design); at the mpmath step counts of its order it measures 4
    status = cli.main(
        ["verify", "--problems", "kepler", "--degrees", "1", "--families", "lobatto",
         "--compositions", "4", "6"]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert status == 0, out
    assert out.count("blanes_moan") == 2 and "0 of 3 studies fail" in out
    kepler = report.PROBLEMS["kepler"]
    rows = report.verify(
        [("kepler", kepler.factory(), kepler.mp_step_counts)], [1], ["lobatto"],
        compositions=(4,),
    )  # fmt: skip
    splitting = rows[-1]
    assert splitting.precision.startswith("mpmath")
    assert splitting.step_counts == list(report.MP_SPLITTING_COUNTS[4])
    assert abs(splitting.measured - 4) < 0.1
