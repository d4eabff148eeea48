"""Calibrating a rig described as a circuit (issue 20, items 1 and 2).

* the simulated-load replay (``CircuitDevice.run_imposed(load=...)``) against the separately
  written load loop ``CircuitDevice.run_load``;
* the identifiability selection on sensitivity matrices whose answer is known by
  construction (a duplicated column, a dead column, a column buried in noise);
* the calibration scenario's ``[circuit]``/``[load]``/``[sensors]`` tables and their errors;
* blind, on a record of the independent lab rig (``tests/independent_rig.py``, its own
  equations and scipy's Radau): the clean record's baseline reaches twice the noise floor on
  every channel and no effect is named.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from afo_mj.calibration.identifiability import select_parameters

ROOT = Path(__file__).resolve().parents[1]
RIG_SCENARIO = ROOT / "scenarios" / "calibration" / "lab_rig.toml"


# ---------------------------------------------------------------- identifiability
def _jac(n=2000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, n)
    return np.column_stack([np.sin(7 * t), np.cos(3 * t), t ** 2, rng.normal(size=n)])


def test_duplicated_column_is_held_as_a_combination():
    J = _jac()
    J = np.column_stack([J, 2.0 * J[:, 1]])        # parameter 4 moves the outputs as 1 does
    names = ["a", "b", "c", "d", "b_twin"]
    out = select_parameters(J, names, np.full(len(J), 10.0))
    fitted = {r.name for r in out.rows if r.fitted}
    assert len({"b", "b_twin"} & fitted) == 1
    held = next(r for r in out.rows if r.name in {"b", "b_twin"} and not r.fitted)
    assert "combination" in held.reason
    assert {"a", "c", "d"} <= fitted
    # the whitened singular values show the lost direction: the last is ~0
    assert out.singular_values[-1] < 1e-8 * out.singular_values[0]


def test_dead_and_immovable_columns_are_held_with_their_reason():
    J = _jac()
    J[:, 2] = 0.0
    out = select_parameters(J, ["a", "b", "c", "d"], np.full(len(J), 10.0),
                            movable=[True, True, True, False])
    by = {r.name: r for r in out.rows}
    assert not by["c"].fitted and "no sensitivity" in by["c"].reason
    assert not by["d"].fitted and "value is 0" in by["d"].reason
    assert by["a"].fitted and by["b"].fitted


def test_column_below_the_noise_is_held_by_its_predicted_error():
    J = _jac()
    J[:, 3] *= 1e-5      # moving d by 100 % changes the outputs by 1e-5 normalised units
    w = np.full(len(J), 1.0 / 0.05)     # noise 0.05 normalised
    out = select_parameters(J, ["a", "b", "c", "d"], w, max_relative_se=0.05)
    by = {r.name: r for r in out.rows}
    assert not by["d"].fitted
    # the Cramér–Rao bound of a lone column: σ / (w ‖J_d‖): check the table's figure for a
    # parameter that is kept against the closed form with the others present
    A = J[:, list(out.selected)] * w[:, None]
    se = np.sqrt(np.diag(np.linalg.inv(A.T @ A)))
    for j, s in zip(out.selected, se):
        assert by[["a", "b", "c", "d"][j]].predicted_relative_se == pytest.approx(s, rel=1e-9)


def test_select_parameters_refuses_bad_input():
    with pytest.raises(ValueError, match="jac shape"):
        select_parameters(np.ones((5, 2)), ["a"], np.ones(5))
    with pytest.raises(ValueError, match="row_weights"):
        select_parameters(np.ones((5, 1)), ["a"], np.zeros(5))


# ---------------------------------------------------------------- the simulated load
def test_simulated_load_replay_matches_the_load_loop():
    from afo_mj.circuits.codegen import build
    from afo_mj.circuits.device import CircuitDevice, JointLoad
    from afo_mj.circuits.library import lab_bench

    cc = build(lab_bench())
    n = 1500
    t = np.arange(n) * 1e-3
    cmd = 4.0 * np.sin(2 * np.pi * 3 * t) * (t > 0.05)
    a = CircuitDevice(cc, timestep_s=1e-3).run_load(cmd, inertia_kg_m2=0.05,
                                                    stiffness_nm_rad=100.0,
                                                    damping_nm_s_rad=2.0)
    b = CircuitDevice(cc, timestep_s=1e-3).run_imposed(
        cmd, np.zeros(n + 1), np.zeros(n + 1), load=JointLoad(0.05, 100.0, 2.0))
    assert np.max(np.abs(a["angle_rad"])) > 0.01          # the foot moved
    np.testing.assert_allclose(b["angle_rad"], a["angle_rad"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b["line_a"], a["line_a"], rtol=0, atol=1e-6)
    with pytest.raises(Exception, match="load.inertia_kg_m2"):
        JointLoad(0.0)


# ---------------------------------------------------------------- the scenario
def _scenario(tmp_path, extra: str) -> str:
    text = RIG_SCENARIO.read_text(encoding="utf-8")
    f = tmp_path / "rig.toml"
    f.write_text(text + "\n" + extra, encoding="utf-8")
    return str(f)


def test_rig_scenario_declares_circuit_load_and_sensors(tmp_path):
    from afo_mj.calibration.calibrate import load_calibration_scenario
    setup = load_calibration_scenario(_scenario(
        tmp_path, '[sensors.motor_current_a]\ncalibrated = false\n'))
    assert setup.circuit is not None and setup.load.inertia_kg_m2 == 0.05
    assert setup.options.uncalibrated_channels == ("motor_current_a",)
    rp = setup.replay()
    assert rp.described and "ankle_angle_rad" in rp.outputs
    assert rp.check_inputs({"motor_voltage_v": 0, "time_s": 0}) == ("motor_voltage_v",)
    assert rp.has("cylinders.seal_fc")          # the role answers to the rig's "cylinder"


@pytest.mark.parametrize("extra, match", [
    ('[sensors.motor_current_a]\ngain = 2\n', "sensors.motor_current_a.gain"),
    ('[sensors.motor_current_a]\ncalibrated = "no"\n', "calibrated"),
    ('[sensors.motor_current_a]\nsignal = "nope"\n', "sensors.motor_current_a.signal"),
])
def test_rig_scenario_errors_name_the_key(tmp_path, extra, match):
    from afo_mj.calibration.calibrate import load_calibration_scenario
    from afo_mj.hydraulics.params import ParameterError
    with pytest.raises(ParameterError, match=match):
        load_calibration_scenario(_scenario(tmp_path, extra)).replay()


def test_rig_scenario_load_errors(tmp_path):
    from afo_mj.calibration.calibrate import load_calibration_scenario
    from afo_mj.hydraulics.params import ParameterError
    text = RIG_SCENARIO.read_text(encoding="utf-8")
    f = tmp_path / "rig.toml"
    f.write_text(text.replace("inertia_kg_m2 = 0.05", "inertia_kg_m2 = -1"), encoding="utf-8")
    with pytest.raises(ParameterError, match="load.inertia_kg_m2"):
        load_calibration_scenario(str(f))
    f.write_text(text.replace('mode = "simulated"', 'mode = "free"'), encoding="utf-8")
    with pytest.raises(ParameterError, match="load.mode"):
        load_calibration_scenario(str(f))


# ---------------------------------------------------------------- blind, independent rig
@pytest.fixture(scope="module")
def rig():
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import independent_rig
    return independent_rig


def _rig_setup(**options):
    from afo_mj.calibration.calibrate import CalibrationOptions, load_calibration_scenario
    setup = load_calibration_scenario(str(RIG_SCENARIO))
    return type(setup)(setup.preset, setup.overrides,
                       CalibrationOptions(uncalibrated_channels=(), **options),
                       setup.circuit, setup.load, setup.signals)


@pytest.mark.slow
def test_effect_outside_the_library_is_not_named(rig, tmp_path):
    """Blind: a 6 s record of the independent rig whose torque cell rings at 80 Hz (a
    second-order sensor, not in the library): the baseline misses 2× the torque channel's
    noise floor, no physical effect is named, and the data-driven discrepancy reads the torque
    channel as the model's torque through a second-order instrument near 80 Hz. The residual is
    located (a resonance near 80 Hz on the torque channel) and the discrepancy brings it within
    2σ, so the verdict is ``unexplained_residual``, not ``structure_wrong`` (kept for a channel
    nothing accounts for; issue 41): measured, torque 2.45× its floor, accounted for by the
    replay's numerical error, the resonance and the discrepancy."""
    from afo_mj.calibration.calibrate import calibrate_setup
    data = rig.write_record(tmp_path / "ring.csv", duration_s=6.0, seed=4,
                            effects={"torque_sensor_resonance": 80.0})
    rep = calibrate_setup(data, _rig_setup(max_effects=1, refit_top=2))
    assert rep["baseline"]["ratio"]["ankle_torque_nm"] > 2.0
    assert rep["effects_selected"] == []
    assert rep["verdict"] == "unexplained_residual"
    by = rep["residual_attribution"]["channels"]["ankle_torque_nm"]["explained_by"]
    assert {"resonance", "data_driven_discrepancy"} <= set(by), by
    assert rep["residual_attribution"]["unexplained"] == []
    assert "resonance at" in rep["unexplained_where"]
    where = rep["baseline"]["structure_wrong_where"]
    assert "ankle_torque_nm" in where
    freq = float(where.split("dominant frequency ")[1].split(" Hz")[0])
    assert 60.0 < freq < 100.0
    disc = rep["data_driven_discrepancy"]
    assert "ankle_torque_nm" in disc and "data-driven" in disc["ankle_torque_nm"]["label"]
    # the discrepancy reads the torque cell as a second-order instrument near its 80 Hz
    torque = disc["ankle_torque_nm"]
    assert torque["found"] and torque["form"] == "second_order_reading", torque
    assert 70.0 < torque["natural_frequency_hz"] < 90.0
    assert torque["held_out_gain"] > 0.3


