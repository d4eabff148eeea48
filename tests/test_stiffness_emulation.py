"""Stiffness emulation (PHAFO): the clinical stiffness rig and a child with foot drop walking.

Both scenarios run once per module through ``afo-mj run`` (as a user runs them) and their
``summary.json`` is read back. The references are independent of the code under test: the
issue's acceptance figure (emulated stiffness within 10 % of the commanded 1, 2.5 and
4.6 N·m/deg), the ideal spring's torque at the imposed amplitude (K × 12°), the published
PHAFO limits (62 N·m, 14.1 MPa rail), the 0.5 % energy-balance limit, and, for walking, the
same child walking without an orthosis.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from afo_mj.cli import main

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "scenarios"
COMMANDED_NM_PER_DEG = (1.0, 2.5, 4.6)        # the stiffnesses
AMPLITUDE_DEG = 12.0                           # scenarios/stiffness_bench.toml
PHAFO_MAX_TORQUE_NM = 62.0                     # published (facts.md)
PHAFO_RAIL_PA = 14.1e6                         # published (facts.md)


def _run(out: Path, scenario: str, *extra: str) -> dict:
    rc = main(["run", str(SCEN / scenario), "--out", str(out), *extra])
    assert rc == 0
    return json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("stiffness_bench") / "run"
    return out, _run(out, "stiffness_bench.toml")


# -- the stiffness rig ---------------------------------------------------------------------------
@pytest.mark.parametrize("k_nm_per_deg", COMMANDED_NM_PER_DEG)
def test_bench_emulated_stiffness_within_10_percent(bench, k_nm_per_deg):
    _, s = bench
    v = s["stiffness"][f"k{k_nm_per_deg:g}"]
    assert v["commanded_nm_per_deg"] == pytest.approx(k_nm_per_deg, rel=1e-12)
    assert v["emulated_nm_per_deg"] == pytest.approx(k_nm_per_deg, rel=0.10)
    assert v["emulated_nm_per_rad"] == pytest.approx(k_nm_per_deg * 180.0 / math.pi, rel=0.10)
    assert v["cycles_analysed"] >= 1
    assert s["acceptance"]["passed"] is True


@pytest.mark.parametrize("k_nm_per_deg", COMMANDED_NM_PER_DEG)
def test_bench_peak_torque_is_the_springs_and_within_device_limits(bench, k_nm_per_deg):
    _, s = bench
    v = s["stiffness"][f"k{k_nm_per_deg:g}"]
    # an ideal spring at the imposed amplitude: K × A
    assert v["peak_torque_nm"] == pytest.approx(k_nm_per_deg * AMPLITUDE_DEG, rel=0.10)
    assert v["peak_torque_nm"] <= PHAFO_MAX_TORQUE_NM
    # the load pressure makes the torque: |τ| = A_e r Δp with the PHAFO's 32 mm pulley and
    # the HAFO's cylinders, A_e r = 5.24e-6 m³ (valve_afo docstring), within seal friction
    assert v["peak_load_pressure_pa"] * 5.24e-6 == pytest.approx(v["peak_torque_nm"], rel=0.05)
    # the rail is held at its 14.1 MPa set point, not beyond the relief
    assert v["peak_supply_pressure_pa"] == pytest.approx(PHAFO_RAIL_PA, rel=0.03)
    assert v["electrical_in_j"] > 0
    assert abs(v["energy_balance_error_rel"]) < 0.005


def test_bench_energy_and_figure(bench):
    out, s = bench
    assert abs(s["energy"]["balance_error_rel"]) < 0.005
    assert (out / "stiffness_loops.png").stat().st_size > 10_000


def test_stiffness_bench_errors_name_key_value_allowed(tmp_path, capsys):
    # 4.6 N·m/deg × 15° = 69 N·m: beyond the PHAFO's 62 N·m
    rc = main(["run", str(SCEN / "stiffness_bench.toml"), "--out", str(tmp_path / "x"),
               "--set", "bench.amplitude_deg=15"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "bench.amplitude_deg" in err and "15" in err and "62" in err and "allowed" in err
    assert not (tmp_path / "x").exists()
    rc = main(["run", str(SCEN / "stiffness_bench.toml"), "--out", str(tmp_path / "y"),
               "--set", 'device.preset="hafo"'])
    assert rc == 2
    err = capsys.readouterr().err
    assert "device.preset" in err and "hafo" in err and "phafo" in err
    assert not (tmp_path / "y").exists()


def test_hafo_bench_still_parses_as_the_default_kind():
    from afo_mj.scenarios.bench_scenario import load_bench_scenario
    b = load_bench_scenario(SCEN / "bench_hafo.toml")
    assert b.bench_kind == "hafo" and b.stiffness is None
    assert b.tests == ("torque_velocity", "isometric_steps", "frequency_response",
                       "position_step")
