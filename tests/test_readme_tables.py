"""tools/readme_tables.py: the measured tables of README.md and docs/*.md, generated.

Fast: no walk is run; the formatting functions get hand-made result dicts and the runner is
monkeypatched."""

from __future__ import annotations

import importlib.util
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def rt():
    spec = importlib.util.spec_from_file_location("readme_tables",
                                                  ROOT / "tools" / "readme_tables.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["readme_tables"] = mod
    spec.loader.exec_module(mod)
    return mod


def _walk(**kw):
    r = {"hip_angle_rms_error_deg": 2.345, "knee_angle_rms_error_deg": 2.81,
         "ankle_angle_rms_error_deg": 2.66, "peak_ankle_plantarflexor_moment_nm_per_kg": 1.494,
         "peak_ankle_power_w_per_kg": 3.306, "ankle_push_off_positive_work_j_per_kg": 0.2904,
         "push_off_peak_plantarflexion_deg": 9.84, "min_toe_clearance_m": 0.0241,
         "speed_m_s": 1.0612, "residual_force_rms_percent_body_weight": 2.71,
         "swing_mean_ankle_angle_deg": -4.83, "fell": False, "fall_time_s": None,
         "completed_strides": 10, "body_mass_kg": 75.0, "height_m": 1.75,
         "plantarflexor_strength_fraction": 1.0, "dorsiflexor_strength_fraction": 1.0}
    r.update(kw)
    return r


def _rows(md: str) -> list[list[str]]:
    return [[c.strip() for c in ln.strip("|").split("|")] for ln in md.splitlines()
            if ln.startswith("|")][2:]


def test_num_rounds_scales_and_marks_missing(rt):
    assert rt.num(0.2904, ".3f") == "0.290"
    assert rt.num(0.0241, ".1f", 100.0) == "2.4"          # m → cm
    assert rt.num({"mean": 1.494, "sd": 0.1}) == "1.49"  # a mean ± SD entry: its mean
    assert rt.num(-0.14, ".1f") == "−0.1"                # real minus sign
    assert rt.num(-0.04, ".1f") == "0.0"                 # no "−0.0"
    for missing in (None, float("nan"), {"mean": None}, "x"):
        assert rt.num(missing) == rt.MISSING == "–"


def test_scenario_table_units_rounding_and_missing(rt):
    res = {"walk_healthy": _walk(),
           "walk_weak_plantarflexors": _walk(plantarflexor_strength_fraction=0.5,
                                             min_toe_clearance_m=None),
           "walk_child_healthy": _walk(body_mass_kg=25.0, height_m=1.2),
           "walk_spastic_ankle": _walk(fell=True, fall_time_s=4.023, completed_strides=3)}
    rows = {r[0]: r for r in _rows(rt.format_scenarios(res))}
    h = rows["`walk_healthy`"]
    assert h[1:] == ["2.3 / 2.8 / 2.7", "1.49", "3.31", "0.290", "9.8", "2.4", "1.06", "2.7"]
    weak = rows["`walk_weak_plantarflexors` (50 %)"]
    assert weak[6] == "–"                                 # missing toe clearance
    child = rows["`walk_child_healthy` (25 kg, 1.2 m)"]
    assert child[2] == "1.49 (healthy × 1.2/1.75 = 1.02)"
    assert rows["`walk_spastic_ankle`"][1] == "falls in stride 4 (t = 4.02 s)"
    assert rows["`walk_foot_drop`"][1:] == ["–"] * 8      # not run: every cell missing
    assert rows["Winter normal (reference)"][2:5] == ["1.69", "3.24", "0.345"]


def test_weakness_table_orders_strengths_and_shows_the_fall(rt):
    res = {0.5: _walk(push_off_peak_plantarflexion_deg=4.96, speed_m_s=0.8234),
           1.0: _walk(), 0.35: _walk(fell=True, fall_time_s=6.08, completed_strides=4)}
    rows = _rows(rt.format_plantarflexor_weakness(res))
    assert [r[0] for r in rows] == ["100 % (`walk_healthy`)",
                                    "50 % (`walk_weak_plantarflexors`)", "35 %"]
    assert rows[1][1:4] == ["0.290", "5.0", "0.82"]
    assert rows[2][1] == "falls in stride 5 (t = 6.08 s)"


def test_weakness_and_scenario_tables_agree_where_they_overlap(rt, monkeypatch):
    """Both blocks read the same runs (one memo keyed by scenario and overrides)."""
    calls = []

    def fake_memo(key, fn):
        calls.append(key)
        return _walk(speed_m_s=0.5 + 0.01 * len(key))
    monkeypatch.setattr(rt, "_memo", fake_memo)
    main = {r[0].split(" ")[0]: r for r in _rows(rt.format_scenarios(rt.collect_scenarios()))}
    graded = {r[0]: r for r in _rows(rt.format_plantarflexor_weakness(
        rt.collect_plantarflexor_weakness()))}
    assert graded["100 % (`walk_healthy`)"][3] == main["`walk_healthy`"][7]
    assert graded["50 % (`walk_weak_plantarflexors`)"][3] == main["`walk_weak_plantarflexors`"][7]
    assert "walk:scenarios/walk_healthy.toml" in calls


def test_ideal_assist_table_orders_peaks_and_labels_conditions(rt):
    res = {"assist": {"walk_healthy": {40.0: _walk(ankle_push_off_positive_work_j_per_kg=0.1381),
                                       0.0: _walk()},
                      "walk_weak_plantarflexors": {0.0: _walk(speed_m_s=0.8234),
                                                   20.0: _walk(fell=True, fall_time_s=5.5,
                                                               completed_strides=4)}},
           "worn": {"0.97 kg at the right ankle": _walk(knee_angle_rms_error_deg=4.81)}}
    rows = _rows(rt.format_ideal_assist(res))
    assert [r[0] for r in rows] == ["healthy, no device", "healthy, ideal assist 40 N·m",
                                    "weak (50 %), no device", "weak (50 %), ideal assist 20 N·m",
                                    "healthy, carrying 0.97 kg at the right ankle"]
    assert rows[1][1:] == ["0.138", "9.8", "1.06", "2.3 / 2.8 / 2.7"]
    assert rows[2][3] == "0.82"
    assert rows[3][1] == "falls in stride 5 (t = 5.50 s)"
    assert rows[4][4] == "2.3 / 4.8 / 2.7"


def test_push_off_assist_is_a_half_sine_over_35_to_62_percent_of_stance(rt):
    import numpy as np
    dev = rt.PushOffAssist(40.0)
    stance = np.array([True, False])
    peak = dev.torque_nm(0.0, 0, 0, np.array([0.485, 0.485]), stance)
    assert peak[0] == pytest.approx(-40.0) and peak[1] == 0.0       # swing leg: nothing
    assert dev.torque_nm(0.0, 0, 0, np.array([0.35 + 0.27 / 6, 0.5]), stance)[0] \
        == pytest.approx(-20.0)                                      # sin(pi/6) = 1/2
    assert dev.torque_nm(0.0, 0, 0, np.array([0.30, 0.5]), stance)[0] == 0.0


def test_schwartz_table(rt):
    res = {"`walk_schwartz_free` vs Free": {"knee_angle_rad": 0.744, "ankle_angle_rad": 0.79,
                                            "thigh_angle_rad": 0.94, "hip_angle_rad": 0.08},
           "`walk_schwartz_fast` vs Fast": None}
    rows = _rows(rt.format_schwartz_bands(res))
    assert rows[0] == ["knee", "0.74", "–"]
    assert [r[0] for r in rows] == ["knee", "ankle", "thigh from vertical", "hip"]


def _stiff(k, p_w=118.38):
    return {"commanded_nm_per_deg": k, "emulated_nm_per_deg": k * 1.0002,
            "hysteresis_energy_j": 0.2936, "peak_torque_nm": 12.249 * k,
            "peak_supply_pressure_pa": 14.189e6, "energy_balance_error_rel": 1.29e-13,
            "electrical_in_j": 1420.58, "mean_electrical_power_w": p_w,
            "losses_j": {"motor_copper": 675.08, "pump_volumetric": 323.21,
                         "servo_valve_throttling": 293.61, "driver": 71.11,
                         "pump_mechanical": 35.17, "battery_internal": 8.35, "relief": 0.18}}


def test_stiffness_bench_table_units(rt):
    rows = _rows(rt.format_stiffness_bench({"stiffness": {"1": _stiff(1.0)}}))
    assert rows == [["1.0", "1.000", "0.29", "12.2", "14.19", "1e-13"]]      # Pa → MPa


def test_phafo_power_table_converts_joules_to_watts(rt):
    rows = _rows(rt.format_phafo_power({"stiffness": {"1": _stiff(1.0)}}))
    # W = J × (mean power / energy drawn) = J / 12.0 s
    assert rows == [["1.0", "118", "56", "27", "24", "6", "3", "1"]]
    missing = _stiff(2.5)
    missing["mean_electrical_power_w"] = None
    assert _rows(rt.format_phafo_power({"stiffness": {"2": missing}}))[0][1:] == ["–"] * 7


def test_foot_drop_table_orders_conditions_and_units(rt):
    res = {"assist_k4.6": _walk(fell=True, fall_time_s=4.02, completed_strides=3),
           "assist_k1": _walk(min_toe_clearance_m=0.00361, push_off_peak_power_w=69.04,
                              electrical_in_j_per_stride=249.2),
           "no_device": _walk(push_off_peak_power_w=71.8, electrical_in_j_per_stride=None)}
    rows = _rows(rt.format_foot_drop(res))
    assert [r[0] for r in rows] == ["no device", "1 N·m/deg", "4.6 N·m/deg"]
    assert rows[0][5] == "–"
    assert rows[1][1:] == ["−4.8", "3.6", "69.0", "1.06", "249"]           # m → mm
    assert rows[2][1] == "falls in stride 4 (t = 4.02 s)"


def _doc_files() -> list[Path]:
    return [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))