@pytest.mark.slow
def test_clean_independent_rig_record_reaches_the_noise_floor(rig, tmp_path):
    """Blind: a clean 10 s record of the independent rig, calibrated from the datasheet
    description: every channel's held-out baseline NRMSE within 2× its noise floor (σ/SD),
    verdict ``no_missing_effect``, no effect named and no declared value beyond its
    tolerance."""
    from afo_mj.calibration.calibrate import calibrate_setup
    data = rig.write_record(tmp_path / "clean.csv", duration_s=10.0, seed=3)
    rep = calibrate_setup(data, _rig_setup(max_effects=1, refit_top=2))
    ratio = rep["baseline"]["ratio"]
    assert set(ratio) >= {"pressure_a_pa", "ankle_torque_nm", "motor_current_a",
                          "ankle_angle_rad"}
    assert max(ratio.values()) < 2.0, ratio
    assert rep["verdict"] == "no_missing_effect" and rep["effects_selected"] == []
    assert rep["identifiability"]["fitted"]         # the table is reported
    # nothing named: no declared value beyond its tolerance (the seal's breakaway velocity,
    # only a smoothing width here, is not fitted; the replay's step is chosen so that its
    # error does not move the motor inductance; issue 41)
    assert rep["declared_deviations"] == [], rep["declared_deviations"]


