"""The independent lab ankle rig (tests/independent_rig.py) against independent references:
analytic pressure build-up, the energy balance, an analytic leakage steady state, the sign
convention, every effect switch, the record format, and its independence from afo_mj."""

from __future__ import annotations

import ast
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import independent_rig as R
from afo_mj.calibration.measured_data import MeasuredDataWarning, load_measured

RIG_FILE = Path(__file__).with_name("independent_rig.py")
P = R.RigParams()


def _bulk_modulus_from_volumes(p_gauge, b_l, alpha, n):
    """Effective bulk modulus from its definition ``B = −V dp/dV`` with the liquid and the
    gas volumes written out (``V_g = α V_l0 (p0/p)^{1/n}``, ``dV_l/dp = −V_l0/B_l``)."""
    p = p_gauge + R.P_ATM
    v_l, v_g = 1.0, alpha * (R.P_ATM / p) ** (1 / n)
    dv_dp = -v_l / b_l - v_g / (n * p)
    return -(v_l + v_g) / dv_dp


def _ramp(v0, t_ramp=2e-3):
    return lambda t: v0 * min(t / t_ramp, 1.0)


@pytest.mark.parametrize("air", [0.0, 0.005])
def test_locked_closed_pressure_rise_rate(air):
    """(a) Locked load, hoses shut: dp/dt at the pump port = B_eff / V_port · d ω."""
    prm = R.RigParams(air_fraction=air)
    w0 = 100.0
    rig = R.Rig(prm, {}, lambda t: prm.motor_k * w0, locked=True, hoses_closed=True)
    y0 = rig.initial_state(omega_m=w0)
    b = prm.oil_bulk_modulus_pa if air == 0 else _bulk_modulus_from_volumes(
        prm.charge_pressure_pa, prm.oil_bulk_modulus_pa, air, prm.polytropic_index)
    expected = b / prm.port_volume_m3 * prm.displacement_m3_rad * w0
    dy = rig.rhs(0.0, y0)
    assert dy[rig.ix["p_pa"]] == pytest.approx(expected, rel=1e-9)
    # integrated: the slope over the first 0.2 µs (B_eff varies with p over longer windows)
    t, Y = rig.simulate(2e-7, rtol=1e-10, y0=y0, sample_rate_hz=1e7)
    slope = (Y[rig.ix["p_pa"], -1] - Y[rig.ix["p_pa"], 0]) / t[-1]
    assert slope == pytest.approx(expected, rel=1e-3)


ENERGY_EFFECTS = {"stribeck": True, "pressure_friction": True, "piston_leakage": True,
                  "pump_leakage": True, "hose_compliance": True, "check_cracking": True,
                  "current_limit": 4.0}


@pytest.mark.parametrize("effects", [{}, ENERGY_EFFECTS, {"line_inertance": True},
                                     {"cable_compliance": True}])
def test_energy_balance(effects):
    """(b) electrical + reservoir energy in = resistive + friction + leakage + throttling +
    damping losses + stored (oil, spring, inertia, inductance, line, cable)."""
    rig = R.Rig(None, effects, R.default_voltage_profile(1.0))
    t, Y = rig.simulate(1.0)
    e = R.energy_balance(rig, Y)
    assert e["E_in"] > 0.5
    for k, v in e.items():
        if k.startswith("L_"):
            assert v >= -1e-9, (k, v)
    assert abs(e["residual"]) <= 1e-4 * e["inputs"], e
    if effects:
        assert e["L_check"] > 0 and e["L_seal"] > 0


def test_piston_leakage_steady_state():
    """(c) Piston held, piston leakage on, constant voltage: pump flow − slip = leakage flow,
    motor torque = d Δp + friction, hose drops laminar: the pressures solve a linear system."""
    c_l = 5e-14
    v0 = 3.0
    rig = R.Rig(None, {"piston_leakage": c_l}, _ramp(v0), locked=True)
    t, Y = rig.simulate(1.5, sample_rate_hz=100.0)
    d, k, res = P.displacement_m3_rad, P.motor_k, P.resistance_ohm
    r_h = 128 * P.oil_viscosity_pa_s * P.hose_length_m / (math.pi * P.hose_bore_m ** 4)
    # unknowns: ω, Δp_port, Δp_chamber, q
    a = np.array([
        [k * k / res + P.motor_viscous_nm_s, d, 0.0, 0.0],   # k (V − kω)/R = bω + T_c + dΔp
        [d, -P.pump_leak_m3_s_pa, 0.0, -1.0],                # dω = C_s Δp_port + q
        [0.0, 0.0, c_l, -1.0],                               # q = C_l Δp_ch
        [0.0, 1.0, -1.0, -2 * r_h],                          # Δp_port = Δp_ch + 2 R_h q
    ])
    rhs = np.array([k * v0 / res - P.motor_coulomb_nm, 0.0, 0.0, 0.0])
    w, dp_port, dp_ch, q = np.linalg.solve(a, rhs)
    assert w > 10 * P.motor_coulomb_speed_rad_s      # Coulomb term saturated (tanh ≈ 1)
    ix = rig.ix
    assert Y[ix["p_pa"], -1] - Y[ix["p_pb"], -1] == pytest.approx(dp_port, rel=1e-5)
    assert Y[ix["p_a"], -1] - Y[ix["p_b"], -1] == pytest.approx(dp_ch, rel=1e-5)
    assert Y[ix["omega_m"], -1] == pytest.approx(w, rel=1e-5)
    # held piston: the torque is −r A Δp_chamber
    tau = rig.algebraic(t[-1], Y[:, -1])["tau"]
    assert tau == pytest.approx(-P.pulley_radius_m * P.area_m2 * dp_ch, rel=1e-5)