def test_every_block_has_its_markers_once_in_its_file_and_nowhere_else(rt):
    texts = {p.relative_to(ROOT).as_posix(): p.read_text(encoding="utf-8")
             for p in _doc_files()}
    for name, block in rt.BLOCKS.items():
        assert block.file in texts, (name, block.file)
        begin, end = rt.markers(name)
        for f, text in texts.items():
            want = 1 if f == block.file else 0
            assert text.count(begin) == want and text.count(end) == want, (name, f)
        text = texts[block.file]
        i, j = rt.block_span(text, name)
        assert "Generated by `python tools/readme_tables.py --only " + name in text[i:j]


def _design_summary(total_kg=2.9199, stall=90.008):
    return {"requirements": {"peak_torque_nm": 90.0},
            "best": {"cylinder_bore_m": 0.0123, "pulley_radius_m": 0.03,
                     "torque_per_pressure_m3": 6.831e-6, "hose_bore_m": 0.0029884,
                     "pump_displacement_m3_rev": 6.64e-8, "peak_pump_speed_rad_s": 1186.3,
                     "oil": "ISO_VG32", "motor_rated_power_w": 46.42,
                     "battery_capacity_ah": 1.522, "system_efficiency": 0.5432,
                     "efficiency": {"pump": 0.7377, "motor": 0.7904, "lines": 0.9383,
                                    "cylinders": 0.9781},
                     "heat_w": 8.935, "surface_temperature_k": 315.806, "total_kg": total_kg,
                     "mass_kg": {"motor": 0.0663, "battery": 0.2048}},
            "predicted_bench": {"stall_torque_nm": 90.0298, "no_load_speed_deg_s": 108.79},
            "simulated_bench": {"stall_torque_nm": stall, "no_load_speed_deg_s": 108.871},
            "bench_agreement": {"stall_torque_rel": -0.000238, "no_load_speed_rel": 0.000746},
            "mass_check": {"design_total_kg": 2.9199, "budget_total_kg": 2.9518,
                           "total_rel_difference": -0.010814, "design_ankle_kg": 0.94373,
                           "budget_ankle_kg": 0.97, "ankle_rel_difference": -0.027077,
                           "items": {"pulley_bearings": {"design_kg": 0.0902, "budget_kg": 0.12,
                                                         "difference_kg": -0.0298},
                                     "hoses": {"design_kg": 0.097, "budget_kg": 0.102,
                                               "difference_kg": -0.005},
                                     "foot_plate": {"design_kg": 0.28, "budget_kg": 0.28,
                                                    "difference_kg": 0.0}}},
            "walk_check": {"gait": "winter/normal", "no_load_speed_deg_s": 108.79,
                           "peak_plantarflexion_velocity_deg_s": 222.09,
                           "back_driven_fraction_of_stride": 0.12,
                           "conditions": {"transparent": {"net_work_j_per_stride": -32.118},
                                          "assist": {"net_work_j_per_stride": -31.114}}},
            "studies": {"pressure": [
                {"operating_pressure_pa": 4.0e6, "total_kg": 3.1443, "system_efficiency": 0.5381,
                 "hydraulic_power_density_w_kg": 116.4, "system_energy_density_wh_kg": 4.873},
                {"operating_pressure_pa": 21.0e6, "total_kg": 2.9054,
                 "system_efficiency": 0.5502, "hydraulic_power_density_w_kg": 140.2,
                 "system_energy_density_wh_kg": 5.268}],
                "oil": [{"oil": "ISO_VG22", "total_kg": 2.9492},
                        {"oil": "ISO_VG46", "total_kg": 2.9054}],
                "power": [{"power_factor": 0.25, "rated_output_power_w": 41.23, "feasible": True,
                           "total_kg": 2.7343, "hydraulic_power_density_w_kg": 36.55},
                          {"power_factor": 3.0, "rated_output_power_w": 494.8, "feasible": False,
                           "binding": ["surface_temperature"]}]},
            "hose_bore_tradeoff": {"hose_bore_m": [0.0015, 0.008],
                                   "optimum_hose_bore_m": 0.0024442,
                                   "feasible_optimum_hose_bore_m": 0.00281,
                                   "interior_optimum": True, "feasible_interior_optimum": True}}