def test_piston_position_includes_the_series_cable_stretch():
    """With a series cable compliance 1/k (rad/(N m)) the pistons travel ``A Δp / k_lin``
    beyond the kinematic ``s/2 − r θ`` (a linear spring ``k_lin = k / r²`` loaded by the
    piston force ``A Δp``; Hooke), checked with the joint locked at θ = 0 while the pump
    loads the cylinder."""
    from afo_mj.circuits.codegen import build
    from afo_mj.circuits.device import CircuitDevice
    from afo_mj.circuits.library import lab_bench

    comp = 3.1e-4
    cc = build(lab_bench())
    dev = CircuitDevice(cc, timestep_s=1e-3)
    dev.P[0, cc.param_labels.index("cylinder.series_compliance")] = comp
    n = 400
    cmd = np.where(np.arange(n) > 20, 3.0, 0.0)
    log = dev.run_imposed(cmd, np.zeros(n + 1), np.zeros(n + 1))
    r = 0.04
    area = np.pi / 4 * (12e-3 ** 2 - 2e-3 ** 2)
    dp = log["chamber_a"] - log["chamber_b"]
    assert np.max(np.abs(dp)) > 5e5
    k_lin = 1.0 / (comp * r * r)
    expected = 0.5 * 0.06 + area * dp / k_lin
    np.testing.assert_allclose(log["cylinder.piston_position_m"], expected, rtol=0, atol=1e-9)


