"""Record mistakes a user makes are refused or flagged before a fit (issue 20, item 7): an
angle past the declared cylinder's end stops, pressures at the relief setting.

References: the HAFO's published geometry (45 mm stroke piston-cable cylinder on a 40 mm
pulley, centred: ±0.5625 rad, Neubauer 2017 ch. 5) and its 14 MPa relief cracking pressure,
written here by hand, not read from the code under test."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from afo_mj.calibration.record_checks import check_record
from afo_mj.devices.hafo import PRESETS

HAFO = PRESETS["hafo"]
T = np.linspace(0.0, 4.0, 4001)
STROKE_LIMIT_RAD = 0.5 * 0.045 / 0.040
RELIEF_PA = 14.0e6


def test_published_geometry_is_what_the_check_uses():
    assert HAFO.cylinder.stroke_m == pytest.approx(0.045)
    assert HAFO.pulley_radius_m == pytest.approx(0.040)
    assert HAFO.relief.cracking_dp_pa == pytest.approx(RELIEF_PA)


def test_angle_in_degrees_is_refused_naming_the_channel_and_the_limit():
    deg = 10.0 * np.sin(2 * np.pi * T)                       # 10 "rad": degrees logged
    f = check_record({"ankle_angle_rad": deg}, HAFO)
    assert [x.severity for x in f] == ["refuse"] and f[0].channel == "ankle_angle_rad"
    assert f"{STROKE_LIMIT_RAD:.3g}" in f[0].message and "deg" in f[0].message
    # inside the stroke, and just outside it
    assert check_record({"ankle_angle_rad": 0.99 * STROKE_LIMIT_RAD * np.sin(T)}, HAFO) == []
    over = check_record({"ankle_angle_rad": np.full(10, 1.01 * STROKE_LIMIT_RAD)}, HAFO)
    assert over and over[0].check == "stroke"


def test_pressure_at_the_relief_setting_is_flagged_not_refused():
    p = 15.0e6 * np.clip(np.sin(2 * np.pi * T), 0, None)    # peaks above 14 MPa gauge
    f = check_record({"pressure_a_pa": p, "ankle_angle_rad": 0.1 * np.sin(T)}, HAFO)
    assert [(x.severity, x.check, x.channel) for x in f] == [("flag", "relief",
                                                              "pressure_a_pa")]
    assert "14" in f[0].message and "gauge" in f[0].message
    assert check_record({"pressure_a_pa": 0.9 * RELIEF_PA * np.sin(T) ** 2}, HAFO) == []


def test_angle_noise_swamping_the_torque_is_flagged():
    """A 0.002 rad encoder imposed on the HAFO: with the pump held the oil's ankle stiffness
    is (A r)^2 (1/C_a + 1/C_b) (Merritt §5.3), computed here from the geometry; the flag's
    torque equals K σθ and appears only when it exceeds 3 torque-sensor σ."""
    import math

    from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA, Fluid
    p = HAFO
    # piston-cable: the cable runs through both chambers, so both sides are annuli
    area = p.cylinders * math.pi / 4 * (p.cylinder.bore_m ** 2 - p.cylinder.rod_diameter_m ** 2)
    b = float(Fluid(p.fluid).bulk_modulus_pa(1e6 + ATMOSPHERIC_PRESSURE_PA))
    v_hose = math.pi / 4 * p.hose.bore_m ** 2 * p.hose.length_m
    v_side = p.cylinder.dead_volume_a_m3 + area * p.cylinder.stroke_m / 2
    c_side = (v_side + v_hose + p.pump_port_volume_m3) / b + v_hose / p.hose.wall_bulk_modulus_pa
    k_ref = (area * p.pulley_radius_m) ** 2 * 2 / c_side
    ch = {"ankle_angle_rad": 0.2 * np.sin(T), "ankle_torque_nm": 10 * np.sin(T)}
    f = check_record(ch, p, {"ankle_angle_rad": 0.002, "ankle_torque_nm": 0.5},
                     ("ankle_angle_rad",))
    assert [x.check for x in f] == ["input_noise"]
    assert f"~{k_ref * 0.002:.3g} N*m" in f[0].message
    assert check_record(ch, p, {"ankle_angle_rad": 1e-5, "ankle_torque_nm": 0.5},
                        ("ankle_angle_rad",)) == []
    # an angle that is an output (the load simulated) is not imposed: nothing to flag
    assert check_record(ch, p, {"ankle_angle_rad": 0.002, "ankle_torque_nm": 0.5}, ()) == []


def test_calibrate_refuses_an_angle_with_a_shifted_zero_and_writes_nothing(tmp_path):
    """An angle whose zero is not mid-stroke (here +0.5 rad) passes the loader's unit check
    (|θ| < 1.2 rad) but would drive the piston into its end stop: refused, exit 2."""
    from afo_mj.app.calibrate import calibrate_record
    from afo_mj.app.errors import InvalidInput
    from afo_mj.calibration.measured_data import load_measured, write_measured
    from afo_mj.calibration.synthetic_records import generate_record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = generate_record(tmp_path / "ok.csv", "hafo", duration_s=3.0, seed=1)
    chans = {k: np.asarray(v) for k, v in data.channels.items()}
    chans["ankle_angle_rad"] = chans["ankle_angle_rad"] + 0.5
    src = tmp_path / "shifted.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_measured(src, {"time_s": data.time_s, **chans}, inputs=data.inputs,
                       outputs=data.outputs, source=data.source, noise=data.noise)
        assert load_measured(src).channels["ankle_angle_rad"].max() > STROKE_LIMIT_RAD
    out = tmp_path / "report"
    with pytest.raises(InvalidInput, match="ankle_angle_rad reaches .* past the declared"):
        calibrate_record("hafo", src, out)
    assert not out.exists()


def test_check_signs_refuses_anti_correlated_outputs_only():
    from afo_mj.calibration.record_checks import check_signs
    rng = np.random.default_rng(0)
    s = np.sin(2 * np.pi * T)
    noisy = s + 0.3 * rng.standard_normal(T.size)
    assert check_signs({"ankle_torque_nm": noisy}, {"ankle_torque_nm": s}) == []
    f = check_signs({"ankle_torque_nm": -noisy, "pressure_a_pa": noisy},
                    {"ankle_torque_nm": s, "pressure_a_pa": s}, ("motor_voltage_v",
                                                                 "ankle_angle_rad"))
    assert [(x.severity, x.channel) for x in f] == [("refuse", "ankle_torque_nm")]
    assert "ankle_angle_rad" in f[0].message and "dorsiflexion positive" in f[0].message


def test_calibrate_refuses_a_flipped_torque_before_fitting(tmp_path):
    """A torque logged plantarflexion-positive: refused after the first replay (exit 2, nothing
    written), not fitted into a confident verdict."""
    from afo_mj.app.calibrate import calibrate_record
    from afo_mj.app.errors import InvalidInput
    from afo_mj.calibration.measured_data import write_measured
    from afo_mj.calibration.synthetic_records import generate_record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = generate_record(tmp_path / "ok.csv", "hafo", duration_s=3.0, seed=2)
        chans = {k: np.asarray(v) for k, v in data.channels.items()}
        chans["ankle_torque_nm"] = -chans["ankle_torque_nm"]
        src = tmp_path / "flipped.csv"
        write_measured(src, {"time_s": data.time_s, **chans}, inputs=data.inputs,
                       outputs=data.outputs, source=data.source, noise=data.noise)
    out = tmp_path / "report"
    with pytest.raises(InvalidInput, match="ankle_torque_nm is anti-correlated"):
        calibrate_record("hafo", src, out)
    assert not out.exists()
