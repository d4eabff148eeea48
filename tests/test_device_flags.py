"""Issue 38 items 3 and 4: end-stop impacts, brakes and poor tracking are reported as what
they are, and a fall is a result for every walk (plain or with a device, in ``run`` and in a
sweep's rows).

References: the end-stop contact figures against hand-summed synthetic signals; the circuit's
end-stop probe against the stop law written out here from the imposed motion (Hopsan's hard
stop, ``F = k pen + c v_pen``, never pulling); the gait flags against the physics of the
cases (a 20 mm stroke on a 40 mm pulley is ±14°, less than push-off's plantarflexion; the
published prototype's 105 deg/s pump is back-driven by a walking ankle, README)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from afo_mj.metrics.device_flags import (END_STOP_CONTACT_MIN_NM, device_flags,
                                         end_stop_contact, mechanical_role, tracking_flag)

HAFO = "scenarios/gait_assist_hafo.toml"
SHORT = ["gait.strides=5", "gait.analyse_strides=[3, 5]"]


def test_end_stop_contact_against_hand_summed_signal():
    dt = 1e-3
    stop = np.zeros(1000)
    stop[100:150] = 80.0             # contact 1: 50 ms at 80 N·m
    stop[600:620] = -30.0            # contact 2: 20 ms at -30 N·m
    stop[700] = 0.5 * END_STOP_CONTACT_MIN_NM     # grazing, not contact
    dlv = np.full(1000, 10.0)
    dlv[100:150] = 150.0
    dlv[400] = -25.0                 # the largest torque outside contact
    c = end_stop_contact(stop, dlv, dt, n_strides=2)
    assert c["contact_time_s"] == pytest.approx(0.070)
    assert c["contact_time_s_per_stride"] == pytest.approx(0.035)
    assert c["contact_fraction"] == pytest.approx(0.070)
    assert c["contacts_per_stride"] == pytest.approx(1.0)
    assert c["impulse_nm_s_per_stride"] == pytest.approx((80 * 0.050 + 30 * 0.020) / 2)
    assert c["peak_torque_nm"] == pytest.approx(80.0)
    assert c["delivered_peak_outside_contact_nm"] == pytest.approx(25.0)
    # contact from the first sample is one contact
    c0 = end_stop_contact(np.r_[5.0, 5.0, 0.0], np.ones(3), dt, 1)
    assert c0["contacts_per_stride"] == 1.0


def test_flags_follow_their_definitions():
    assert mechanical_role(-3.0, 2.0)[0] == "brake"
    assert mechanical_role(10.0, 12.0)[0] == "actuator"
    assert mechanical_role(0.2, 0.4)[0] == "near_zero"
    assert tracking_flag(12.0, 40.0) is True          # 30 % of the command
    assert tracking_flag(4.0, 40.0) is False          # 10 %
    assert tracking_flag(4.9, 0.0) is False           # below the absolute floor
    assert tracking_flag(math.nan, 40.0) is False
    f = device_flags({"contact_time_s": 0.01}, "brake", False)
    assert f == {"end_stop_contact": True, "brake": True, "tracking_poor": False,
                 "newton_unconverged": False, "battery_overload": False,
                 "flags": ["end_stop_contact", "brake"]}
    assert device_flags(None, "actuator", False)["flags"] == []


def test_end_stop_probe_is_the_stop_law_on_an_imposed_overtravel():
    """Drive the HAFO's ankle (transparent) slowly past the pistons' stroke ends and compare
    the logged ``cylinders.end_stop_torque_nm`` with the stop law evaluated here."""
    from afo_mj.devices.hafo import HAFO_GAIT, HafoDevice
    p = HAFO_GAIT
    cy, r, count = p.cylinder, p.pulley_radius_m, p.cylinders
    dev = HafoDevice(p, timestep_s=1e-3)
    th_end = cy.stroke_m / 2 / r                      # the angle where x reaches 0
    n = 1200
    t = np.arange(1, n + 1) * 1e-3
    vel = np.full(n, 0.01)                            # rad/s, slow: the pressures settle
    ang = th_end - 0.007 + 0.01 * t                   # crosses th_end at 0.7 s, 5 mrad past
    out = dev.run_imposed(np.zeros(n), ang, vel)
    stop = out["cylinders.end_stop_torque_nm"]
    # each log row is the end of a sample interval: the law at the row's own joint motion
    x = cy.stroke_m / 2 - r * out["angle_rad"]
    xd = -r * out["velocity_rad_s"]
    k, c = cy.end_stop_stiffness_n_m, cy.end_stop_damping_n_s_m
    force = np.where(x < 0, np.maximum(-k * x - c * xd, 0.0), 0.0)
    expected = -r * count * force
    assert np.any(expected < -1.0) and np.any(expected == 0.0)
    # (the replay's last row logs the last imposed angle, its probes one interval on)
    np.testing.assert_allclose(stop[:-1], expected[:-1], rtol=1e-9, atol=1e-9)


def _hafo_assist(*extra):
    from afo_mj.app.run import run_scenario
    return run_scenario(HAFO, overrides=SHORT + ['device.conditions=["assist"]', *extra],
                        figures=False)


def test_short_stroke_reports_stop_contact_and_the_peak_outside_it():
    res = _hafo_assist("device.params.cylinder.stroke_m=0.02")
    d = res.summary.to_json()["device"]
    assert d["end_stop_contact"] and "end_stop_contact" in d["flags"]
    es = d["end_stop"]
    assert es["contact_time_s_per_stride"] > 0.02 and es["contacts_per_stride"] >= 1.0
    assert es["impulse_nm_s_per_stride"] > 1.0
    # the stops, not the actuator, made the large joint torque: the actuator's own peak
    # (outside contact) is near its 40 N·m command, the whole-joint peak far above it
    assert d["peak_torque_incl_end_stops_nm"] > 100.0
    assert d["peak_torque_nm"] < 60.0
    assert d["tracking_poor"]
    # the default 45 mm stroke (±32°) is never reached in this walk
    d0 = _hafo_assist().summary.to_json()["device"]
    assert not d0["end_stop_contact"] and d0["end_stop"]["contact_time_s"] == 0.0
    assert d0["flags"] == [] and d0["mechanical_role"] == "actuator"
    assert d0["peak_torque_nm"] == pytest.approx(d0["peak_torque_incl_end_stops_nm"])


def test_console_says_what_the_flags_say(capsys, tmp_path):
    from afo_mj.cli import main
    out = tmp_path / "r"
    rc = main(["run", HAFO, "--out", str(out), "--quiet", "--set", SHORT[0], "--set", SHORT[1],
               "--set", 'device.conditions=["assist"]',
               "--set", "device.params.cylinder.stroke_m=0.02"])
    text = capsys.readouterr().out
    assert rc == 0
    assert "END-STOP CONTACT" in text and "TRACKING" in text
    s = json.loads((out / "summary.json").read_text())
    assert s["device"]["end_stop_contact"] is True
    assert s["device_conditions"]["assist"]["device"]["end_stop_contact"] is True


def test_prototype_worn_transparent_is_flagged_as_a_brake():
    from afo_mj.app.run import run_scenario
    res = run_scenario("scenarios/gait_assist_hafo_prototype.toml",
                       overrides=SHORT + ['device.conditions=["transparent"]'], figures=False)
    d = res.summary.to_json()["device"]
    assert d["brake"] and d["mechanical_role"] == "brake" and "brake" in d["flags"]
    assert d["net_work_j_per_stride"] < -5.0
    assert d["net_work_j_per_stride"] == pytest.approx(
        d["positive_work_j_per_stride"] + d["negative_work_j_per_stride"])


FALL = ["gait.strides=4", "gait.analyse_strides=[3, 4]",
        "impairment.plantarflexor_strength_fraction=0.1"]


@pytest.mark.parametrize("scenario,extra", [
    ("scenarios/walk_healthy.toml", []),
    (HAFO, ['device.conditions=["no_device", "transparent"]']),
])
def test_a_fall_is_a_written_result_for_every_walk(tmp_path, capsys, scenario, extra):
    """The same weak walker falls without and with the orthosis: both runs exit 0, write
    their results and say ``fell`` with the time (a device walk used to exit 1 with nothing
    written)."""
    from afo_mj.cli import main
    out = tmp_path / "r"
    args = ["run", scenario, "--out", str(out), "--quiet"]
    for o in FALL + extra:
        args += ["--set", o]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "FELL" in text
    s = json.loads((out / "summary.json").read_text())
    assert s["fell"] is True and 0.5 < s["fall_time_s"] < 6.0
    assert s["fall_time_s"] == round(s["fall_time_s"], 6)      # not 4.3419999999
    assert (out / "gait_curves.csv").exists()
    if "device_conditions" in s:
        for c, v in s["device_conditions"].items():
            assert v["fell"] is True and v["fall_time_s"] > 0.5, c
        assert s["device"]["window"]


def test_a_fallen_sweep_point_is_ok_with_fell_and_constrainable(tmp_path):
    """A sweep row of a walk that fell is a result (status ok, fell true), and a study can
    constrain on the device flags (0/1 through the row)."""
    from afo_mj.app.sweep_point import run_point
    from afo_mj.studies.optimize import Constraint, _metric_value
    row = run_point(HAFO, FALL + ['device.conditions=["transparent"]'], "r0", {})
    assert row["status"] == "ok" and row["exit_code"] == 0, row["error"]
    assert row["fell"] is True
    row2 = run_point(HAFO, SHORT + ['device.conditions=["assist"]',
                                    "device.params.cylinder.stroke_m=0.02"], "r1", {})
    assert row2["status"] == "ok" and row2["device.end_stop_contact"] is True
    v, present = _metric_value(row2, "device.end_stop_contact")
    assert present and v == 1.0
    assert Constraint("device.end_stop_contact", max=0.0).violation(v) > 0
    assert row2["device.end_stop.contact_time_s_per_stride"] > 0.0


def test_sweep_says_which_runs_hit_the_stops(tmp_path, capsys):
    """``afo-mj sweep`` over the stroke: the short-stroke run is counted and named as an
    end-stop contact (and poor tracking), the full-stroke run is not; both are ok rows."""
    from pathlib import Path

    from afo_mj import cli
    root = Path(__file__).resolve().parents[1]
    study = tmp_path / "stroke.toml"
    study.write_text(
        f'name = "stroke"\nscenario = "{(root / HAFO).as_posix()}"\n'
        f'set = ["gait.strides=5", "gait.analyse_strides=[3, 5]", '
        f"'device.conditions=[\"assist\"]']\n"
        '[design]\nkind = "grid"\n[[parameter]]\nkey = "device.params.cylinder.stroke_m"\n'
        'levels = [0.02, 0.045]\n')
    rc = cli.main(["sweep", str(study), "--out", str(tmp_path / "o"), "--quiet",
                   "--workers", "1", "--format", "csv"])
    text = capsys.readouterr().out
    assert rc == 0
    doc = json.loads(text.strip().splitlines()[-1])
    assert doc["failed"] == 0 and doc["outcomes"].get("end-stop contact") == 1
    line = [ln for ln in text.splitlines() if ln.startswith("  ") and "end-stop contact" in ln]
    assert len(line) == 1 and "1 run(s)" in line[0]


def test_compare_rows_carry_the_flags_and_say_them(tmp_path):
    from afo_mj.app.compare import compare
    from afo_mj.outputs.comparison_report import format_tables
    res = compare([HAFO], tmp_path / "c", overrides=["device.params.cylinder.stroke_m=0.02",
                                                     "gait.analyse_strides=[3, 5]"], strides=5)
    (row,) = res.comparison.rows
    assert row["end_stop_contact"] is True and row["tracking_poor"] is True
    assert row["end_stop_contact_time_s_per_stride"] > 0.02
    assert row["peak_torque_incl_end_stops_nm"] > 100.0 > 60.0 > row["peak_torque_nm"]
    text = format_tables(res.comparison)
    assert "END-STOP CONTACT: " in text and "POOR TRACKING: " in text


def test_compare_says_which_rows_had_unconverged_solver_steps():
    """A comparison row whose circuit accepted unconverged Newton steps carries the count in
    its columns and gets a WARNING SOLVER line under the tables naming it; a clean row none."""
    from afo_mj.experiments.device_comparison import HEAD_COLUMNS
    from afo_mj.outputs.comparison_report import caveats
    assert {"newton_unconverged", "newton_unconverged_steps"} <= set(HEAD_COLUMNS)
    lines = caveats([{"label": "hafo assist", "newton_unconverged": True,
                      "newton_unconverged_steps": 12},
                     {"label": "valve assist", "newton_unconverged": False,
                      "newton_unconverged_steps": 0}])
    assert len(lines) == 1 and lines[0].startswith("WARNING SOLVER: hafo assist: 12 ")