def test_first_order_sensor_lag_against_closed_forms():
    """``τ ẏ_m = y − y_m`` from equilibrium: a ramp ``y = t`` gives
    ``y_m = t − τ (1 − e^{−t/τ})`` and a sine of ω settles to amplitude ``1/√(1 + (ωτ)²)``
    (Doebelin §3.3), on uniform and non-uniform sample times."""
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.hydraulics.sensor import first_order_lag
    tau = 0.02
    t = np.linspace(0.0, 0.2, 201)
    np.testing.assert_allclose(first_order_lag(t, t, tau), t - tau * (1 - np.exp(-t / tau)),
                               rtol=0, atol=1e-15)
    tn = np.sort(np.concatenate([[0.0, 0.2], np.random.default_rng(1).uniform(0, 0.2, 300)]))
    np.testing.assert_allclose(first_order_lag(tn, tn, tau),
                               tn - tau * (1 - np.exp(-tn / tau)), rtol=0, atol=1e-15)
    w = 2 * np.pi * 20.0
    ts = np.arange(0, 2.0, 1e-4)
    ym = first_order_lag(ts, np.sin(w * ts), tau)
    amp = np.max(np.abs(ym[ts > 1.0]))
    assert amp == pytest.approx(1 / np.sqrt(1 + (w * tau) ** 2), rel=1e-3)
    np.testing.assert_array_equal(first_order_lag(t, np.sin(t), 0.0), np.sin(t))
    with pytest.raises(ParameterError, match="tau_s"):
        first_order_lag(t, t, -1.0)


def test_effect_at_a_library_bound_does_not_earn_its_name():
    """A fitted value within 1 % of its range at a bound (of the log-range for a positive
    range over decades) is flagged; a lower bound of 0 ("off") is not."""
    from afo_mj.calibration.calibrate import Calibration
    from afo_mj.calibration.effect_library import effects_for
    lib = {e.name: e for e in effects_for(["ankle_torque_nm"], described=True)}
    st = lib["stribeck_friction"]
    x = lambda *vals: np.array([v / p.scale for v, p in zip(vals, st.parameters)])  # noqa: E731
    assert Calibration.at_bound(None, st, x(40.0, 1.6e-3)) == []       # 2 mm/s-ish: fine
    hit = Calibration.at_bound(None, st, x(40.0, 1.02e-3))               # pinned at 1 mm/s
    assert len(hit) == 1 and "stribeck_velocity_m_s" in hit[0]
    assert Calibration.at_bound(None, st, x(499.0, 0.01))                # force at 500 N
    leak = lib["piston_leakage"]
    assert Calibration.at_bound(None, leak, np.array([0.0])) == []       # off is allowed


def test_sensor_lag_estimate_recovers_a_known_shift():
    """A measured channel that is the model's chirp read 3.4 samples (3.4 ms) late, plus
    noise: the baseline's lag estimate finds +3.4 ms; an aligned channel gives 0."""
    from types import SimpleNamespace

    from afo_mj.calibration.calibrate import Calibration
    fs = 1000.0
    t = np.arange(20000) / fs
    y = np.sin(2 * np.pi * (0.5 * t + 0.3 * t * t))
    late = np.sin(2 * np.pi * (0.5 * (t - 3.4e-3) + 0.3 * (t - 3.4e-3) ** 2))
    rng = np.random.default_rng(0)
    fake = SimpleNamespace(t=t, fs_hz=fs, options=SimpleNamespace(settle_s=0.3),
                           outputs=["a", "b"],
                           meas={"a": late + 0.05 * rng.normal(size=t.size),
                                 "b": y + 0.05 * rng.normal(size=t.size)})
    lags = Calibration.sensor_lags(fake, {"a": y, "b": y})
    assert lags["a"] == pytest.approx(3.4e-3, abs=2e-4)
    assert lags["b"] == pytest.approx(0.0, abs=2e-4)


def _deviation_fake(n=3000, seed=0):
    """Sensitivity columns with a known geometry (whitened by unit weights): the oil's bulk
    modulus ``b``; a cable compliance whose column is ``−b`` plus 10 % of an orthogonal
    direction (cos = −0.995: raising the compliance acts like lowering the modulus); a hose
    wall effect ``−b`` plus 40 % of another (cos ≈ −0.93 with b, +0.93 with the lowered b:
    below 0.95); a pump leakage orthogonal to all."""
    from types import SimpleNamespace
    rng = np.random.default_rng(seed)
    b, u, v, o = (rng.normal(size=n) for _ in range(4))
    for x in (u, v, o):
        x -= (x @ b) / (b @ b) * b
    u *= np.linalg.norm(b) / np.linalg.norm(u)
    v *= np.linalg.norm(b) / np.linalg.norm(v)
    o *= np.linalg.norm(b) / np.linalg.norm(o)
    cable = -b + 0.1 * u
    wall = -b + 0.4 * v
    eff = lambda name: SimpleNamespace(name=name, parameters=(  # noqa: E731
        SimpleNamespace(lo=0.0),))
    return SimpleNamespace(
        row_weights=np.ones(n),
        screen_columns={"fluid.liquid_bulk_modulus_pa": b,
                        "cylinder.series_compliance_rad_per_nm": cable,
                        "pump.slip_coefficient": o},
        rank_columns={"declared": {}, "effects": {"hose_wall_compliance": 3.0 * wall,
                                                  "pump_leakage": o,
                                                  "entrained_air": 0.5 * (-b + 0.05 * u)}},
        library=[eff("hose_wall_compliance"), eff("pump_leakage"), eff("entrained_air")])


