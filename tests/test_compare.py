"""``afo-mj compare``: orthosis architectures side by side on one gait (short real walks)."""

from __future__ import annotations

import csv
import json
import math
import types
from pathlib import Path

import pytest

from afo_mj.experiments import device_comparison as dc
from cli_helpers import csv_number, run_cli

SCEN = Path(__file__).resolve().parents[1] / "scenarios"
HAFO = SCEN / "gait_assist_hafo.toml"

VARIANTS = '''
[device.variants.short_hose]
"hose.length_m" = 0.5

[device.variants.long_hose]
"hose.length_m" = 2.5
'''


def _hoses_copy(tmp: Path) -> Path:
    text = HAFO.read_text(encoding="utf-8").replace('name = "gait_assist_hafo"',
                                                    'name = "gait_assist_hafo_hoses"')
    p = tmp / "gait_assist_hafo_hoses.toml"
    p.write_text(text + VARIANTS, encoding="utf-8")
    return p




@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("compare")
    hoses = _hoses_copy(tmp)
    out = tmp / "cmp"
    rc, stdout, stderr = run_cli(["compare", str(HAFO), str(hoses), "--out", str(out),
                                "--strides", "5"])
    assert rc == 0, stderr
    with (out / "comparison.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return out, rows, stdout, hoses


def test_files_rows_and_columns(compared):
    out, rows, stdout, hoses = compared
    for name in ("comparison.csv", "comparison.json", "comparison.png", "comparison.md"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert not [p for p in out.parent.iterdir() if ".tmp-" in p.name]
    assert sorted(r["label"] for r in rows) == ["gait_assist_hafo",
                                                "gait_assist_hafo_hoses:long_hose",
                                                "gait_assist_hafo_hoses:short_hose"]
    cols = set(rows[0])
    for c in ("scenario", "variant", "preset", "torque_tracking_rmse_nm",
              "device_positive_work_j_per_stride", "electrical_j_per_stride",
              "hydraulic_j_per_stride", "mechanical_j_per_stride", "efficiency_total",
              "efficiency_electrical_to_hydraulic", "efficiency_hydraulic_to_mechanical",
              "loss_line_j_per_stride", "loss_motor_copper_j_per_stride", "peak_pressure_mpa",
              "fluid_temperature_rise_k", "mass_total_kg", "mass_at_ankle_kg",
              "battery_runtime_h", "human_ankle_positive_work_j_per_stride", "speed_m_s",
              "energy_balance_error_rel", "efficiency_rank", "efficiency_rank_in_scenario",
              "mechanical_role", "not_comparable_reason"):
        assert c in cols, c
    for r in rows:
        assert r["preset"] == "hafo_gait" and r["fell"] == "false"
        assert 0.2 < csv_number(r["efficiency_total"]) < 1.0
        assert csv_number(r["mass_total_kg"]) > csv_number(r["mass_at_ankle_kg"]) > 0
        assert csv_number(r["human_ankle_positive_work_no_device_j_per_stride"]) > 0
    # the human reference is one no-device walk shared by all three rows (same walker/gait)
    assert len({r["human_ankle_positive_work_no_device_j_per_stride"] for r in rows}) == 1

    doc = json.loads((out / "comparison.json").read_text(encoding="utf-8"),
                     parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    assert [r["label"] for r in doc["rows"]] == [r["label"] for r in rows]
    assert doc["columns"] == list(rows[0])
    assert [s["name"] for s in doc["scenarios"]] == ["gait_assist_hafo", "gait_assist_hafo_hoses"]
    assert doc["scenarios"][1]["variants"] == ["short_hose", "long_hose"]
    assert doc["scenarios"][0]["strides"] == 5 and doc["scenarios"][0]["analyse_strides"] == [2, 5]
    assert doc["run_info"]["wall_time_s"] > 0
    md = (out / "comparison.md").read_text(encoding="utf-8")
    assert "gait_assist_hafo_hoses:long_hose" in md and "| line |" in md
    for unit in ("[J/stride]", "[N*m]", "[MPa]", "[kg]", "[%]"):
        assert unit in stdout, unit
    assert "gait_assist_hafo_hoses:short_hose" in stdout and str(out) in stdout


def test_per_stride_ledger_closes(compared):
    _, rows, _, _ = compared
    for r in rows:
        losses = sum(csv_number(v) for k, v in r.items() if k.startswith("loss_") and v != "")
        mech_net = csv_number(r["mechanical_net_j_per_stride"])
        stored = csv_number(r["stored_j_per_stride"])
        elec_net = csv_number(r["electrical_net_j_per_stride"])
        elec = csv_number(r["electrical_j_per_stride"])
        assert losses + mech_net + stored == pytest.approx(elec_net, rel=0.02), r["label"]
        assert (losses + mech_net + stored + csv_number(r["electrical_regenerated_j_per_stride"])
                == pytest.approx(elec, rel=0.02)), r["label"]
        assert abs(csv_number(r["energy_balance_error_rel"])) < 0.02
        # efficiency chain: each stage passes on less than it takes
        assert 0 < csv_number(r["efficiency_electrical_to_hydraulic"]) < 1
        assert 0 < csv_number(r["efficiency_hydraulic_to_mechanical"]) < 1
        assert csv_number(r["efficiency_hydraulic_to_mechanical"]) == pytest.approx(
            mech_net / csv_number(r["hydraulic_j_per_stride"]))


def test_longer_hose_loses_more_in_the_line(compared):
    _, rows, _, _ = compared
    by = {r["label"]: r for r in rows}
    short = by["gait_assist_hafo_hoses:short_hose"]
    long_ = by["gait_assist_hafo_hoses:long_hose"]
    # laminar line loss ∝ length: 5x the hose, clearly more loss (flows differ somewhat)
    assert (csv_number(long_["loss_line_j_per_stride"])
            > 1.5 * csv_number(short["loss_line_j_per_stride"]))
    assert (csv_number(long_["efficiency_hydraulic_to_mechanical"])
            < csv_number(short["efficiency_hydraulic_to_mechanical"]))


def test_rows_ranked_together_over_all_scenarios(compared):
    _, rows, stdout, hoses = compared
    eff = [csv_number(r["efficiency_total"]) for r in rows]
    assert all(math.isfinite(e) for e in eff)          # all three are actuators
    assert eff == sorted(eff, reverse=True)            # one ranking, best first
    assert [int(r["efficiency_rank"]) for r in rows] == [1, 2, 3]
    for file in (str(HAFO), str(hoses)):               # the per-scenario rank is labelled so
        grp = [r for r in rows if r["scenario_file"] == file]
        assert [int(r["efficiency_rank_in_scenario"]) for r in grp] == list(
            range(1, len(grp) + 1))
    assert "rank (all rows)" in stdout and "rank in scenario" in stdout
    assert all(r["mechanical_role"] == "actuator" and r["not_comparable_reason"] == ""
               for r in rows)


@pytest.mark.parametrize("scenario, needle", [
    ("walk_healthy.toml", "no [device]"),
    ("bench_hafo.toml", "bench scenario"),
])
def test_not_a_device_walk_is_rejected(tmp_path, scenario, needle):
    out = tmp_path / "cmp"
    rc, _, err = run_cli(["compare", str(HAFO), str(SCEN / scenario), "--out", str(out),
                        "--strides", "3"])
    assert rc == 2
    assert scenario in err and needle in err and "allowed" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_invalid_options_are_rejected(tmp_path):
    out = tmp_path / "cmp"
    rc, _, err = run_cli(["compare", str(HAFO), str(HAFO), "--out", str(out)])
    assert rc == 2 and "row label = 'gait_assist_hafo'" in err and "allowed" in err
    rc, _, err = run_cli(["compare", str(HAFO), "--out", str(out), "--strides", "0"])
    assert rc == 2 and "--strides = 0" in err and "allowed" in err
    rc, _, err = run_cli(["compare", str(HAFO), "--out", str(out), "--set",
                        "device.params.hose.length_m=-1"])
    assert rc == 2 and "length_m = -1" in err and "allowed" in err
    assert not out.exists()


def test_failing_run_writes_nothing(tmp_path, monkeypatch):
    from afo_mj.gait.walk import WalkNumericsError
    from afo_mj.experiments import device_walk

    def boom(*a, **k):
        raise WalkNumericsError("synthetic numerics failure")

    monkeypatch.setattr(device_walk, "run_device_scenario", boom)
    out = tmp_path / "cmp"
    rc, _, err = run_cli(["compare", str(HAFO), "--out", str(out), "--strides", "3"])
    assert rc == 1 and "synthetic numerics failure" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def _block(losses: dict, elec=10.0, mech=4.0, mech_net=None, regen=0.0, runtime_h=None):
    """A synthetic condition block with the given named losses (J per stride); the run is 10
    strides of 1 s, so whole-run figures are 10 × the per-stride ones."""
    mech_net = mech if mech_net is None else mech_net
    return {"device": {"torque_tracking_rmse_nm": 1.0, "mass_total_kg": 2.0,
                       "battery_runtime_h": runtime_h},
            "energy": {"run_duration_s": 10.0, "electrical_regenerated_j": 10 * regen,
                       "mechanical_out_j": 10 * mech_net, "stored_change_j": {"x": 0.0},
                       "balance_error_rel": 0.0},
            "energy_per_stride": {"stride_time_s": 1.0, "electrical_in_j": elec,
                                  "hydraulic_j": 6.0, "mechanical_positive_out_j": mech,
                                  "losses_j": losses},
            "human": {"ankle_positive_work_j_per_stride": 5.0}, "ankle": {}, "gait": None}


def _item(scenario: str, variant: str = "", preset: str = "hafo_gait"):
    return dc.CompareItem(0, f"{scenario}.toml", types.SimpleNamespace(name=scenario), None,
                          types.SimpleNamespace(preset=preset, sides=("right",)), variant)


def test_losses_are_the_union_of_whatever_the_devices_name():
    sc = types.SimpleNamespace(name="s")
    items = [dc.CompareItem(0, "s.toml", sc, None,
                            types.SimpleNamespace(preset=p, sides=("right",)), v)
             for p, v in (("pump", "a"), ("valve", "b"))]
    rows = [dc.comparison_row(items[0], _block({"line": 1.0, "motor_copper": 5.0}, mech=4.0)),
            dc.comparison_row(items[1], _block({"servo_valve_throttling": 3.0, "unloading": 1.0,
                                                "relief": 0.5, "line": 0.5}, mech=5.0))]
    cols = dc.all_columns(rows)
    rows = dc.order_rows(rows)
    assert [c for c in cols if c.startswith("loss_")] == [
        "loss_line_j_per_stride", "loss_motor_copper_j_per_stride",
        "loss_servo_valve_throttling_j_per_stride", "loss_unloading_j_per_stride",
        "loss_relief_j_per_stride"]
    assert [r["label"] for r in rows] == ["s:b", "s:a"]          # 50 % before 40 %
    assert [r["efficiency_rank_in_scenario"] for r in rows] == [1, 2]
    assert "loss_motor_copper_j_per_stride" not in rows[0]       # missing, not zero
    assert rows[0]["efficiency_total"] == pytest.approx(0.5)
    assert rows[0]["efficiency_hydraulic_to_mechanical"] == pytest.approx(5 / 6)  # net/net


def test_one_ranking_over_all_rows_not_one_per_scenario():
    """Issue 19 item 11: rows of different scenarios are ranked together (one rank 1)."""
    rows = [dc.comparison_row(_item("s1", "a"), _block({"x": 6.0}, elec=10.0, mech=4.0)),
            dc.comparison_row(_item("s1", "b"), _block({"x": 7.0}, elec=10.0, mech=3.0)),
            dc.comparison_row(_item("s2"), _block({"x": 5.0}, elec=10.0, mech=5.0))]
    rows = dc.order_rows(rows)
    assert [r["label"] for r in rows] == ["s2", "s1:a", "s1:b"]
    assert [r["efficiency_rank"] for r in rows] == [1, 2, 3]
    assert [r["efficiency_rank_in_scenario"] for r in rows] == [1, 1, 2]
    assert [r["efficiency_rank"] for r in rows].count(1) == 1


def test_a_brake_gets_no_efficiency_no_battery_runtime_and_a_stated_reason():
    """Issue 19 item 11: the prototype HAFO, back-driven past its no-load speed, measured
    (compare --strides 3): 3.77 J/stride drawn, 1.79 J/stride positive mechanical output,
    -63.5 J/stride net (37.5 J/stride regenerated), 21.7 h battery. On positive output it read
    47.5 % efficient; it is a brake: no efficiency, no battery runtime, no rank, a reason."""
    from afo_mj.outputs import comparison_report as cr

    brake = dc.comparison_row(_item("proto", preset="hafo"),
                              _block({"relief": 4.0, "line": 6.0, "motor_copper": 6.3},
                                     elec=3.77, mech=1.79, mech_net=-63.5, regen=37.5,
                                     runtime_h=21.7))
    assist = dc.comparison_row(_item("gait"), _block({"line": 2.0}, elec=21.2, mech=12.3,
                                                     mech_net=9.9, runtime_h=3.8))
    rows = dc.order_rows([brake, assist])
    assert [r["label"] for r in rows] == ["gait", "proto"]
    b, a = rows[1], rows[0]
    assert b["mechanical_role"] == "brake"
    assert math.isnan(b["efficiency_total"]) and math.isnan(b["battery_runtime_h"])
    assert b["efficiency_rank"] is None and b["efficiency_rank_in_scenario"] is None
    assert "brake" in b["not_comparable_reason"] and "-63.50 J/stride" in b["not_comparable_reason"]
    # the actuator: efficiency on net work delivered, its battery runtime kept, rank 1
    assert a["mechanical_role"] == "actuator" and a["not_comparable_reason"] == ""
    assert a["efficiency_total"] == pytest.approx(9.9 / 21.2)
    assert a["battery_runtime_h"] == pytest.approx(3.8) and a["efficiency_rank"] == 1
    # printed tables and comparison.md carry the caveat; the csv cells are empty
    comp = dc.Comparison(rows, dc.all_columns(rows), [{"file": "proto.toml"},
                                                      {"file": "gait.toml"}])
    text = cr.format_tables(comp)
    md = cr._markdown_report(comp)
    for doc in (text, md):
        assert "NOT COMPARABLE: proto: brake" in doc and "47.5" not in doc
        assert "21.70" not in doc and "net mechanical work delivered" in doc
    assert cr._csv_value(b["efficiency_total"]) == "" == cr._csv_value(b["battery_runtime_h"])


@pytest.mark.parametrize("net, pos, role", [
    (9.9, 12.3, "actuator"), (-63.5, 1.79, "brake"), (0.4, 0.5, "near_zero"),
    (3.0, 10.0, "near_zero"), (float("nan"), 1.0, "")])
def test_mechanical_role(net, pos, role):
    got, reason = dc.mechanical_role(net, pos)
    assert got == role and (reason == "") == (role == "actuator")


def _user_circuit_scenario(tmp: Path) -> Path:
    """A walking scenario wearing a user's own [circuit] table: the calibration lab rig's
    datasheet description (scenarios/calibration/lab_rig.toml) under the pump_torque law,
    on the walker and assistance of gait_lab_bench.toml."""
    root = Path(__file__).resolve().parents[1] / "scenarios"
    walk = (root / "gait_lab_bench.toml").read_text(encoding="utf-8")
    walk = walk[:walk.index("[circuit]")] + walk[walk.index("[assistance]"):]
    walk = walk.replace('name = "gait_lab_bench"', 'name = "gait_user_rig"')
    rig = (root / "calibration" / "lab_rig.toml").read_text(encoding="utf-8")
    circuit = rig[rig.index("[circuit]"):rig.index("[load]")].replace(
        'controller = { kind = "open_loop" }',
        'controller = { kind = "pump_torque", motor = "motor", pump = "pump", '
        'actuator = "cylinder" }')
    p = tmp / "gait_user_rig.toml"
    p.write_text(walk + "\n" + circuit, encoding="utf-8")
    return p


def test_compare_takes_a_library_circuit_and_a_users_description(tmp_path):
    """Issue 40: compare runs on gait_lab_bench.toml's circuit and on a user's TOML
    description side by side; each row names its circuit and its per-stride ledger closes
    (electrical net = losses + mechanical net + stored, the energy balance)."""
    from afo_mj.app.compare import compare
    lab = Path(__file__).resolve().parents[1] / "scenarios" / "gait_lab_bench.toml"
    user = _user_circuit_scenario(tmp_path)
    res = compare([str(lab), str(user)], tmp_path / "c",
                  overrides=["gait.analyse_strides=[2, 4]"], strides=4)
    with (tmp_path / "c" / "comparison.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [r["label"] for r in rows] == ["gait_lab_bench", "gait_user_rig"], rows
    assert res is not None
    for r in rows:
        losses = sum(csv_number(v) for k, v in r.items() if k.startswith("loss_") and v != "")
        assert losses + csv_number(r["mechanical_net_j_per_stride"]) + csv_number(
            r["stored_j_per_stride"]) == pytest.approx(
                csv_number(r["electrical_net_j_per_stride"]), rel=0.02), r["label"]
