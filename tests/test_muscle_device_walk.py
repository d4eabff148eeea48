"""Any device on the muscle walker from a scenario (issue 39, item 3): ``[walker] model =
"muscle"`` with ``[device]`` or ``[circuit]`` runs through ``afo-mj run`` on the muscle walker,
and the summary holds the wearer's effort (net metabolic rate by Umberger 2010 and Bhargava
2004, per condition and against no device) beside the device's closed ledger.

The references are independent of the new path: the muscle walk with the HAFO written earlier
for the assistance study (:func:`afo_mj.experiments.muscle_assistance.assistance_walk`, its own
device construction and call of ``run_muscle_walk``), which the scenario's assist condition
must reproduce bit for bit over their common span; the metabolic rates recomputed here from
the walk's per-muscle rates; and the ledger's own terms.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from afo_mj.cli import main

ROOT = Path(__file__).resolve().parents[1]
HAFO = ROOT / "scenarios" / "gait_muscle_hafo.toml"
SHORT = ["--strides", "5", "--set", "gait.analyse_strides=[3, 5]"]


@pytest.fixture(scope="module")
def hafo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("muscle_hafo") / "out"
    assert main(["run", str(HAFO), "--out", str(out), *SHORT]) == 0
    return out, json.loads((out / "summary.json").read_text())


def test_the_muscle_walker_wears_the_hafo_with_its_effort_and_ledger(hafo_run, capsys):
    out, s = hafo_run
    assert s["scenario"]["walker_model"] == "muscle"
    conds = s["device_conditions"]
    assert list(conds) == ["no_device", "transparent", "assist"]
    for c, v in conds.items():
        assert not v["fell"], c
        m = v["muscle"]
        assert 1.0 < m["net_metabolic_umberger_w_per_kg"] < 10.0, c
        assert 0.5 < m["net_metabolic_bhargava_w_per_kg"] < 10.0, c
        assert set(m["muscles"]) >= {"soleus", "gastrocnemius", "tibialis_anterior"}
        if c != "no_device":
            assert abs(v["energy"]["balance_error_rel"]) <= 1e-9, c
    # the change against no device is the difference of the two blocks
    for c in ("transparent", "assist"):
        ch = s["comparison_vs_no_device"][c]
        for model in ("umberger", "bhargava"):
            key = f"net_metabolic_{model}_w_per_kg"
            d = conds[c]["muscle"][key] - conds["no_device"]["muscle"][key]
            assert ch[f"net_metabolic_{model}_change_w_per_kg"] == pytest.approx(d, abs=1e-12)
            assert ch[f"net_metabolic_{model}_change_pct"] == pytest.approx(
                100 * d / conds["no_device"]["muscle"][key], rel=1e-12)
    # the headline condition (assist) is the summary's muscle block, with its files
    assert s["muscle"] == conds["assist"]["muscle"]
    assert (out / "muscles_cycle.csv").is_file() and (out / "device_timeseries.csv").is_file()


def test_the_assist_condition_is_the_assistance_studys_hafo_walk(tmp_path):
    """The scenario path (parser → device_config → make_device → walk_muscle_scenario)
    walks exactly the walk the assistance study builds by hand for the same HAFO, wearer and
    profile, and the summary's metabolic rate is the walk's own per-muscle rates averaged
    over the analysed strides."""
    from afo_mj.experiments.device_walk import run_device_scenario
    from afo_mj.experiments.muscle_assistance import Assistance, assistance_walk
    from afo_mj.gait.muscle_walk import load_reflex_set
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario, muscle_reflex_sets

    sc = load_scenario(HAFO, overrides=["gait.strides=4", "gait.analyse_strides=[2, 4]",
                                        'device.conditions=["assist"]'])
    walks = {}
    summary, results = run_device_scenario(sc, sc.load_reference(), device_config(sc),
                                           muscle_walks=walks)
    rec = results["assist"][0]
    params = load_reflex_set(muscle_reflex_sets()["adapted/hafo"])
    ref, _dev = assistance_walk(Assistance(kind="hafo", hafo_preset="hafo_gait",
                                           hafo_peak_torque_nm=40.0), sc.walker, params,
                                duration_s=4.0)
    n = min(len(rec.time_s), len(ref.record.time_s))
    assert n > 3500
    np.testing.assert_array_equal(rec.joint_angle_rad[:n], ref.record.joint_angle_rad[:n])
    np.testing.assert_array_equal(rec.device_moment_nm[:n], ref.record.device_moment_nm[:n])
    # the metabolic figure from the per-muscle rates, over the analysed span
    walk = walks["assist"]
    t0, t1 = results["assist"][1].summary["analysed_span_s"]
    sel = (walk.record.time_s > t0) & (walk.record.time_s <= t1)
    rate = walk.metabolic_umberger_w[sel].sum(axis=(1, 2)).mean() / sc.walker.body_mass_kg
    m = summary["device_conditions"]["assist"]["muscle"]
    assert m["net_metabolic_umberger_w_per_kg"] == pytest.approx(rate, rel=0.02)


@pytest.mark.slow
def test_a_described_circuit_on_the_muscle_walker(tmp_path, capsys):
    """The spring-return circuit description worn by the muscle walker: exit 0, the wearer's
    metabolic rate per condition on the console and in the summary, the ledger closed."""
    out = tmp_path / "sr"
    rc = main(["run", str(ROOT / "scenarios" / "gait_spring_return.toml"), "--out", str(out),
               "--set", "walker.model=muscle", "--set", "walker.reflex_set=adapted/hafo",
               *SHORT])
    text = capsys.readouterr().out
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    assert "circuit" in s and s["scenario"]["walker_model"] == "muscle"
    for c, v in s["device_conditions"].items():
        assert v["muscle"]["net_metabolic_umberger_w_per_kg"] > 0.0, c
        if c != "no_device":
            assert abs(v["energy"]["balance_error_rel"]) <= 1e-9, c
    assert text.count("wearer's net metabolic rate") == len(s["device_conditions"])
    assert "vs no device" in text


def test_the_torque_walkers_controller_is_still_refused_on_the_muscle_walker(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(HAFO.read_text() + "\n[controller]\nankle_kp_nm_per_rad = 200.0\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "controller" in err and "does not apply to walker.model = 'muscle'" in err
    assert not (tmp_path / "o").exists()


def test_no_metabolic_change_is_given_against_a_fall():
    """A walk that fell (with or without the device) has no steady rate to set against the
    other's: the change is None and the note names the fall (the fall is the result)."""
    from afo_mj.experiments.device_walk import _metabolic_change
    a = {"net_metabolic_umberger_w_per_kg": 4.0, "net_metabolic_bhargava_w_per_kg": 3.0}
    b = {"net_metabolic_umberger_w_per_kg": 3.0, "net_metabolic_bhargava_w_per_kg": 2.4}
    ok = _metabolic_change(a, b)
    assert ok["net_metabolic_umberger_change_pct"] == pytest.approx(-25.0)
    assert ok["net_metabolic_bhargava_change_w_per_kg"] == pytest.approx(-0.6)
    assert "net_metabolic_change_note" not in ok
    for base_fall, cond_fall, says in ((None, 0.57, "with the device fell at t = 0.570 s"),
                                       (0.852, None, "without the device fell at t = 0.852")):
        c = _metabolic_change(a, b, base_fall, cond_fall)
        assert c["net_metabolic_umberger_change_pct"] is None
        assert c["net_metabolic_bhargava_change_w_per_kg"] is None
        assert says in c["net_metabolic_change_note"]
