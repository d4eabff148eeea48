"""Valve-controlled and digital AFOs against the pump-controlled HAFO on one gait (issue 5).

``afo-mj compare`` runs the HAFO, the valve-controlled AFO's supply variants and the digital
AFO with the same walker and the same 40 N·m Zhang assistance profile. The expectations are
the seed's (ch. 1, 4; facts.md): a valve fed at constant supply pressure throttles the
difference between supply and load pressure, so a valve-controlled circuit spends more
electrical energy than a pump-controlled one for the same delivered work, and the difference
sits in the throttling, unloading and relief losses; supply variants that cut the surplus
flow or the supply pressure do better.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
STRIDES = 6

# issue 5's acceptance: one ``afo-mj compare`` of seven device walks (~8 s warm) and two more
# runs for the determinism check (~16 s); the quick subset (-m "not slow") leaves them out
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    out = tmp_path_factory.mktemp("cmp") / "out"
    cmd = [sys.executable, "-m", "afo_mj.cli", "compare",
           str(ROOT / "scenarios/gait_assist_hafo.toml"),
           str(ROOT / "scenarios/gait_assist_valve.toml"),
           str(ROOT / "scenarios/gait_assist_digital.toml"),
           "--out", str(out), "--strides", str(STRIDES)]
    env = {"MUJOCO_GL": "egl", "PATH": "/usr/bin:/bin"}
    if os.environ.get("AFO_MJ_CACHE_DIR"):     # the suite's compiled circuits, not ~/.cache's
        env["AFO_MJ_CACHE_DIR"] = os.environ["AFO_MJ_CACHE_DIR"]
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env, timeout=600)
    assert res.returncode == 0, res.stderr
    rows = list(csv.DictReader(open(out / "comparison.csv")))
    return {r["label"]: r for r in rows}, out


def _f(row, key):
    v = row.get(key, "")
    return float(v) if v not in ("", None) else 0.0


VALVE_LABELS = ("gait_assist_valve:no_accumulator", "gait_assist_valve:accumulator",
                "gait_assist_valve:unloading", "gait_assist_valve:pressure_control",
                "gait_assist_valve:variable_displacement")
THROTTLING_LOSSES = ("loss_servo_valve_throttling_j_per_stride", "loss_unloading_j_per_stride",
                     "loss_relief_j_per_stride")


def test_every_device_and_variant_is_compared(table):
    rows, out = table
    assert set(VALVE_LABELS) | {"gait_assist_hafo", "gait_assist_digital"} == set(rows)
    for r in rows.values():
        assert r["fell"] in ("False", "false", "0")
        # energy ledger closes (issue: within 0.5 %)
        assert abs(_f(r, "energy_balance_error_rel")) < 0.005
    assert (out / "comparison.png").stat().st_size > 10_000


def test_valve_costs_more_than_pump_for_the_same_assistance(table):
    rows, _ = table
    pump = rows["gait_assist_hafo"]
    w_pump = _f(pump, "device_positive_work_j_per_stride")
    e_pump = _f(pump, "electrical_j_per_stride")
    for label in VALVE_LABELS:
        r = rows[label]
        # the same delivered assistance (device positive work per stride within 20 %) ...
        assert abs(_f(r, "device_positive_work_j_per_stride") - w_pump) < 0.2 * w_pump, label
        # ... for more electrical energy: at least twice the pump-controlled device's
        e = _f(r, "electrical_j_per_stride")
        assert e > 2.0 * e_pump, (label, e, e_pump)
        # and the difference is attributed: throttling in the servo valve, unloading and
        # relief losses carry at least half of it, and the largest single loss is one of them
        named = sum(_f(r, k) for k in THROTTLING_LOSSES)
        assert named > 0.5 * (e - e_pump), (label, named, e - e_pump)
        losses = {k: _f(r, k) for k in r if k.startswith("loss_")}
        assert max(losses, key=losses.get) in THROTTLING_LOSSES, label
    # the pump-controlled circuit has no throttling valve at all
    assert _f(pump, "loss_servo_valve_throttling_j_per_stride") == 0.0


def test_supply_variants_ordered_by_efficiency(table):
    """Docs (README, "Valve-controlled, digital and stiffness-emulating AFOs"): a constant-speed
    pump dumps its surplus over the relief valve at full pressure whether or not an
    accumulator is fitted; unloading or a variable-displacement pump removes the surplus but
    the valve still throttles from a full-pressure rail; a rail that follows the load removes
    most of the throttling; the pump-controlled HAFO has none."""
    rows, _ = table
    eff = {k: _f(rows[k], "efficiency_total") for k in rows}
    relief = min(eff["gait_assist_valve:no_accumulator"], eff["gait_assist_valve:accumulator"])
    relief_max = max(eff["gait_assist_valve:no_accumulator"],
                     eff["gait_assist_valve:accumulator"])
    surplus_removed = (eff["gait_assist_valve:unloading"],
                       eff["gait_assist_valve:variable_displacement"])
    assert min(surplus_removed) > 2.0 * relief_max
    assert eff["gait_assist_valve:pressure_control"] > 1.5 * max(surplus_removed)
    assert eff["gait_assist_hafo"] > 1.5 * eff["gait_assist_valve:pressure_control"]
    assert relief > 0.0
    # the table lists a scenario's variants best first
    ranks = {k: int(rows[k]["efficiency_rank_in_scenario"]) for k in VALVE_LABELS}
    order = sorted(VALVE_LABELS, key=lambda k: ranks[k])
    assert [eff[k] for k in order] == sorted((eff[k] for k in order), reverse=True)


def test_digital_reported_against_proportional_valve(table):
    rows, out = table
    dig, prop = rows["gait_assist_digital"], rows["gait_assist_valve:unloading"]
    for r in (dig, prop):
        assert _f(r, "torque_tracking_rmse_nm") > 0.0
        assert 0.0 < _f(r, "efficiency_total") < 1.0
    # the digital circuit names its own losses: PWM switching valve, release valve, coils
    for k in ("loss_switching_valve_j_per_stride", "loss_release_valve_and_ports_j_per_stride",
              "loss_valve_actuators_j_per_stride"):
        assert _f(dig, k) > 0.0
    assert _f(dig, "loss_servo_valve_throttling_j_per_stride") == 0.0
    data = json.loads((out / "comparison.json").read_text())
    assert len(data["rows"]) == len(rows)


def test_valve_run_is_deterministic(tmp_path):
    outs = []
    for k in range(2):
        out = tmp_path / f"r{k}"
        res = subprocess.run(
            [sys.executable, "-m", "afo_mj.cli", "run",
             str(ROOT / "scenarios/gait_assist_valve.toml"), "--out", str(out),
             "--set", "gait.strides=4", "--set", "gait.analyse_strides=[2,4]",
             "--set", 'device.conditions=["assist"]'],
            capture_output=True, text=True, cwd=ROOT,
            env={"MUJOCO_GL": "egl", "PATH": "/usr/bin:/bin"}, timeout=600)
        assert res.returncode == 0, res.stderr
        outs.append((out / "summary.json").read_text())
    assert outs[0] == outs[1]
    s = json.loads(outs[0])
    assert abs(s["energy"]["balance_error_rel"]) < 0.005
    assert s["device_preset"] == "valve"