def test_sign_convention():
    """(d) Positive motor voltage: plantarflexion (negative) torque and angle, port A above
    port B, piston toward chamber B (x > 0), motor turning forward."""
    rig = R.Rig(None, {}, _ramp(3.0))
    t, Y = rig.simulate(0.5)
    ch = R.true_channels(rig, t, Y)
    assert ch["ankle_torque_nm"][-1] < -5.0
    assert ch["ankle_angle_rad"][-1] < -0.02
    assert ch["pressure_a_pa"][-1] > ch["pressure_b_pa"][-1] + 1e6
    assert ch["piston_position_m"][-1] > 0
    assert ch["motor_speed_rad_s"][200] > 0 and ch["motor_current_a"][-1] > 0
    # and the reverse
    rig = R.Rig(None, {}, _ramp(-3.0))
    t, Y = rig.simulate(0.5)
    ch = R.true_channels(rig, t, Y)
    assert ch["ankle_torque_nm"][-1] > 5.0 and ch["ankle_angle_rad"][-1] > 0.02


DURATION_E = 0.8


@pytest.fixture(scope="module")
def baseline():
    return R.simulate_record(DURATION_E, {}, seed=3)[1]


@pytest.mark.parametrize("name", list(R.EFFECTS))
def test_effect_changes_record(baseline, name):
    """(e) Each effect, switched on at its default, changes the record beyond the sensor
    noise on at least one channel (same seed: the noise is the same draw)."""
    ch = R.simulate_record(DURATION_E, {name: True}, seed=3)[1]
    sig = R.noise_sigmas(P)
    ratio = {k: float(np.max(np.abs(ch[k] - baseline[k]))) / sig[k] for k in sig}
    assert max(ratio.values()) > 3.0, ratio


def test_effects_off_leave_record_unchanged(baseline):
    """(e) Effects named but switched off (False / None) give the baseline exactly."""
    off = {name: (False if j % 2 else None) for j, name in enumerate(R.EFFECTS)}
    ch = R.simulate_record(DURATION_E, off, seed=3)[1]
    for k in baseline:
        np.testing.assert_array_equal(ch[k], baseline[k])
    with pytest.raises(ValueError, match="unknown effect"):
        R.resolve_effects({"stribek": True})


def test_effect_list():
    assert len(R.EFFECTS) >= 8
    for e in R.EFFECTS.values():
        assert e.default > 0 and e.description


def test_record_loads_cleanly(tmp_path):
    """(f) The record loads through load_measured with no error and no warning."""
    path = tmp_path / "rig.csv"
    R.write_record(path, 1.0, {"piston_leakage": True, "sensor_delay": True}, seed=7)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeasuredDataWarning)
        d = load_measured(path)
    assert list(d.inputs) == ["motor_voltage_v"]
    assert set(d.outputs) == set(R.CHANNEL_UNITS) - {"motor_voltage_v"}
    assert d.sample_period_s == pytest.approx(1e-3)
    assert d.source["preset"] == "hafo"
    assert "independent" in d.source["description"]
    assert d.noise["pressure_a_pa"] == pytest.approx(2e4)
    text = path.with_suffix(".toml").read_text()
    assert "[noise]" in text and "piston_leakage" in text
    # the angle is quantised to the 12-bit encoder's LSB
    lsb = P.encoder_lsb_rad
    theta = np.asarray(d.channels["ankle_angle_rad"])
    assert np.allclose(theta / lsb, np.round(theta / lsb), atol=1e-6)
    assert np.ptp(theta) > 10 * lsb


def test_imports_only_the_writer_from_afo_mj():
    """(g) The rig imports nothing from afo_mj but measured_data's writer."""
    tree = ast.parse(RIG_FILE.read_text())
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.split(".")[0] == "afo_mj"]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "afo_mj":
            assert node.module == "afo_mj.calibration.measured_data", node.module
            assert [a.name for a in node.names] == ["write_measured"]
    assert found == []
    calls = {n.func.id for n in ast.walk(tree)
             if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
    assert "__import__" not in calls
    modules = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert "importlib" not in modules


@pytest.mark.slow
def test_default_length_record(tmp_path):
    """A default-length (20 s) record with four effects on writes and loads cleanly."""
    path = tmp_path / "rig20.csv"
    R.write_record(path, 20.0, {"stribeck": True, "piston_leakage": True,
                                "check_cracking": True, "sensor_delay": True}, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeasuredDataWarning)
        load_measured(path)