def test_design_hafo_block_against_hand_written_markdown(rt):
    md = rt.format_design_hafo(_design_summary())
    rows = _rows(md)
    assert rows[0] == ["stall torque", "90.03 N·m", "90.01 N·m (−0.02 %)"]
    assert rows[1] == ["no-load speed", "108.8 deg/s", "108.9 deg/s (+0.07 %)"]
    assert rows[2][2] == "2.952 kg, mass budget of the written parameters (−1.1 %)"
    # only parts worn at the ankle explain the ankle's difference, largest first
    assert rows[3] == ["mass at the ankle", "0.944 kg",
                       "0.970 kg (−2.7 %: pulley bearings 0.090 vs 0.120 kg)"]
    assert ("a 0.066 cm³/rev pump (peak speed 1186 rad/s), ISO VG 32, a 46 W class motor "
            "(66 g), a 6S 1.52 Ah pack (0.20 kg); system efficiency 54 % over the stride "
            "(pump 74 %, motor 79 %, lines 94 %, cylinders 98 %), 8.9 W of heat, pack surface "
            "42.7 °C.") in md                                   # K → °C, m³ → cm³, kg → g
    assert "carries the 90 N·m target for 0.4 kg less." in md    # 3.3 − 2.92
    assert ("back-drives the pump for 12 % of the stride; net device work −32.1 J/stride "
            "transparent, −31.1 J/stride assist.") in md


