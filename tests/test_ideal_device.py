"""The ideal orthosis (issue 39 item 3: ``[assistance]`` — an ideal Zhang profile, a clutched
spring, the worn mass alone — on any walker from a scenario; ``afo_mj.devices.ideal``).

References, each independent of the device's own code: the Zhang et al. (2017) profile
written out here and evaluated on a gait phase recomputed here from the logged foot switch;
the clutched spring's torque recomputed from the logged angle, phase and stance; the
assistance study's own walk (:func:`afo_mj.experiments.muscle_assistance.assistance_walk`)
for the same wearer and profile; the ledger against the work integrated from the log.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from afo_mj.cli import main

ROOT = Path(__file__).resolve().parents[1]
ZHANG = ROOT / "scenarios" / "gait_muscle_ideal_zhang.toml"
SPRING = ROOT / "scenarios" / "gait_muscle_clutched_spring.toml"
HAFO = ROOT / "scenarios" / "gait_assist_hafo.toml"
SHORT = ['gait.strides=4', 'gait.analyse_strides=[2, 4]', 'device.conditions=["assist"]']


def _zhang_by_hand(phase, peak):
    """Zhang et al. 2017 at the published timing, written out: zero before 26.7 %, a
    flat-ended cubic rise to ``peak`` at 52.9 %, a flat-ended cubic fall to zero at 62.7 %;
    plantarflexion (negative). ``phase < 0`` (no stride measured): zero."""
    x = 100.0 * phase
    if phase < 0 or x < 26.7 or x > 62.7:
        return 0.0
    u = (x - 26.7) / 26.2 if x <= 52.9 else (62.7 - x) / 9.8
    return -peak * u * u * (3.0 - 2.0 * u)


def _phase_from_switch(t_start, stance, lo=0.4, hi=3.0):
    """The gait phase a foot switch gives, recomputed: heel strike = rising edge of stance,
    phase = (t − last heel strike) / mean of the last three strides within [lo, hi] s,
    clipped at 1; −1 before the first such stride."""
    out = np.full(len(t_start), -1.0)
    last, strides, was = None, [], False
    for i, (t, on) in enumerate(zip(t_start, stance)):
        if on and not was:
            if last is not None and lo <= t - last <= hi:
                strides.append(t - last)
            last = t
        was = on
        if strides and last is not None:
            out[i] = min((t - last) / np.mean(strides[-3:]), 1.0)
    return out


def _run(path, overrides=SHORT):
    from afo_mj.experiments.device_walk import run_device_scenario
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(path, overrides=list(overrides))
    cfg = device_config(sc)
    summary, results = run_device_scenario(sc, sc.load_reference(), cfg)
    return sc, cfg, summary, results


def test_delivered_torque_is_the_command_exactly_in_every_mode():
    from afo_mj.control import assistance as asst
    from afo_mj.devices.ideal import ClutchedSpring, IdealDevice
    rng = np.random.default_rng(7)
    devices = [IdealDevice(sides=("right", "left"), profile=asst.zhang_profile(40, 52.9,
                                                                               26.2, 9.8)),
               IdealDevice(sides=("left",), spring=ClutchedSpring(200.0, 0.1, 0.6)),
               IdealDevice(sides=("right",), impedance=[(1e9, 150.0, 2.0, 0.05, 0.0)])]
    for dev in devices:
        moved = 0
        for k in range(5000):
            t = k * 1e-3
            stance = np.array([(t % 1.0) < 0.6, ((t + 0.5) % 1.0) < 0.6])
            ang, vel = rng.normal(0, 0.2, 2), rng.normal(0, 2.0, 2)
            force, damping = dev.begin_step(t, ang, vel, stance)
            cmd = force.copy()
            assert np.all(damping == 0.0)
            delivered = dev.end_step(rng.normal(0, 2.0, 2))
            np.testing.assert_array_equal(delivered, cmd)
            worn = np.zeros(2, bool)
            worn[dev.side_index] = True
            assert np.all(delivered[~worn] == 0.0)
            moved += bool(np.any(cmd != 0.0))
        assert moved > 500


def test_ideal_zhang_from_the_scenario_is_the_assistance_studys_walk():
    """The scenario path (preset "ideal" → device_config → make_device → the muscle walker)
    walks bit for bit the assistance study's ideal Zhang walk (0.5 N·m/kg, both ankles,
    3-stride ramp) with the same reflex set; its torque is the Zhang profile written out here
    on the phase recomputed from the logged foot switch, once the ramp is over."""
    from afo_mj.experiments.muscle_assistance import Assistance, assistance_walk
    from afo_mj.gait.muscle_scenario import muscle_walk_duration_s
    from afo_mj.gait.muscle_walk import load_reflex_set
    from afo_mj.scenarios.walk_scenario import muscle_reflex_sets
    sc, cfg, summary, results = _run(ZHANG)
    rec, _analysis, dev = results["assist"]
    assert rec.events.fall_time_s is None
    params = load_reflex_set(muscle_reflex_sets()["adapted/zhang"])
    ref, none = assistance_walk(Assistance(kind="zhang", zhang_peak_nm_per_kg=0.5,
                                           ramp_strides=3), sc.walker, params,
                                duration_s=muscle_walk_duration_s(sc))
    assert none is None
    n = min(len(rec.time_s), len(ref.record.time_s))
    assert n > 5000
    np.testing.assert_array_equal(rec.joint_angle_rad[:n], ref.record.joint_angle_rad[:n])
    np.testing.assert_array_equal(rec.device_moment_nm[:n], ref.record.device_moment_nm[:n])
    # the device's log: delivered = commanded, = the record's device torque, both ankles
    L = dev.log.arrays()
    np.testing.assert_array_equal(L["delivered_torque_nm"], L["commanded_torque_nm"])
    m = min(len(rec.time_s), len(L["time_s"]))
    np.testing.assert_array_equal(rec.device_moment_nm[:m], L["delivered_torque_nm"][:m])
    peak = 0.5 * sc.walker.body_mass_kg
    t_start = L["time_s"][:, 0] - sc.walker.timestep_s
    for j in range(2):
        stance = L["stance"][:, j] > 0.5
        ph = _phase_from_switch(t_start, stance)
        np.testing.assert_allclose(L["phase"][:, j], ph, atol=1e-9)
        hs = np.flatnonzero(np.diff(stance.astype(int)) == 1) + 1
        full = np.zeros(len(ph), bool)
        # the ramp: (strides measured)/3; full torque from the 4th measured stride on
        full[hs[4]:] = True
        want = np.array([_zhang_by_hand(p, peak) if s else 0.0 for p, s in zip(ph, stance)])
        np.testing.assert_allclose(L["delivered_torque_nm"][full, j], want[full],
                                   atol=0.005 * peak)
        assert L["delivered_torque_nm"][full, j].min() < -0.95 * peak
    # the ledger of an ideal source: drawn = positive work, regenerated = negative work
    led = dev.ledger(0)
    p = L["mechanical_power_w"][:, 0] * sc.walker.timestep_s
    assert led["electrical_drawn_j"] == pytest.approx(p[p > 0].sum(), rel=1e-9)
    assert led["electrical_regenerated_j"] == pytest.approx(-p[p < 0].sum(), rel=1e-9)
    assert led["losses_j"] == {} and led["balance_error_rel"] == 0.0
    block = summary["device_conditions"]["assist"]
    assert block["energy"]["efficiency_total"] == pytest.approx(1.0)
    assert block["device"]["torque_tracking_rmse_nm"] == 0.0
    assert block["device"]["battery_runtime_h"] is None


def test_clutched_spring_is_minus_k_times_the_stretch_past_its_engagement_angle():
    """Recomputed from the log: in each stance the clutch engages at the first sample whose
    phase lies in [10 %, 62 %], at that sample's angle θ_e; while the phase stays ≤ 62 % the
    torque is −k·max(θ − θ_e, 0); everywhere else (swing, before engagement, past the
    release, no stride measured) it is 0."""
    sc, cfg, summary, results = _run(SPRING)
    rec, _a, dev = results["assist"]
    assert rec.events.fall_time_s is None
    k, eng, rel = 180.0, 0.10, 0.62
    assert (cfg.spring.stiffness_nm_per_rad, cfg.spring.engage_phase,
            cfg.spring.release_phase) == (k, eng, rel)
    L = dev.log.arrays()
    engaged_stances = 0
    for j in range(2):
        tau = L["delivered_torque_nm"][:, j]
        np.testing.assert_array_equal(tau, L["commanded_torque_nm"][:, j])
        ph, th = L["phase"][:, j], L["command_angle_rad"][:, j]
        stance = L["stance"][:, j] > 0.5
        want = np.zeros(len(tau))
        edges = np.flatnonzero(np.diff(np.r_[0, stance.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):            # each stance [a, b)
            window = np.flatnonzero((ph[a:b] >= eng) & (ph[a:b] <= rel)) + a
            if window.size == 0:
                continue
            theta_e = th[window[0]]
            want[window] = -k * np.maximum(th[window] - theta_e, 0.0)
            engaged_stances += 1
        np.testing.assert_allclose(tau, want, rtol=0.0, atol=1e-12)
        assert tau.min() < -5.0 and tau.max() <= 0.0
    assert engaged_stances >= 10
    # the logged engagement angle: the torque is the spring's about it while engaged
    on = L["clutch_engaged"] > 0.5
    assert on.any()
    stretch = np.maximum(L["command_angle_rad"] - L["engaged_angle_rad"], 0.0)
    np.testing.assert_array_equal(L["delivered_torque_nm"][on], -k * stretch[on])
    assert np.all(L["delivered_torque_nm"][~on] == 0.0)


def test_clutched_spring_scenario_runs_with_the_wearers_metabolic_change(tmp_path, capsys):
    out = tmp_path / "cs"
    rc = main(["run", str(SPRING), "--out", str(out), "--strides", "5",
               "--set", "gait.analyse_strides=[3, 5]"])
    text = capsys.readouterr().out
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["device_preset"] == "ideal"
    assert list(s["device_conditions"]) == ["no_device", "assist"]
    assist = s["device_conditions"]["assist"]
    assert assist["muscle"]["net_metabolic_umberger_w_per_kg"] > 0.0
    ch = s["comparison_vs_no_device"]["assist"]
    d = (assist["muscle"]["net_metabolic_umberger_w_per_kg"]
         - s["device_conditions"]["no_device"]["muscle"]["net_metabolic_umberger_w_per_kg"])
    assert ch["net_metabolic_umberger_change_w_per_kg"] == pytest.approx(d, abs=1e-12)
    assert "vs no device" in text
    assert assist["energy"]["balance_error_rel"] == 0.0
    assert (out / "device_timeseries.csv").is_file()
    # the gait figures with and without the device; no hydraulics figures for a device
    # that has no hydraulics (their signals are not in its log)
    pngs = {p.name for p in out.glob("*.png")}
    assert {"gait_conditions.png", "ankle_angle_conditions.png"} <= pngs
    assert not pngs & {"device_torque.png", "device_stride_hydraulics.png"}


def test_the_ideal_device_walks_the_torque_walker(tmp_path):
    """gait_assist_hafo with the HAFO swapped for the ideal device: the torque walker steps
    it in its compiled loop (its C entry points); delivered = commanded = the record's
    torque, the Zhang peak of 40 N·m reached, nothing delivered while transparent, and a worn
    mass at the ankle."""
    sc, cfg, summary, results = _run(HAFO, ["device.preset=ideal", "gait.strides=5",
                                            "gait.analyse_strides=[3, 5]",
                                            "device.params.mass_kg=0.5"])
    assert cfg.preset == "ideal"
    rec, analysis, dev = results["assist"]
    assert rec.events.fall_time_s is None and analysis is not None
    L = dev.log.arrays()
    np.testing.assert_array_equal(L["delivered_torque_nm"], L["commanded_torque_nm"])
    n = min(len(rec.time_s), len(L["time_s"]))
    np.testing.assert_array_equal(rec.device_moment_nm[:n, 0], L["delivered_torque_nm"][:n, 0])
    assert np.all(rec.device_moment_nm[:, 1] == 0.0)
    assert L["delivered_torque_nm"].min() == pytest.approx(-40.0, abs=0.2)
    block = summary["device_conditions"]["assist"]["device"]
    assert block["peak_torque_nm"] == pytest.approx(40.0, abs=0.2)
    assert block["mass_at_ankle_kg"] == 0.5
    assert [(w.site, w.mass_kg) for w in dev.worn_masses()] == [("ankle_axis_r", 0.5)]
    rec_t, _a, dev_t = results["transparent"]
    assert np.all(rec_t.device_moment_nm == 0.0)
    assert dev_t.ledger(0)["electrical_drawn_j"] == 0.0


@pytest.mark.parametrize("overrides, words", [
    (["device.params.mass_kg=-1"], ["mass_kg", "-1"]),
    (["device.params.min_stride_s=3.5"], ["min_stride_s", "max_stride_s"]),
    (["device.params.bore_m=0.01"], ["bore_m", "mass_kg"]),
    (["assistance.profile=\"clutched_spring\"", "device.preset=\"hafo_gait\""],
     ["clutched_spring", "ideal"]),
    (["assistance.engage_pct=70"], ["assistance.engage_pct", "70"]),
    (["assistance.release_pct=5"], ["assistance.release_pct", "30"]),
    (["assistance.engage_pct=40", "assistance.release_pct=35"],
     ["assistance.engage_pct", "release_pct"]),
    (["assistance.spring_nm_per_rad=-3"], ["assistance.spring_nm_per_rad", "-3"]),
    (["assistance.ramp_strides=1.5"], ["assistance.ramp_strides", "integer"]),
])
def test_bad_ideal_parameters_are_refused_by_name(overrides, words):
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario
    with pytest.raises(ScenarioError) as exc:
        device_config(load_scenario(SPRING, overrides=overrides))
    for w in words:
        assert w in str(exc.value), str(exc.value)


def test_spring_keys_and_ramp_are_refused_where_they_do_not_apply(tmp_path, capsys):
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario
    with pytest.raises(ScenarioError, match="assistance.spring_nm_per_rad"):
        device_config(load_scenario(ZHANG, overrides=["assistance.spring_nm_per_rad=100"]))
    with pytest.raises(ScenarioError, match="assistance.ramp_strides"):
        device_config(load_scenario(HAFO, overrides=["assistance.ramp_strides=2"]))
    # in the CLI: exit 2, one message, nothing written
    out = tmp_path / "o"
    assert main(["run", str(HAFO), "--out", str(out),
                 "--set", 'assistance.profile="clutched_spring"']) == 2
    err = capsys.readouterr().err
    assert "clutched_spring" in err and "ideal" in err
    assert not out.exists()


def test_the_device_and_its_parameter_sets_refuse_bad_values_by_name():
    from afo_mj.devices.ideal import ClutchedSpring, IdealAnkleParams, IdealDevice
    from afo_mj.hydraulics.params import ParameterError
    cases = [(lambda: IdealAnkleParams(mass_kg=11.0), "mass_kg"),
             (lambda: ClutchedSpring(engage_phase=0.5, release_phase=0.4), "engage_phase"),
             (lambda: ClutchedSpring(stiffness_nm_per_rad=-1.0), "stiffness_nm_per_rad"),
             (lambda: IdealDevice(sides=("middle",)), "device.sides"),
             (lambda: IdealDevice(profile=np.zeros(11), spring=ClutchedSpring()),
              "profile and spring"),
             (lambda: IdealDevice(ramp_strides=-1), "ramp_strides"),
             (lambda: IdealDevice(timestep_s=0.0), "timestep_s"),
             (lambda: IdealDevice().ledger(1), "ledger side index")]
    for make, word in cases:
        with pytest.raises(ParameterError, match=word):
            make()
