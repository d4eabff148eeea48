"""``afo-mj compare``: orthosis architectures side by side on one gait (short real walks)."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import types
from pathlib import Path

import pytest

from afo_mj import cli
from afo_mj.analysis import device_comparison as dc

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


def _main(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cli.main(argv)
    return rc, out.getvalue(), err.getvalue()


def _f(x: str) -> float:
    return float(x) if x != "" else math.nan


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("compare")
    hoses = _hoses_copy(tmp)
    out = tmp / "cmp"
    rc, stdout, stderr = _main(["compare", str(HAFO), str(hoses), "--out", str(out),
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
    assert [r["label"] for r in rows][0] == "gait_assist_hafo"
    assert sorted(r["label"] for r in rows[1:]) == ["gait_assist_hafo_hoses:long_hose",
                                                    "gait_assist_hafo_hoses:short_hose"]
    cols = set(rows[0])
    for c in ("scenario", "variant", "preset", "torque_tracking_rmse_nm",
              "device_positive_work_j_per_stride", "electrical_j_per_stride",
              "hydraulic_j_per_stride", "mechanical_j_per_stride", "efficiency_total",
              "efficiency_electrical_to_hydraulic", "efficiency_hydraulic_to_mechanical",
              "loss_line_j_per_stride", "loss_motor_copper_j_per_stride", "peak_pressure_mpa",
              "fluid_temperature_rise_k", "mass_total_kg", "mass_at_ankle_kg",
              "battery_runtime_h", "human_ankle_positive_work_j_per_stride", "speed_m_s",
              "energy_balance_error_rel", "efficiency_rank_in_scenario"):
        assert c in cols, c
    for r in rows:
        assert r["preset"] == "hafo_gait" and r["fell"] == "false"
        assert 0.2 < _f(r["efficiency_total"]) < 1.0
        assert _f(r["mass_total_kg"]) > _f(r["mass_at_ankle_kg"]) > 0
        assert _f(r["human_ankle_positive_work_no_device_j_per_stride"]) > 0
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
        losses = sum(_f(v) for k, v in r.items() if k.startswith("loss_") and v != "")
        mech_net, stored = _f(r["mechanical_net_j_per_stride"]), _f(r["stored_j_per_stride"])
        elec_net = _f(r["electrical_net_j_per_stride"])
        elec = _f(r["electrical_j_per_stride"])
        assert losses + mech_net + stored == pytest.approx(elec_net, rel=0.02), r["label"]
        assert (losses + mech_net + stored + _f(r["electrical_regenerated_j_per_stride"])
                == pytest.approx(elec, rel=0.02)), r["label"]
        assert abs(_f(r["energy_balance_error_rel"])) < 0.02
        # efficiency chain: each stage passes on less than it takes
        assert 0 < _f(r["efficiency_electrical_to_hydraulic"]) < 1
        assert 0 < _f(r["efficiency_hydraulic_to_mechanical"]) < 1
        assert _f(r["efficiency_hydraulic_to_mechanical"]) == pytest.approx(
            mech_net / _f(r["hydraulic_j_per_stride"]))


def test_longer_hose_loses_more_in_the_line(compared):
    _, rows, _, _ = compared
    by = {r["label"]: r for r in rows}
    short = by["gait_assist_hafo_hoses:short_hose"]
    long_ = by["gait_assist_hafo_hoses:long_hose"]
    # laminar line loss ∝ length: 5x the hose, clearly more loss (flows differ somewhat)
    assert _f(long_["loss_line_j_per_stride"]) > 1.5 * _f(short["loss_line_j_per_stride"])
    assert (_f(long_["efficiency_hydraulic_to_mechanical"])
            < _f(short["efficiency_hydraulic_to_mechanical"]))


def test_rows_ordered_by_efficiency_within_scenario(compared):
    _, rows, _, hoses = compared
    groups: dict[str, list] = {}
    for r in rows:
        groups.setdefault(r["scenario_file"], []).append(r)
    assert list(groups) == [str(HAFO), str(hoses)]          # scenarios keep the given order
    for grp in groups.values():
        eff = [_f(r["efficiency_total"]) for r in grp]
        assert eff == sorted(eff, reverse=True)
        assert [int(r["efficiency_rank_in_scenario"]) for r in grp] == list(range(1, len(grp) + 1))


@pytest.mark.parametrize("scenario, needle", [
    ("walk_healthy.toml", "no [device]"),
    ("bench_hafo.toml", "bench scenario"),
])
def test_not_a_device_walk_is_rejected(tmp_path, scenario, needle):
    out = tmp_path / "cmp"
    rc, _, err = _main(["compare", str(HAFO), str(SCEN / scenario), "--out", str(out),
                        "--strides", "3"])
    assert rc == 2
    assert scenario in err and needle in err and "allowed" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_invalid_options_are_rejected(tmp_path):
    out = tmp_path / "cmp"
    rc, _, err = _main(["compare", str(HAFO), str(HAFO), "--out", str(out)])
    assert rc == 2 and "row label = 'gait_assist_hafo'" in err and "allowed" in err
    rc, _, err = _main(["compare", str(HAFO), "--out", str(out), "--strides", "0"])
    assert rc == 2 and "--strides = 0" in err and "allowed" in err
    rc, _, err = _main(["compare", str(HAFO), "--out", str(out), "--set",
                        "device.params.hose.length_m=-1"])
    assert rc == 2 and "length_m = -1" in err and "allowed" in err
    assert not out.exists()


def test_failing_run_writes_nothing(tmp_path, monkeypatch):
    from afo_mj.gait.walk import WalkNumericsError
    from afo_mj.scenarios import device_scenario

    def boom(*a, **k):
        raise WalkNumericsError("synthetic numerics failure")

    monkeypatch.setattr(device_scenario, "run_device_scenario", boom)
    out = tmp_path / "cmp"
    rc, _, err = _main(["compare", str(HAFO), "--out", str(out), "--strides", "3"])
    assert rc == 1 and "synthetic numerics failure" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def _block(losses: dict, elec=10.0, mech=4.0):
    """A synthetic condition block with the given named losses (J per stride)."""
    return {"device": {"torque_tracking_rmse_nm": 1.0, "mass_total_kg": 2.0},
            "energy": {"run_duration_s": 10.0, "electrical_regenerated_j": 0.0,
                       "mechanical_out_j": 10 * mech, "stored_change_j": {"x": 0.0},
                       "balance_error_rel": 0.0},
            "energy_per_stride": {"stride_time_s": 1.0, "electrical_in_j": elec,
                                  "hydraulic_j": 6.0, "mechanical_positive_out_j": mech,
                                  "losses_j": losses},
            "human": {"ankle_positive_work_j_per_stride": 5.0}, "ankle": {}, "gait": None}


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