def test_design_guidelines_block_against_hand_written_markdown(rt):
    md = rt.format_design_guidelines(_design_summary())
    assert md.splitlines()[0] == "| operating pressure MPa | 4.0 | 21.0 |"
    assert _rows(md) == [["total mass kg", "3.144", "2.905"],
                         ["system efficiency %", "53.8", "55.0"],
                         ["hydraulic power density W/kg", "116", "140"],
                         ["system energy density Wh/kg", "4.87", "5.27"]]
    assert ("From 4.0 to 21.0 MPa the lightest design goes from 3.144 to 2.905 kg (−8 %) and "
            "its system efficiency from 53.8 to 55.0 %.") in md
    assert "VG 22 2.949 kg, VG 46 2.905 kg." in md
    assert ("(the corner speed × 0.25 … 3): 41 W 2.73 kg (37 W/kg), 495 W infeasible "
            "(surface temperature).") in md
    assert "lowest at 2.44 mm; with each bore's lightest feasible motor, at 2.81 mm " \
           "(both inside 1.5–8 mm)." in md


def test_design_architectures_block_orders_and_merges_pump_losses(rt):
    light = {"pump": {"total_kg": 2.762, "system_efficiency": 0.417,
                      "losses_j_per_stride": {"motor_copper": 4.55, "pump_mechanical": 2.39,
                                              "pump_volumetric": 1.59, "line": 2.06}},
             "digital": {"total_kg": 2.653, "system_efficiency": 0.234,
                         "losses_j_per_stride": {"pump_mechanical": 9.22, "pump_volumetric": 0.5,
                                                 "switching_valves": 5.88}},
             "valve": None}
    sim = {"rows": [_cmp_row("gait_assist_hafo", 0.4977, 1),
                    _cmp_row("gait_assist_valve:pressure_control", 0.152, 2),
                    _cmp_row("gait_assist_digital", 0.118, 3)]}
    md = rt.format_design_architectures({"light": light, "simulated": sim, "hafo": {
        "valve": {"feasible": False, "explanation": "infeasible: too hot"},
        "digital": {"feasible": True, "explanation": None}}})
    rows = _rows(md)
    assert rows[0] == ["pump-controlled", "2.76", "42 %", "motor copper 4.5, pump 4.0, line 2.1"]
    # a constant-speed pump's mechanical loss stands alone (the digital circuit's)
    assert rows[1][3] == "pump mechanical 9.2, switching valves 5.9, pump volumetric 0.5"
    assert rows[2][1:] == ["infeasible", "–", "–"]
    assert "order of system efficiency: pump > digital." in md
    assert "pump 50 %, valve 15 %, digital 12 % (another order: pump > valve > digital)." in md
    assert "At the HAFO requirements: valve: infeasible: too hot." in md


