"""The ``galerkin-vi`` command line."""

from __future__ import annotations

import pytest

from galerkin_vi import cli


def test_verify_prints_the_order_table_and_passes(capsys):
    status = cli.main(["verify", "--problems", "harmonic_oscillator", "--degrees", "1", "2"])
    out = capsys.readouterr().out
    assert status == 0
    assert "predicted" in out and "measured" in out
    assert out.count("pass") == 4  # 2 degrees x 2 families
    assert "0 of 4 measured orders miss" in out


def test_verify_exit_status_is_nonzero_when_an_order_misses(capsys, monkeypatch):
    monkeypatch.setattr(cli, "ORDER_TOLERANCE", -1.0)  # nothing can pass
    status = cli.main(["verify", "--problems", "pendulum", "--degrees", "1", "--families", "gauss"])
    assert status == 1
    assert "FAIL" in capsys.readouterr().out


def test_verify_rejects_unknown_problem():
    with pytest.raises(SystemExit):
        cli.main(["verify", "--problems", "no_such_problem"])
