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
    # the stiffness protocol needs a torque controller: the open-loop lab drive has none
    rc = main(["run", str(SCEN / "stiffness_bench.toml"), "--out", str(tmp_path / "y"),
               "--set", 'device.preset="lab_bench"'])
    assert rc == 2
    err = capsys.readouterr().err
    assert "'stiffness' cannot run on device 'lab_bench'" in err
    assert "torque controller" in err and "'open_loop'" in err
    assert not (tmp_path / "y").exists()


def test_old_bench_kinds_still_parse_to_their_protocols():
    """The deprecated ``bench.kind`` forms read as the rig and protocols they stood for,
    each with a note; the shipped files give the rig and protocols themselves."""
    from afo_mj.scenarios.bench_scenario import load_bench_scenario, parse_bench_scenario
    b = load_bench_scenario(SCEN / "bench_hafo.toml")
    assert (b.rig, b.stiffness, b.notes) == ("stand", None, ())
    assert b.protocols == ("torque_velocity", "isometric_steps", "frequency_response",
                           "position_step")
    old = {"hafo": ('[device]\npreset = "hafo"\n[bench]\nkind = "hafo"\n'
                    'tests = ["isometric_steps"]\n', "stand", ("isometric_steps",)),
           "stiffness": ('[device]\npreset = "phafo"\n[bench]\nkind = "stiffness"\n',
                         "stand", ("stiffness",)),
           "circuit": ('[circuit]\nlibrary = "lab_bench"\n[bench]\nkind = "circuit"\n',
                       "load", ("torque_velocity", "frequency_response"))}
    for kind, (text, rig, protocols) in old.items():
        b = parse_bench_scenario(text, origin="f.toml")
        assert (b.rig, b.protocols) == (rig, protocols), kind
        assert any(f"bench.kind = {kind!r} is deprecated" in n for n in b.notes), b.notes
    new = parse_bench_scenario(SCEN.joinpath("stiffness_bench.toml").read_text(),
                               origin="f.toml")
    kinded = parse_bench_scenario(SCEN.joinpath("stiffness_bench.toml").read_text().replace(
        'rig = "stand"\nprotocols = ["stiffness"]', 'kind = "stiffness"'), origin="f.toml")
    assert kinded.stiffness == new.stiffness and kinded.notes and not new.notes


# -- a child with foot drop walking with the emulator ---------------------------------------------
#: Walkable emulated stiffnesses [N·m/deg]. At 4.6 N·m/deg about neutral the spring's push-off
#: torque equals this child's whole plantarflexor strength and the walker falls (reported as a
#: condition without an analysable stride; see scenarios/gait_stiffness_emulation.toml).
WALKED_NM_PER_DEG = (1.0, 2.5)


@pytest.fixture(scope="module")
def gait(tmp_path_factory):
    out = tmp_path_factory.mktemp("gait_stiffness") / "run"
    s = _run(out, "gait_stiffness_emulation.toml")
    return s["device_conditions"]


def _normal_mid_swing_ankle_deg() -> float:
    """Winter's normal ankle angle averaged over mid-swing (10–90 % of swing, toe off at 61 %
    of the cycle, Winter's normal stance): the independent target of an orthosis for foot
    drop (≈ −5.6°)."""
    import numpy as np

    from afo_mj.gait.reference import load_normative
    ref = load_normative("winter", "normal")
    toe_off = 0.61
    ph = np.linspace(toe_off + 0.1 * (1 - toe_off), toe_off + 0.9 * (1 - toe_off), 401)
    return float(np.degrees(np.mean(ref.angles_rad(ph)[:, 2])))


@pytest.mark.slow
def test_gait_conditions_ran(gait):
    assert list(gait) == ["no_device", "assist_k4.6", "assist_k2.5", "assist_k1"]
    assert gait["no_device"]["gait"] is not None and not gait["no_device"]["gait"]["fell"]
    for k in WALKED_NM_PER_DEG:
        g = gait[f"assist_k{k:g}"]["gait"]
        assert g is not None and not g["fell"] and g["n_cycles_used"] >= 10


@pytest.mark.slow
@pytest.mark.parametrize("k_nm_per_deg", WALKED_NM_PER_DEG)
def test_emulator_lifts_the_dropped_foot_in_swing(gait, k_nm_per_deg):
    base = gait["no_device"]["gait"]
    g = gait[f"assist_k{k_nm_per_deg:g}"]["gait"]
    normal = _normal_mid_swing_ankle_deg()
    a0 = base["swing_mean_ankle_angle_deg"]["mean"]
    a1 = g["swing_mean_ankle_angle_deg"]["mean"]
    # the foot-drop baseline: without an orthosis the foot hangs > 10° below normal in swing
    assert a0 < normal - 10.0
    # Measured (0.4 cc/rev PHAFO pump): -21.5° without, -4.8° at 1 and -4.4° at 2.5 N·m/deg,
    # +16.7° / +17.1° (cycle-to-cycle SD <= 0.03°). At least 10° less plantarflexed is the
    # size of the deficit a foot-drop AFO is prescribed for (the baseline lies 16° below
    # normal), with 6° of margin on the measured gain; and the emulator must bring the swing
    # ankle back to within 5° of Winter's normal mid-swing angle.
    assert a1 - a0 >= 10.0
    assert abs(a1 - normal) <= 5.0
    # Minimum toe clearance in mid-swing: 3.0 mm without, 3.6 / 3.9 mm with (SD <= 0.07 mm).
    # The gain is small because the walker's toe-clearance reflex (swing_clearance_m = 10 mm)
    # already holds a dropped forefoot a few mm off the floor by keeping the knee flexed
    # longer in swing; with the emulator the knee extends on time at the same few mm. So the
    # asserted minimum is half the smallest measured gain, +0.3 mm (> 4 SD above zero), not
    # the +5 mm one might expect of a walker without that reflex.
    c0 = base["min_toe_clearance_m"]["mean"]
    c1 = g["min_toe_clearance_m"]["mean"]
    assert c1 - c0 >= 0.3e-3


@pytest.mark.slow
@pytest.mark.parametrize("k_nm_per_deg", WALKED_NM_PER_DEG)
def test_gait_energy_balance_and_per_stride_figures(gait, k_nm_per_deg):
    v = gait[f"assist_k{k_nm_per_deg:g}"]
    assert abs(v["energy"]["balance_error_rel"]) < 0.005
    assert v["energy_per_stride"]["electrical_in_j"] > 0
    assert v["ankle"]["push_off_peak_power_w"] > 0
    # a spring emulation: the device's peak torque is at most K × the largest ankle excursion
    # from neutral in this gait (Winter's peak plantarflexion 19.8°, + 5° for the walker's
    # own deviation and the torque loop's overshoot) and within the PHAFO's 62 N·m
    assert v["device"]["peak_torque_nm"] <= min(k_nm_per_deg * 25.0, PHAFO_MAX_TORQUE_NM)