@pytest.mark.parametrize("a, b, same", [
    ("0.290", "0.290", True), ("0.290", "0.291", True),       # a rounding boundary
    ("0.290", "0.292", False), ("−60.5", "−60.3", False), ("25.2", "25.3", True),
    ("171", "170", True), ("171", "169", False), ("−0.1", "0.0", True),
    ("2e-14", "−5e-12", True), ("1.2e-09", "4.8e-10", True),  # round-off: both ≤ 1e-8
    ("1.2e-05", "4.8e-05", False), ("2.2e-05", "2.3e-05", True), ("4e-13", "0.3", False)])
def test_numbers_compare_at_their_printed_precision(rt, a, b, same):
    assert rt.same_number(a, b) is same
    assert rt.same_at_printed_precision(f"| x | {a} |", f"| x | {b} |") is same


def test_words_must_match_exactly(rt):
    assert not rt.same_at_printed_precision("falls in stride 5", "walks 5")
    assert not rt.same_at_printed_precision("| 1.0 |", "| 1.0 | 2 |")
    # names holding digits are words, not numbers
    assert not rt.same_at_printed_precision("ISO_VG32", "ISO_VG33")
    stamp = "<sub>Generated by `python tools/readme_tables.py --only x` on {}; runs y.</sub>"
    assert rt.same_at_printed_precision("| 1.06 |\n" + stamp.format("2026-01-01"),
                                        "| 1.07 |\n" + stamp.format("2026-11-27"))


