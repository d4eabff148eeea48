"""tools/readme_tables.py: the README's measured tables, generated (issue 19 item 7).

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


def test_every_block_has_its_markers_once_in_the_readme(rt):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    for name, block in rt.BLOCKS.items():
        assert block.file == "README.md"
        begin, end = rt.markers(name)
        assert text.count(begin) == 1 and text.count(end) == 1, name
        i, j = rt.block_span(text, name)
        assert "Generated by `python tools/readme_tables.py --only " + name in text[i:j]


def _fake_results(rt, speed=1.0612):
    res = {"scenarios": {n: _walk(speed_m_s=speed) for n in rt.SCENARIO_ROWS},
           "plantarflexor_weakness": {1.0: _walk(speed_m_s=speed), 0.5: _walk()},
           "schwartz_bands": {"free": {"knee_angle_rad": 0.74}},
           "stiffness_bench": {"stiffness": {"1": _stiff(1.0)}},
           "phafo_power": {"stiffness": {"1": _stiff(1.0)}},
           "foot_drop": {"no_device": _walk()},
           "hafo_gait": {"healthy": {"no_device": _walk()}},
           "hafo_bench": {"hafo": {"bench": {"stall_torque_nm": 65.44}}},
           "comparison": {"rows": [_cmp_row("gait_assist_hafo", 0.4712, 1)]}}
    assert set(res) == set(rt.BLOCKS)
    return res


def test_check_is_0_on_an_unchanged_readme_and_1_on_a_changed_one(rt, tmp_path, monkeypatch,
                                                                   capsys):
    shutil.copy(ROOT / "README.md", tmp_path / "README.md")
    res = _fake_results(rt)
    monkeypatch.setattr(rt, "collect", lambda name: res[name])
    assert rt.main(["--root", str(tmp_path)]) == 0                  # write the fake blocks
    written = (tmp_path / "README.md").read_text(encoding="utf-8")
    assert rt.main(["--root", str(tmp_path), "--check"]) == 0
    # another day, same numbers: unchanged (the date is not compared, and is kept)
    monkeypatch.setattr(rt, "render", lambda n, r, d, _f=rt.render: _f(n, r, "2099-01-01"))
    assert rt.main(["--root", str(tmp_path), "--check"]) == 0
    assert rt.main(["--root", str(tmp_path)]) == 0
    assert (tmp_path / "README.md").read_text(encoding="utf-8") == written
    capsys.readouterr()
    # a changed number: --check says which block, exits 1, writes nothing
    res = _fake_results(rt, speed=0.95)
    monkeypatch.setattr(rt, "collect", lambda name: res[name])
    assert rt.main(["--root", str(tmp_path), "--check"]) == 1
    out = capsys.readouterr().out
    assert "scenarios: would change" in out and "plantarflexor_weakness: would change" in out
    assert "stiffness_bench" not in out
    assert (tmp_path / "README.md").read_text(encoding="utf-8") == written
    assert rt.main(["--root", str(tmp_path), "--check", "--only", "stiffness_bench"]) == 0


def test_missing_markers_fail_before_any_run(rt, tmp_path, monkeypatch):
    (tmp_path / "README.md").write_text("no markers\n", encoding="utf-8")
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