def test_a_softened_oil_lists_the_cable_spring_by_sensitivity():
    """Issue 41 item 2: a bulk modulus fitted below its tolerance lists what points the same
    way in the whitened sensitivities (cosine ≥ 0.95), from the columns alone: the cable
    compliance *raised* (cos 0.995) and entrained air (an effect switched on, cos 0.999), not
    the hose wall at cos 0.93 nor the orthogonal pump slip or leakage; the modulus raised
    instead lists nothing (the effects act one way only)."""
    from afo_mj.calibration.calibrate import Calibration
    fake = _deviation_fake()
    low = Calibration.equivalents(fake, "fluid.liquid_bulk_modulus_pa", -0.48)
    assert [(q["name"], q["direction"]) for q in low] == [
        ("entrained_air", ""), ("cylinder.series_compliance_rad_per_nm", "raised")]
    assert low[1]["similarity"] == pytest.approx(1 / np.sqrt(1.01), rel=1e-9)
    high = Calibration.equivalents(fake, "fluid.liquid_bulk_modulus_pa", +0.48)
    assert [(q["name"], q["direction"]) for q in high] == [
        ("cylinder.series_compliance_rad_per_nm", "lowered")]
    # a softer cable fitted as the cable itself lists the oil lowered among its equivalents
    cab = Calibration.equivalents(fake, "cylinder.series_compliance_rad_per_nm", +3.9)
    assert ("fluid.liquid_bulk_modulus_pa", "lowered") in [(q["name"], q["direction"])
                                                            for q in cab]


def test_declared_deviation_beyond_tolerance_and_3_se_only():
    """A described value beyond its tolerance by more than 3 SE is listed with its
    equivalents; within tolerance, or beyond it but within 3 SE, it is not."""
    from types import SimpleNamespace

    from afo_mj.calibration.calibrate import Calibration
    from afo_mj.calibration.effect_library import DeclaredParameter as D
    fake = _deviation_fake()
    names = ["fluid.liquid_bulk_modulus_pa", "pump.slip_coefficient",
             "cylinder.series_compliance_rad_per_nm"]
    fake.declared = [D(n, "-", (n,), 0.1, 10.0, tolerance=t, path=n, value=v)
                     for n, t, v in zip(names, (0.3, 1.0, 0.3), (1.6e9, 1e-7, 5.4e-4))]
    fake.declared_labels = [d.labels for d in fake.declared]
    fake.declared_value = lambda d, labels: d.value
    fake.equivalents = lambda name, change: Calibration.equivalents(fake, name, change)
    m = SimpleNamespace(x=np.array([0.52, 1.9, 1.5]))
    out = Calibration.declared_deviations(fake, m, {"sd": np.array([0.01, 0.05, 0.2])})
    assert [d["parameter"] for d in out] == ["fluid.liquid_bulk_modulus_pa"]
    assert out[0]["fitted"] == pytest.approx(0.52 * 1.6e9)
    assert out[0]["equivalent_to"][1].startswith(
        "cylinder.series_compliance_rad_per_nm (declared value raised, similarity 1.00)")