def _fake_results(rt, speed=1.0612):
    res = {"scenarios": {n: _walk(speed_m_s=speed) for n in rt.SCENARIO_ROWS},
           "plantarflexor_weakness": {1.0: _walk(speed_m_s=speed), 0.5: _walk()},
           "schwartz_bands": {"free": {"knee_angle_rad": 0.74}},
           "stiffness_bench": {"stiffness": {"1": _stiff(1.0)}},
           "phafo_power": {"stiffness": {"1": _stiff(1.0)}},
           "foot_drop": {"no_device": _walk()},
           "hafo_gait": {"healthy": {"no_device": _walk()}},
           "hafo_bench": {"hafo": {"bench": {"stall_torque_nm": 65.44}}},
           "comparison": {"rows": [_cmp_row("gait_assist_hafo", 0.4712, 1)]},
           "design_hafo": _design_summary(),
           "design_guidelines": _design_summary(),
           "design_architectures": {"light": {}, "hafo": {}, "simulated": {"rows": []}},
           "ideal_assist": {"assist": {"walk_healthy": {0.0: _walk(), 20.0: _walk()}},
                            "worn": {"x": _walk()}}}
    assert set(res) == set(rt.BLOCKS)
    return res


def _copy_docs(rt, root: Path) -> None:
    for f in {b.file for b in rt.BLOCKS.values()}:
        (root / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / f, root / f)


def _read_docs(rt, root: Path) -> dict:
    return {f: (root / f).read_text(encoding="utf-8") for f in {b.file for b in rt.BLOCKS.values()}}


def test_check_is_0_on_unchanged_docs_and_1_on_changed_ones(rt, tmp_path, monkeypatch, capsys):
    _copy_docs(rt, tmp_path)
    res = _fake_results(rt)
    monkeypatch.setattr(rt, "collect", lambda name: res[name])
    assert rt.main(["--root", str(tmp_path)]) == 0                  # write the fake blocks
    written = _read_docs(rt, tmp_path)
    assert rt.main(["--root", str(tmp_path), "--check"]) == 0
    # another day, same numbers: unchanged (the date is not compared, and is kept)
    monkeypatch.setattr(rt, "render", lambda n, r, d, _f=rt.render: _f(n, r, "2099-01-01"))
    assert rt.main(["--root", str(tmp_path), "--check"]) == 0
    assert rt.main(["--root", str(tmp_path)]) == 0
    assert _read_docs(rt, tmp_path) == written
    capsys.readouterr()
    # another machine's rounding (1.0612 m/s prints 1.06, 1.0651 prints 1.07: one unit of the
    # last printed digit): --check passes
    res = _fake_results(rt, speed=1.0651)
    monkeypatch.setattr(rt, "collect", lambda name: res[name])
    assert rt.main(["--root", str(tmp_path), "--check"]) == 0
    assert _read_docs(rt, tmp_path) == written
    # a changed number: --check says which block and which lines, exits 1, writes nothing
    res = _fake_results(rt, speed=0.95)
    monkeypatch.setattr(rt, "collect", lambda name: res[name])
    assert rt.main(["--root", str(tmp_path), "--check"]) == 1
    out = capsys.readouterr().out
    assert "scenarios: would change" in out and "plantarflexor_weakness: would change" in out
    assert "| 1.06 |" in out and "| 0.95 |" in out                  # the lines that differ
    assert "stiffness_bench" not in out.split("regenerate:")[0]
    assert "--only scenarios --only plantarflexor_weakness" in out
    assert _read_docs(rt, tmp_path) == written
    assert rt.main(["--root", str(tmp_path), "--check", "--only", "stiffness_bench"]) == 0
    # a design block lives in docs/design_tool.md and is checked there
    res["design_hafo"] = _design_summary(stall=91.48)
    assert rt.main(["--root", str(tmp_path), "--check", "--only", "design_hafo"]) == 1
    assert "design_hafo: would change (docs/design_tool.md)" in capsys.readouterr().out


