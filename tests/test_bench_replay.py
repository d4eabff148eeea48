"""Bench replay and the calibration effects' component equations, against independent
references: the same device stepped with MuJoCo on the ankle test stand, the seal module, the
2×2 linear algebra of the series compliance, and the play operator's definition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.devices import pump_ankle_actuator as pa
from afo_mj.devices.hafo import HafoDevice, hafo_params
from afo_mj.hydraulics.params import ParameterError
from afo_mj.hydraulics.seal import OringSeal, OringSealParams
from afo_mj.hydraulics.sensor import sensor_reading
from afo_mj.hydraulics.transmission import play_operator, series_compliance_m3_pa
from afo_mj.scenarios.bench_replay import BenchReplay, ReplayError


def _volt(t):
    return 3.0 * math.sin(2 * math.pi * 0.8 * t) + 1.5 * math.sin(2 * math.pi * 3.1 * t)


def test_replay_matches_the_mujoco_test_stand():
    """The compiled replay against HafoDevice stepped by MuJoCo with the same imposed angle."""
    from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad

    traj = ImposedTrajectory.sinusoid(0.1, 1.0)
    stand = AnkleTestStand(load=StandLoad(kind="imposed", trajectory=traj))
    n = 1500
    dev = HafoDevice(hafo_params(), mode="voltage", torque_fn=lambda t, a, v: _volt(t),
                     max_steps=n)
    rec = stand.run_device(dev, n * 1e-3)
    log = dev.log.arrays()
    # the stand's sample k is the state at the start of step k; the log's row k its end
    t = rec.time_s
    volt = np.array([_volt(x) for x in t])
    rep = BenchReplay("hafo")
    out = rep.simulate(t, {"motor_voltage_v": volt, "ankle_angle_rad": rec.angle_rad})
    for ch, field in (("pressure_a_pa", "pressure_a_pa"), ("chamber_b_pa", "chamber_b_pa"),
                      ("motor_current_a", "motor_current_a")):
        ref = log[field][:-1, 0]             # end of step k = start of step k + 1
        got = out[ch][1:]
        span = np.ptp(ref)
        assert span > 0
        err = np.sqrt(np.mean((got[200:] - ref[200:]) ** 2)) / span
        assert err < 0.02, (ch, err)


def test_effects_off_leave_the_replay_unchanged():
    rep = BenchReplay("hafo")
    t = np.arange(800) * 1e-3
    ins = {"motor_voltage_v": 2.0 * np.sin(6 * t), "ankle_angle_rad": 0.1 * np.sin(6 * t)}
    a = rep.simulate(t, ins)
    b = rep.simulate(t, ins, {pa.P_SEAL_CP: 0.0, pa.P_SERIES_COMP: 0.0,
                              pa.P_PUMP_G_EXTRA: 0.0})
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    c = rep.simulate(t, ins, {pa.P_G_LEAK: 1e-14})
    assert np.max(np.abs(c["chamber_a_pa"] - a["chamber_a_pa"])) > 1e4


def test_replay_errors_are_named():
    rep = BenchReplay("hafo")
    t = np.arange(100) * 1e-3
    with pytest.raises(ReplayError, match="motor_voltage_v"):
        rep.simulate(t, {"ankle_angle_rad": np.zeros(100)})
    with pytest.raises(ParameterError, match="preset"):
        BenchReplay("no_such_preset")


def test_kernel_pressure_friction_matches_the_seal_module():
    seal = OringSeal(OringSealParams(pressure_coefficient_m2=2e-6, pressure_friction_enabled=True,
                                     stribeck_enabled=False, viscous_enabled=False), 10e-3)
    P = np.zeros(pa.N_P)
    P[pa.P_SEAL_FC] = seal.coulomb_force_n
    P[pa.P_SEAL_VC] = seal._v_c
    P[pa.P_SEAL_VST] = 1.0
    P[pa.P_SEAL_CP] = 2e-6
    for v, dp in ((0.05, 4e6), (-0.02, -2e6), (1e-4, 6e6)):
        ref = float(seal.friction_force_n(v, dp))
        got = pa._seal_force(v, dp, P)
        # the kernel rounds |Δp| over 10 kPa for its Newton iteration
        assert got == pytest.approx(ref, rel=1e-4)


def test_series_compliance_rates_solve_the_coupled_chambers():
    P = np.zeros(pa.N_P)
    r, ae, k = 0.04, 1.6e-4, 2000.0
    cs = series_compliance_m3_pa(r, ae, k)
    assert cs == pytest.approx(r * r * ae * ae / k)
    P[pa.P_SERIES_COMP] = cs
    na, nb, ca, cb, xdot = 3e-6, -1e-6, 3e-15, 4e-15, 0.02
    dpa, dpb, xdp = pa.chamber_rates(na, nb, ca, cb, xdot, ae, P)
    A = np.array([[ca + cs, -cs], [-cs, cb + cs]])
    ref = np.linalg.solve(A, [na, nb])
    assert dpa == pytest.approx(ref[0], rel=1e-12)
    assert dpb == pytest.approx(ref[1], rel=1e-12)
    # the pistons move by the ankle's motion less the cable's stretch rate r² A_e Δṗ / k
    assert xdp == pytest.approx(xdot - r * r * ae * (dpa - dpb) / k, rel=1e-12)
    P[pa.P_SERIES_COMP] = 0.0
    assert pa.chamber_rates(na, nb, ca, cb, xdot, ae, P) == (na / ca, nb / cb, xdot)
    with pytest.raises(ParameterError, match="stiffness_nm_rad"):
        series_compliance_m3_pa(r, ae, 0.0)


def test_play_operator_definition():
    x = np.array([0.0, 0.05, 0.2, 0.3, 0.25, 0.1, -0.1, 0.0])
    y = play_operator(x, 0.1)
    ref = [0.0]
    for v in x[1:]:
        ref.append(min(max(ref[-1], v - 0.05), v + 0.05))
    np.testing.assert_allclose(y, ref)
    assert np.all(np.abs(y - x) <= 0.05 + 1e-15)
    np.testing.assert_array_equal(play_operator(x, 0.0), x)
    with pytest.raises(ParameterError, match="backlash"):
        play_operator(x, -0.1)


def test_sensor_reading_delay_gain_offset():
    t = np.arange(200) * 1e-3
    y = np.sin(2 * np.pi * 5 * t)
    got = sensor_reading(t, y, gain=1.1, offset=0.3, delay_s=0.01)
    ref = 1.1 * np.sin(2 * np.pi * 5 * (t - 0.01)) + 0.3
    np.testing.assert_allclose(got[20:], ref[20:], atol=2e-3)
    with pytest.raises(ParameterError, match="delay_s"):
        sensor_reading(t, y, delay_s=-1.0)


def test_closed_loop_replay_of_gait_kinematics_matches_the_stand():
    """A record of a walk: the measured ankle angle (Winter's normal gait, replayed as the
    stand's imposed motion) and the torque reference of the HAFO's own controller (a Zhang
    profile over the stride). The replay runs the controller on the model (``commanded_torque_nm``
    input) and must reproduce the MuJoCo-stepped device's pressures, current and torque."""
    from afo_mj.control.assistance import table_lookup, zhang_profile
    from afo_mj.gait.reference import load_normative
    from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad

    ref = load_normative("winter", "normal")
    T = 1.14
    n = 2500
    t = np.arange(n) * 1e-3
    ang = ref.angles_rad(t / T)[:, 2]
    traj = ImposedTrajectory.sampled(t, ang)
    stand = AnkleTestStand(load=StandLoad(kind="imposed", trajectory=traj))
    table = zhang_profile(30.0, 52.9, 26.2, 9.8)

    def cmd(tt, a=None, v=None):
        return float(table_lookup(table, (tt / T) % 1.0))

    dev = HafoDevice(hafo_params(preset="hafo_gait"), torque_fn=cmd, max_steps=n)
    rec = stand.run_device(dev, n * 1e-3)
    log = dev.log.arrays()
    rep = BenchReplay("hafo_gait")
    tau_ref = np.array([cmd(x) for x in rec.time_s])
    out = rep.simulate(rec.time_s, {"commanded_torque_nm": tau_ref,
                                    "ankle_angle_rad": rec.angle_rad})
    for ch, field in (("chamber_a_pa", "chamber_a_pa"), ("pressure_b_pa", "pressure_b_pa"),
                      ("motor_current_a", "motor_current_a"),
                      ("ankle_torque_nm", "delivered_torque_nm")):
        ref_sig = log[field][:-1, 0]
        got = out[ch][1:]
        span = np.ptp(ref_sig[300:])
        err = np.sqrt(np.mean((got[300:] - ref_sig[300:]) ** 2)) / span
        assert err < 0.03, (ch, err)
    # the controller did track the reference (so the closed loop is really exercised)
    assert np.sqrt(np.mean((out["ankle_torque_nm"][300:] - tau_ref[300:]) ** 2)) < 5.0
    # without a command channel the replay says what it needs
    with pytest.raises(ReplayError, match="commanded_torque_nm"):
        rep.simulate(rec.time_s, {"ankle_angle_rad": rec.angle_rad})
