"""Scenarios built from circuit descriptions: the ``[circuit]`` table (walking and bench),
its errors through ``afo-mj run`` (exit 2, nothing written), and the bench-kind checks."""

from __future__ import annotations

from pathlib import Path

import pytest

from afo_mj import cli

SCEN = Path(__file__).resolve().parents[1] / "scenarios"


def _run(argv, capsys):
    rc = cli.main(argv)
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def test_hafo_bench_refuses_a_valve_preset(tmp_path, capsys):
    out = tmp_path / "r"
    rc, _, err = _run(["run", str(SCEN / "bench_hafo.toml"), "--out", str(out),
                       "--set", "device.preset=valve"], capsys)
    assert rc == 2
    assert "device.preset = 'valve'" in err and "valve-controlled" in err
    assert 'bench.kind = "stiffness"' in err
    assert not out.exists()