def test_missing_markers_fail_before_any_run(rt, tmp_path, monkeypatch):
    path = tmp_path / rt.BLOCKS["foot_drop"].file
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("no markers\n", encoding="utf-8")
    monkeypatch.setattr(rt, "collect", lambda name: pytest.fail("ran a block"))
    with pytest.raises(ValueError, match="exactly once"):
        rt.main(["--root", str(tmp_path), "--only", "foot_drop"])


def test_list(rt, capsys):
    assert rt.main(["--list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in rt.BLOCKS)


def test_hafo_gait_table_deficit_regeneration_and_losses(rt):
    dev = dict(device_positive_work_j_per_stride=16.42, device_negative_work_j_per_stride=-2.51,
               electrical_in_j=276.3, electrical_regenerated_j=0.4, balance_error_rel=4.2e-13,
               efficiency_total=0.5912, battery_runtime_h=3.21, peak_pressure_mpa=7.31,
               fluid_temperature_rise_k=0.3, losses_j={"motor_copper": 40.2, "line": 25.1,
                                                      "unloading": 0.0})
    res = {"healthy": {"no_device": _walk(human_ankle_positive_work_j_per_stride=22.4,
                                          push_off_work_j_per_stride=21.7),
                       "assist": _walk(human_ankle_positive_work_j_per_stride=13.4,
                                       push_off_work_j_per_stride=22.7, **dev)},
           "prototype": {"transparent": _walk(push_off_work_j_per_stride=16.6,
                                              **{**dev, "electrical_regenerated_j": 391.6})},
           "weak": {"no_device": _walk(push_off_work_j_per_stride=15.2),
                    "assist": _walk(push_off_work_j_per_stride=20.6, **dev)}}
    md = rt.format_hafo_gait(res)
    rows = {r[0]: r for r in _rows(md.split("\n\n")[0])}
    assert rows["healthy, no device"][3] == rows["healthy, no device"][5] == "–"
    assert rows["healthy, `hafo_gait` assist (Zhang, 40 N·m)"][3:] == [
        "16.4 / −2.5", "22.7", "276 J / 4e-13"]                       # < 1 J regen: not shown
    assert rows["healthy, `hafo` (prototype) transparent"][5] == "276 J (392 J regenerated) / 4e-13"
    assert rows["weak, `hafo_gait` assist"][4] == "20.6 (83 % of the deficit restored)"
    assert rows["healthy, `hafo_gait` transparent"][1:] == ["–"] * 5    # not run
    assert ("total efficiency (positive ankle work / electrical) 0.59. Its losses over the run: "
            "motor copper 40 J, line 25 J. Battery runtime at this gait is 3.2 h; peak pressure "
            "7.3 MPa; oil temperature rise 0.3 K.") in md


def test_hafo_bench_table_units(rt):
    res = {"hafo": {"bench": {"stall_torque_nm": 65.44, "no_load_speed_deg_s": 105.49,
                              "rise_time_s": 0.03492, "overshoot_pct": 13.27,
                              "bandwidth_hz": 2.387, "velocity_bandwidth_hz": 199.26,
                              "position_rise_time_s": 0.18476},
                    "device": {"mass_total_kg": 3.3045, "mass_at_ankle_kg": 0.97},
                    "energy": {"balance_error_rel": 2.2537e-10},
                    "published": {"stall_torque_nm": 65.0, "no_load_speed_deg_s": 105.0}},
           "hafo_gait": {"bench": {"overshoot_pct": 0.004, "rise_time_s": 0.0521}}}
    rows = _rows(rt.format_hafo_bench(res))
    assert rows[0] == ["stall torque", "65.4 N·m (current limit)", "65 N·m", "– N·m"]
    assert rows[3][1] == "34.9 ms, 13.3 %" and rows[3][3] == "52.1 ms, 0 %"   # s → ms
    assert rows[2][1] == "3.30 / 0.97 kg" and rows[7][1] == "2.3e-10"


def _cmp_row(label, eff, rank, **kw):
    r = {"label": label, "fell": False, "fall_time_s": None, "mechanical_role": "actuator",
         "efficiency_total": eff, "electrical_j_per_stride": 25.04,
         "device_positive_work_j_per_stride": 16.42, "torque_tracking_rmse_nm": 3.71,
         "fluid_temperature_rise_k": 0.31, "battery_runtime_h": 3.21,
         "not_comparable_reason": "", "efficiency_rank": rank,
         "loss_names": ["loss_motor_copper_j_per_stride", "loss_pump_mechanical_j_per_stride",
                        "loss_line_j_per_stride", "loss_unloading_j_per_stride"],
         "loss_motor_copper_j_per_stride": 3.61, "loss_pump_mechanical_j_per_stride": 2.72,
         "loss_line_j_per_stride": 2.31, "loss_unloading_j_per_stride": None}
    r.update(kw)
    return r


def test_comparison_table_against_hand_written_markdown(rt):
    """Net efficiency in %, top three losses by name (ties in ledger order, missing losses
    skipped), rank across all rows; a brake gets "–", a numbered note with its reason, no
    battery runtime and no rank; a fall gets its fall text; an unknown label is shown as
    code."""
    rows = [_cmp_row("gait_assist_valve:pressure_control", 0.1804, 1,
                     electrical_j_per_stride=71.3, torque_tracking_rmse_nm=5.64,
                     loss_names=["loss_servo_valve_throttling_j_per_stride",
                                 "loss_motor_copper_j_per_stride", "loss_relief_j_per_stride",
                                 "loss_pump_volumetric_j_per_stride"],
                     loss_servo_valve_throttling_j_per_stride=33.2,
                     loss_motor_copper_j_per_stride=10.04, loss_relief_j_per_stride=4.96,
                     loss_pump_volumetric_j_per_stride=4.96, battery_runtime_h=1.14,
                     fluid_temperature_rise_k=2.04),
            _cmp_row("gait_assist_valve:no_accumulator", 0.0254, 2,
                     electrical_j_per_stride=601.2, battery_runtime_h=0.137),
            _cmp_row("hafo_proto", None, None, mechanical_role="brake",
                     not_comparable_reason="brake: absorbs net work from the ankle "
                     "(net -64.00 J/stride, positive 1.20 J/stride)", battery_runtime_h=None,
                     electrical_j_per_stride=3.84, device_positive_work_j_per_stride=1.2),
            _cmp_row("gait_assist_digital", None, None, fell=True, fall_time_s=4.023,
                     completed_strides=3)]
    expected = """\
| device | net efficiency (net ankle work / electrical) | electrical J/stride | \
delivered +work J/stride | tracking RMSE N·m | largest losses J/stride | oil ΔT K | battery h | \
rank |
|---|---|---|---|---|---|---|---|---|
| valve, pressure control | 18 % | 71 | 16.4 | 5.6 | servo throttling 33, motor copper 10, \
relief 5.0 | 2.0 | 1.1 | 1 |
| valve, no accumulator | 2.5 % | 601 | 16.4 | 3.7 | motor copper 3.6, pump mech. 2.7, \
line 2.3 | 0.3 | 0.14 | 2 |
| `hafo_proto` | – [1] | 4 | 1.2 | 3.7 | motor copper 3.6, pump mech. 2.7, line 2.3 | 0.3 | \
– | – |
| digital (PWM unloading + release) | falls in stride 4 (t = 4.02 s) |  |  |  |  |  |  |  |

[1] `hafo_proto` (brake): brake: absorbs net work from the ankle (net -64.00 J/stride, \
positive 1.20 J/stride)."""
    assert rt.format_comparison({"rows": rows}) == expected
    assert rt.format_comparison({"rows": []}).count("\n") == 1           # header only