def test_a_parameter_held_at_its_bound_leaves_the_covariance():
    """Gauss–Newton covariance with a parameter pinned at an active bound (a declared value at
    its datasheet tolerance in a plausibility refit): two nearly collinear columns are
    unidentifiable together (correlation ≈ 1), but with the first held the second's standard
    error is the one-parameter closed form ``s/‖j₂‖`` (s² = SSE/(n − 1)) and its correlation 0."""
    from afo_mj.calibration.calibration_model import CalibrationModel, _Model
    rng = np.random.default_rng(3)
    n = 500
    j1 = rng.normal(size=n)
    j2 = j1 + 1e-4 * rng.normal(size=n)
    m = _Model([], np.array([1.0, 2.0]), sse=4.0, jac=np.column_stack([j1, j2]))
    both = CalibrationModel.identifiability(None, m)
    assert abs(both["correlation"][0, 1]) > 0.999
    held = CalibrationModel.identifiability(None, m, held=[0])
    s = np.sqrt(4.0 / (n - 1))
    assert held["sd"][1] == pytest.approx(s / np.linalg.norm(j2), rel=1e-9)
    assert held["relative_se"][1] == pytest.approx(s / np.linalg.norm(j2) / 2.0, rel=1e-9)
    assert held["sd"][0] == 0.0 and held["correlation"][0, 1] == 0.0
    assert not held["rank_deficient"] and held["held"] == [0]


# ---------------------------------------------------------------- judged against the noise
def _two_channel_residual(n=4000, k=3.0, seed=5):
    """Training residuals (NRMSE units) of two channels: a precise one (noise floor 0.001)
    carrying a structure ``k`` times its floor (RMS) on top of its noise, and a noisy one
    (floor 0.015) that is noise alone; the declared sensitivity ``J`` an offset on the noisy
    channel, the candidate's change ``d`` the structure itself."""
    rng = np.random.default_rng(seed)
    f1, f2 = 0.001, 0.015
    t = np.linspace(0.0, 1.0, n)
    s = np.sin(2 * np.pi * 3 * t)
    s *= k * f1 / np.sqrt(np.mean(s ** 2))
    r = np.concatenate([s + rng.normal(0.0, f1, n), rng.normal(0.0, f2, n)])
    J = np.concatenate([np.zeros(n), np.ones(n)])[:, None]
    d = np.concatenate([s, np.zeros(n)])
    w = np.concatenate([np.full(n, 1 / f1), np.full(n, 1 / f2)])
    return J, d, r, w


def _lm_fraction(J, d, r):
    """Closed form of the score test's fraction for one column: with ``r`` and ``d`` made
    orthogonal to ``J`` (Gram–Schmidt), ``(d⊥·r⊥)² / (|d⊥|² |r|²)``."""
    P = J @ np.linalg.solve(J.T @ J, J.T)
    rp, dp = r - P @ r, d - P @ d
    return float((dp @ rp) ** 2 / ((dp @ dp) * (r @ r)))


def test_an_effect_on_a_precise_channel_scores_in_noise_units():
    """Rig 2's viscosity drift shows only on the 14-bit angle, whose floor is a tenth of the
    other channels'. In NRMSE units its share of the residual is small (here ~9/235 ≈ 0.04,
    under the described rig's refit gate of 0.05, as the drift's 0.041); in noise units it is
    the structure's excess over the noise (~9/11 ≈ 0.82). The score takes the larger; without
    noise weights (a preset) it is the NRMSE one. A change that must enter with the wrong
    sign scores 0 in both."""
    from afo_mj.calibration.calibrate import _score, _ScoreBase
    J, d, r, w = _two_channel_residual()
    nrmse = _lm_fraction(J, d, r)
    noise = _lm_fraction(J * w[:, None], d * w, r * w)
    assert nrmse == pytest.approx(9 / 235, rel=0.1) and nrmse < 0.05
    assert noise == pytest.approx(9 / 11, rel=0.05)
    sc, coef = _score(_ScoreBase(J, r, w), d[:, None], signed=True)
    assert sc == pytest.approx(noise, rel=1e-9)
    assert coef[-1] == pytest.approx(1.0, rel=0.02)       # the structure at its own size
    sc0, _ = _score(_ScoreBase(J, r), d[:, None], signed=True)
    assert sc0 == pytest.approx(nrmse, rel=1e-9)
    assert _score(_ScoreBase(J, r, w), -d[:, None], signed=True)[0] == 0.0


#: rig 2's noise floors (held-out NRMSE of its sensor noise, 20 s record)
_RIG2_FLOOR = {"ankle_angle_rad": 0.001376, "ankle_torque_nm": 0.01661,
               "chamber_a_pa": 0.01438, "chamber_b_pa": 0.01424, "motor_current_a": 0.01401,
               "motor_speed_rad_s": 0.01790}


