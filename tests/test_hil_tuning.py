"""In-silico human-in-the-loop tuning (afo_mj.studies.hil_tuning, tools/hil_tuning.py): the
profile's scaled coordinates and bounds against hand-computed values, the joint vector's
split, the refusals, the Zhang timing reaching the ideal device, the joint search resumed
against an uninterrupted one, and one tiny real run of the three arms through the tool."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from afo_mj.control.assistance import zhang_profile
from afo_mj.experiments import muscle_assistance as ma
from afo_mj.gait import reflex_law as rl
from afo_mj.gait.muscle_walk import reflex_params
from afo_mj.studies import hil_tuning as hil
from afo_mj.studies.adaptation import AdaptationProtocol

TOOLS = Path(__file__).resolve().parents[1] / "tools"
DATA = Path(__file__).resolve().parents[1] / "afo_mj" / "data" / "adapted"


def test_profile_coordinates_round_trip_and_clip_by_hand():
    b = hil.ProfileBounds()
    # the generic profile (0.5 N·m/kg, 52.9 / 26.2 / 9.8 %) in the default box
    # (0–0.6, 40–65, 10–40, 5–25): worked by hand
    u = b.to_coords(hil.GENERIC)
    assert u == pytest.approx([0.5 / 0.6, 12.9 / 25.0, 16.2 / 30.0, 4.8 / 20.0], abs=1e-12)
    back, violation = b.from_coords(u)
    assert violation == 0.0
    assert back.values == pytest.approx([0.5, 52.9, 26.2, 9.8], abs=1e-12)
    # outside the box: clipped to the bound walked, the squared distance reported
    s, violation = b.from_coords([1.2, -0.1, 0.5, 0.5])
    assert s.values == pytest.approx([0.6, 40.0, 25.0, 15.0], abs=1e-12)
    assert violation == pytest.approx(0.2 ** 2 + 0.1 ** 2, abs=1e-12)
    with pytest.raises(ValueError, match="4 finite numbers"):
        b.from_coords([0.5, 0.5, math.nan, 0.5])


def test_joint_vector_splits_into_reflexes_and_profile():
    b = hil.ProfileBounds()
    z = np.linspace(-0.3, 0.3, rl.N_P)
    x = hil.joint_vector(z, [0.0, 1.0, 0.5, 0.25])
    assert x.shape == (rl.N_P + 4,)
    base = reflex_params()
    params, s, violation = hil.split_joint(x, base, b)
    assert params == pytest.approx(base * np.exp(z), rel=1e-12)
    assert s.values == pytest.approx([0.0, 65.0, 25.0, 10.0], abs=1e-12)
    assert violation == 0.0
    with pytest.raises(ValueError, match=r"allowed: \(33,\)"):
        hil.split_joint(x[:-1], base, b)
    with pytest.raises(ValueError, match="joint_vector"):
        hil.joint_vector(z[:-1], [0.5] * 4)


@pytest.mark.parametrize("kw, match", [
    ({"peak_nm_per_kg": (0.6, 0.2)}, "peak_nm_per_kg"),
    ({"peak_nm_per_kg": (0.0, 1.5)}, "peak_nm_per_kg"),
    ({"fall_time_pct": (5.0, math.inf)}, "fall_time_pct"),
    ({"rise_time_pct": (10.0,)}, "rise_time_pct"),
    ({"peak_time_pct": (30.0, 60.0)}, "earliest onset"),     # 30 − 40 < 0
    ({"peak_time_pct": (40.0, 80.0)}, "latest end"),         # 80 + 25 > 100
])
def test_bad_bounds_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        hil.ProfileBounds(**kw)


def test_protocol_refusals():
    with pytest.raises(ValueError, match="generic"):
        hil.HilProtocol(bounds=hil.ProfileBounds(peak_nm_per_kg=(0.0, 0.4)))
    with pytest.raises(ValueError, match="profile_sigma"):
        hil.HilProtocol(profile_sigma=0.0)
    with pytest.raises(ValueError, match="peak_time_pct"):
        hil.ZhangSetting(0.5, 5.0, 26.2, 9.8)        # onset before heel strike


def test_zhang_timing_reaches_the_device_and_keeps_the_old_state_key():
    a = ma.Assistance("zhang", zhang_peak_nm_per_kg=0.4, zhang_timing_pct=(45.0, 20.0, 12.0))
    dev = ma.ideal_device(a, 75.0)
    # peak 0.4 × 75 = 30 N·m plantarflexion at 45 %, nothing before 25 % or after 57 %
    x = np.linspace(0.0, 100.0, dev.profile.size)
    assert dev.profile[np.argmin(np.abs(x - 45.0))] == pytest.approx(-30.0, rel=1e-9)
    assert np.all(dev.profile[x < 24.9] == 0.0) and np.all(dev.profile[x > 57.1] == 0.0)
    assert dev.profile == pytest.approx(zhang_profile(30.0, 45.0, 20.0, 12.0))
    # at the published timing the repr (the saved searches' state key) is the one written
    # before the timing was a field
    assert repr(ma.Assistance("zhang", ramp_strides=3)) == (
        "Assistance(kind='zhang', sides=('right', 'left'), zhang_peak_nm_per_kg=0.5, "
        "spring_nm_per_rad=180.0, spring_engage_phase=0.1, spring_release_phase=0.62, "
        "spring_ratchet=False, hafo_peak_torque_nm=40.0, hafo_preset='hafo_gait', "
        "ramp_strides=3)")
    assert "zhang_timing_pct=(45.0, 20.0, 12.0)" in repr(a)
    with pytest.raises(ValueError, match="zhang_timing_pct"):
        ma.Assistance("zhang", zhang_timing_pct=(20.0, 30.0, 10.0))


def _tiny(generations):
    return hil.HilProtocol(adaptation=AdaptationProtocol(
        restarts=1, generations=generations, popsize=4, search_walk_s=4.0, score_walk_s=4.0,
        settle_s=1.0, window=1))


def test_joint_search_resumed_equals_uninterrupted(tmp_path):
    """Two generations in one run and one + one in two runs: the same history, best and
    profile (the state is the optimiser's whole state); other settings refused."""
    start = hil.load_reflex_set(DATA / "zhang.json")
    obj = hil.zhang_objective(_tiny(1))
    whole = hil.joint_search(tmp_path / "a", obj, start, _tiny(2), seed=3, workers=1)
    hil.joint_search(tmp_path / "b", obj, start, _tiny(1), seed=3, workers=1)
    resumed = hil.joint_search(tmp_path / "b", obj, start, _tiny(2), seed=3, workers=1)
    assert len(resumed["history"]) == 2
    for h0, h1 in zip(whole["history"], resumed["history"]):
        assert h0["best"] == h1["best"] and h0["mean_profile"] == h1["mean_profile"]
    assert resumed["profile"] == whole["profile"]
    assert resumed["parameters"] == whole["parameters"]
    assert hil.ProfileBounds().contains(hil.ZhangSetting(**resumed["profile"]))
    other = hil.HilProtocol(adaptation=_tiny(2).adaptation, profile_sigma=0.2)
    with pytest.raises(ValueError, match="other settings"):
        hil.joint_search(tmp_path / "b", obj, start, other, seed=3, workers=1)


def test_tiny_experiment_through_the_tool(tmp_path, capsys):
    """1 restart × 2 generations × 4 walks of 4 s per arm: the document reads back, the tuned
    rate is the one of its set and profile walked again here, the paired change is worked
    from the arms' rates; a rerun continues without a walk more."""
    sys.path.insert(0, str(TOOLS))
    import hil_tuning as tool
    from afo_mj.experiments.muscle_assistance import assistance_summary, assistance_walk
    out = tmp_path / "hil"
    argv = ["--out", str(out), "--restarts", "1", "--generations", "2", "--popsize", "4",
            "--workers", "1"]
    # the tool's walks are the protocol's defaults (16 s); the tiny run sets shorter ones
    res = hil.tune_zhang(out, _tiny(2), workers=1)
    assert res.walks == 3 * 2 * 4
    doc = hil.HilTuningResult.from_json(json.loads((out / "hil_tuning.json").read_text()))
    assert doc.to_json() == res.to_json()
    t = res.tuned[0]
    s = hil.ZhangSetting(t.peak_nm_per_kg, t.peak_time_pct, t.rise_time_pct, t.fall_time_pct)
    assert hil.ProfileBounds().contains(s)
    walk, dev = assistance_walk(s.assistance(ma.Assistance("zhang", ramp_strides=3)), None,
                                hil.load_reflex_set(out / "tuned" / "restart0"
                                                    / "reflex_params.json"), 4.0)
    summ = assistance_summary(walk, 1.0, dev)
    want = None if summ["fell_s"] is not None else summ.get("net_metabolic_w_per_kg")
    assert t.net_metabolic_w_per_kg == (None if want is None else pytest.approx(want,
                                                                                 rel=1e-12))
    g = res.generic.restarts[0].net_metabolic_w_per_kg
    if g is not None and want is not None:
        assert res.tuned_vs_generic["paired"][0] == pytest.approx(100 * (want / g - 1))
    again = hil.tune_zhang(out, _tiny(2), workers=1)
    assert again.walks == res.walks and again.tuned[0].search_cost == t.search_cost
    # the tool refuses a folder of other settings (exit 2, named)
    assert tool.main(argv) == 2
    assert "holds an experiment with" in capsys.readouterr().err


# --------------------------------------------------------------------------- the HAFO
def test_hafo_protocol_refusals():
    with pytest.raises(ValueError, match="HilProtocol.device = 'valve'"):
        hil.HilProtocol(device="valve")
    with pytest.raises(ValueError, match="battery_weights .* with device 'zhang'"):
        hil.HilProtocol(battery_weights=(0.0, 1.0))
    for bad in ((), (-1.0,), (0.5, 0.5), (math.nan,), (True,), "1"):
        with pytest.raises(ValueError, match="HilProtocol.battery_weights"):
            hil.HilProtocol(device="hafo", battery_weights=bad)
    p = hil.HilProtocol(device="hafo", battery_weights=(0, 0.25))
    assert p.battery_weights == (0.0, 0.25) and p.generic == hil.GENERIC_HAFO
    assert p.fixed()["device"] == "hafo" and "device" not in hil.HilProtocol().fixed()
    # the HAFO commands peak × body mass: the generic one is the shipped 40 N·m
    a = hil.GENERIC_HAFO.assistance(ma.Assistance("hafo"), 75.0)
    assert a.hafo_peak_torque_nm == 40.0 and a.zhang_timing_pct == ma.ZHANG_TIMING_PCT
    assert hil.ZhangSetting(0.2, 50.0, 20.0, 10.0).assistance(
        ma.Assistance("hafo"), 80.0).hafo_peak_torque_nm == pytest.approx(16.0, abs=1e-9)
    with pytest.raises(ValueError, match="body mass"):
        hil.GENERIC_HAFO.assistance(ma.Assistance("hafo"))
    with pytest.raises(ValueError, match="allowed: 'zhang', or 'hafo'"):
        hil.GENERIC.assistance(ma.Assistance("clutched_spring"), 75.0)
    # a battery weight on the ideal torque, or one the protocol does not list, is refused
    with pytest.raises(ValueError, match="battery_weight = 1.0 with assistance.kind = 'zhang'"):
        hil.joint_cost(reflex_params(), hil.profile_objective(hil.HilProtocol()), 1.0)
    obj = hil.profile_objective(p)
    with pytest.raises(ValueError, match="allowed: one of protocol.battery_weights"):
        hil.joint_search("/nonexistent/never", obj, reflex_params(), p, seed=1,
                         battery_weight=1.0)
    with pytest.raises(ValueError, match="allowed: 'hafo'"):
        hil.joint_search("/nonexistent/never", hil.profile_objective(hil.HilProtocol()),
                         reflex_params(), p, seed=1)
    with pytest.raises(ValueError, match="no battery in its log"):
        ma.battery_use(None, ma.ideal_device(ma.Assistance("zhang"), 75.0))


def _ledger_input_j(params, duration_s):
    _walk, dev = ma.assistance_walk(ma.Assistance("hafo"), None, params, duration_s)
    return dev.ledger(0)["input_j"]


def test_battery_term_against_the_ledger_of_prefix_walks():
    """The objective's battery term on a 6 s HAFO walk against the device's own ledger: the
    walk is deterministic, so the battery energy between the first and last scored heel
    strike is the ledger's input (∫V_oc I dt, integrated in the compiled step) of a walk
    stopped at the last one less that of a walk stopped at the first; per kg and metre with
    the pelvis's distance read here. The wearer's cost is the one gait_cost gives."""
    from afo_mj.studies.gait_optimization import gait_cost
    params = hil.load_reflex_set(DATA / "hafo.json")
    p = hil.HilProtocol(device="hafo", battery_weights=(0.0, 1.0), adaptation=AdaptationProtocol(
        search_walk_s=6.0, score_walk_s=6.0, settle_s=2.0))
    obj = hil.profile_objective(p)
    assert obj.assistance.kind == "hafo" and obj.assistance.hafo_peak_torque_nm == 40.0
    c0, i0 = hil.joint_cost(params, obj, 0.0)
    c1, i1 = hil.joint_cost(params, obj, 1.0)
    assert c0 == gait_cost(params, obj)[0] == i0["wearer_cost"] == i1["wearer_cost"]
    walk, dev = ma.assistance_walk(obj.assistance, None, params, 6.0)
    hs = np.asarray(walk.record.events.heel_strikes_s[0])
    hs = hs[hs > 2.0]
    assert len(hs) >= 3
    e_ref = _ledger_input_j(params, float(hs[-1])) - _ledger_input_j(params, float(hs[0]))
    assert e_ref > 1.0      # the 40 N·m profile draws from the battery
    t, x = walk.record.time_s, walk.record.pelvis_position_m[:, 0]
    dist = float(np.interp(hs[-1], t, x) - np.interp(hs[0], t, x))
    assert i1["battery_j"] == pytest.approx(e_ref, rel=0.02)
    assert i1["battery_j_per_stride"] == pytest.approx(e_ref / (len(hs) - 1), rel=0.02)
    assert i1["electrical_power_w"] == pytest.approx(e_ref / (hs[-1] - hs[0]), rel=0.02)
    assert c1 - c0 == pytest.approx(e_ref / (75.0 * dist), rel=0.02)


def test_hafo_joint_search_keys_its_battery_weight(tmp_path):
    """A HAFO joint search (1 generation of 4 walks of 4 s) keeps its battery weight in its
    state: the folder refuses another weight, and each walk's info carries the battery."""
    start = hil.load_reflex_set(DATA / "hafo.json")
    p = hil.HilProtocol(device="hafo", battery_weights=(0.0, 0.5), adaptation=_tiny(1).adaptation)
    obj = hil.profile_objective(p)
    doc = hil.joint_search(tmp_path / "s", obj, start, p, seed=2, workers=1, battery_weight=0.5)
    assert doc["battery_weight"] == 0.5
    assert p.bounds.contains(hil.ZhangSetting(**doc["profile"]))
    if "speed_m_s" in doc["quality"]:
        assert doc["cost"] == pytest.approx(
            doc["quality"]["wearer_cost"] + 0.5 * doc["quality"]
            ["battery_cost_of_transport_j_per_kg_m"] + hil.BOUND_PENALTY
            * doc["bound_violation"], rel=1e-12)
    with pytest.raises(ValueError, match="other settings"):
        hil.joint_search(tmp_path / "s", obj, start, p, seed=2, workers=1, battery_weight=0.0)