def _judge(before_ratio, after_ratio, generic_noise_drop=0.0):
    """``Calibration.judge_refit`` of a one-parameter candidate on a described rig whose
    held-out errors are ``before_ratio``/``after_ratio`` times rig 2's floors, with a BIC
    fall of 3000 and a 2 % standard error (the declared values are not in the fake)."""
    from types import SimpleNamespace

    from afo_mj.calibration.calibrate import Calibration, CalibrationOptions
    from afo_mj.calibration.calibration_model import CalibrationModel, _Model
    from afo_mj.calibration.effect_library import effects_for

    chans = list(_RIG2_FLOOR)

    def held(ratio):
        err = {c: q * _RIG2_FLOOR[c] for c, q in zip(chans, ratio)}
        err["overall"] = float(np.sqrt(np.mean([err[c] ** 2 for c in chans])))
        return err

    fake = SimpleNamespace(options=CalibrationOptions(), declared=(), described=True,
                           outputs=chans, noise_floor=lambda: dict(_RIG2_FLOOR))
    fake.error_in_noise_units = lambda err: CalibrationModel.error_in_noise_units(fake, err)
    fake.information = lambda m: {"bic": -3000.0 if m.effects else 0.0, "aic": 0.0}
    fake.identifiability = lambda m, held=(): {"relative_se": np.array([0.02]),
                                               "correlation": np.eye(1),
                                               "rank_deficient": False}
    fake.at_bound = lambda e, x: []
    fake.generic_correction = lambda m, n: {
        "channel": "ankle_angle_rad", "held_out_drop": 0.004, "parameters": n,
        "noise_units_channel": "ankle_angle_rad",
        "held_out_drop_noise_units": generic_noise_drop}
    fake.physical = lambda effects, x: {}
    drift = {e.name: e for e in effects_for(chans, described=True)}["viscosity_drift"]
    current = _Model([], np.zeros(0), held_out=held(before_ratio))
    m = _Model([drift], np.array([1.4]), held_out=held(after_ratio))
    rec, _ = Calibration.judge_refit(fake, current, m, drift, 0.5, 1, {"bic": 0.0, "aic": 0.0})
    return rec


def test_a_refit_to_the_noise_floor_pays_in_noise_units():
    """The drift refit measured on rig 2 (angle 4.14× → 1.04× its floor, the others ~1.05×
    → ~1.0×) cuts the overall NRMSE by only 5.6 % (under min_error_drop 10 %: the other
    channels, at their floor, dominate it) but the error in noise units by 48 %
    (√(mean ratio²): 1.94 → 1.00), both by hand here: it pays, in noise units. A clean
    record (every channel within 1.12× its floor) cannot gain 10 % in noise units even with
    every channel brought to 0.98×; and a gain on one channel that does as well in noise
    units leaves the candidate unnamed."""
    before = (4.14, 1.06, 1.05, 1.03, 1.08, 0.99)
    after = (1.04, 1.01, 0.99, 0.98, 1.01, 0.98)
    f = np.array(list(_RIG2_FLOOR.values()))
    by_hand = 1 - np.linalg.norm(np.multiply(after, f)) / np.linalg.norm(np.multiply(before, f))
    in_noise = 1 - np.linalg.norm(after) / np.linalg.norm(before)
    assert by_hand == pytest.approx(0.056, abs=0.002) and in_noise == pytest.approx(0.484,
                                                                                   abs=0.002)
    rec = _judge(before, after)
    assert rec["held_out_drop"] == pytest.approx(by_hand, rel=1e-9)
    assert rec["held_out_drop_noise_units"] == pytest.approx(in_noise, rel=1e-9)
    assert rec["pays"] and rec["pays_in"] == ["noise_units"]
    clean = _judge((1.12, 1.05, 1.02, 1.0, 1.03, 1.01), (0.98,) * 6)
    assert clean["held_out_drop_noise_units"] < 0.10 and not clean["pays"]
    generic = _judge(before, after, generic_noise_drop=0.5)
    assert not generic["pays"] and generic["pays_in"] == []


def test_step_correction_columns_are_replayed_once_per_parameter():
    """The fits' Jacobian correction ``J_f − J_c`` (CalibrationModel.step_correction): a
    parameter's fine-step column is replayed at the first fit that holds it, kept, and
    reused by later fits; a new effect's parameter costs only its own fine column. The
    correction is checked against hand-computed linear columns (J_f = (1+h) a_j, J_c = a_j
    at the 0.5 ms and 62.5 µs steps: J_f − J_c = h a_j)."""
    from types import SimpleNamespace

    from afo_mj.calibration.calibration_model import CalibrationModel
    a = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])      # residuals × parameters
    taken = []

    def jacobian(effects, x, lo, hi, columns=None):
        cols = range(x.size) if columns is None else columns
        taken.extend((fake.replay.max_step_s, j) for j in cols)
        J = np.full((2, x.size), np.nan)
        for j in cols:
            J[:, j] = a[:, j] * (1.0 + 0.1 * (fake.replay.max_step_s < 1e-4))
        return J, np.ones(x.size)

    fake = SimpleNamespace(replay=SimpleNamespace(max_step_s=6.25e-5), sensitivity_step_s=5e-4,
                           _step_corrections={}, jacobian=jacobian)
    jc = a.copy()
    got = CalibrationModel.step_correction(fake, [], ["k", "m"], np.ones(2), None, None,
                                           jc[:, :2])
    assert np.allclose(got, 0.1 * a[:, :2])
    assert taken == [(6.25e-5, 0), (6.25e-5, 1)]
    taken.clear()
    # a later fit with one more parameter: only that column is replayed at the fine step
    got = CalibrationModel.step_correction(fake, [], ["k", "m", "e.p"], np.ones(3), None,
                                           None, jc)
    assert np.allclose(got, 0.1 * a)
    assert taken == [(6.25e-5, 2)]


def test_a_refit_that_trades_precise_channels_for_coarse_ones_does_not_pay():
    """The fit weighs the channels by their spread, the noise units by their noise: a refit
    can cut the overall NRMSE by trading the angle (the most precise channel) for the torque.
    Torque 3× → 2× its floor with the angle 1× → 6× cuts the NRMSE by more than 10 % and
    worsens the error in noise units by more than 10 % (both by hand): it does not pay, and
    says why; the same torque gain with the angle kept pays."""
    f = np.array(list(_RIG2_FLOOR.values()))
    before = (1.0, 3.0, 1.0, 1.0, 1.0, 1.0)
    traded = (6.0, 2.0, 1.0, 1.0, 1.0, 1.0)
    kept = (1.0, 2.0, 1.0, 1.0, 1.0, 1.0)
    nrmse = 1 - np.linalg.norm(np.multiply(traded, f)) / np.linalg.norm(np.multiply(before, f))
    noise = 1 - np.linalg.norm(traded) / np.linalg.norm(before)
    assert nrmse >= 0.10 and noise <= -0.10
    rec = _judge(before, traded)
    assert rec["held_out_drop"] == pytest.approx(nrmse, rel=1e-9)
    assert rec["pays_in"] == ["nrmse"] and rec["worsened_in"] == ["noise_units"]
    assert not rec["pays"]
    from afo_mj.calibration.calibrate import _refit_line
    assert "worse in noise units" in _refit_line(rec)
    ok = _judge(before, kept)
    assert ok["pays"] and ok["worsened_in"] == []


def test_no_plausibility_round_on_a_model_that_still_misses_the_record():
    """A model whose declared values sit beyond their tolerance goes to the plausibility
    round only when it explains the record (every channel within baseline_noise_multiple ×
    its floor): at 1.9× the floor it does, at 2.1× (or 66×, rig 2's brushes) it does not,
    and the search ends without the round."""
    from types import SimpleNamespace

    from afo_mj.calibration.calibrate import Calibration, CalibrationOptions
    from afo_mj.calibration.calibration_model import _Model

    chans = list(_RIG2_FLOOR)
    calls = []
    for ratio, goes in ((1.9, True), (2.1, False), (66.0, False)):
        fake = SimpleNamespace(options=CalibrationOptions(), described=True, outputs=chans,
                               noise_floor=lambda: dict(_RIG2_FLOOR), candidates=[object()],
                               screen_columns=[0], beyond_tolerance=lambda m: ["fluid.bulk"])
        fake.explains = lambda m: Calibration.explains(fake, m)
        fake._within_floor = lambda m, k: Calibration._within_floor(fake, m, k)
        fake.search_round = lambda s, pool: None
        fake.plausibility_round = lambda s, pool: calls.append(ratio)
        start = _Model([], np.ones(1), held_out={c: ratio * v for c, v in _RIG2_FLOOR.items()})
        assert Calibration.explains(fake, start) is goes
        Calibration.search_effects(fake, start, [])
        assert (ratio in calls) is goes
