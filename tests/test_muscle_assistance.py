"""Assistance on the muscle-driven walker (issue 22): the ideal Zhang torque and clutched spring
against their definitions worked here, the HAFO coupled to the muscle walker (ledger closed,
its torque the one the record holds), worn masses, the plantarflexor weakness, and the
summary's rates against the per-muscle arrays summed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from afo_mj.experiments import muscle_assistance as ma
from afo_mj.gait import reflex_law as rl
from afo_mj.gait.muscle_walk import muscle_table_scaled, run_muscle_walk
from afo_mj.human.metabolics import BASAL_W_PER_KG
from afo_mj.human.walker import WalkerParams
from afo_mj.studies.gait_optimization import GaitObjective, load_reflex_set
from importlib.resources import files

SET_125 = files("afo_mj") / "data" / "reflex_params_1.25.json"


@pytest.fixture(scope="module")
def params():
    return load_reflex_set(SET_125)


def _zhang_by_hand(phase, peak):
    """Zhang et al. 2017 with the published timing, written out here: zero before the onset
    26.7 %, a flat-ended cubic rise to ``peak`` at 52.9 %, a flat-ended cubic fall to zero at
    62.7 %; plantarflexion (negative)."""
    x = 100.0 * phase
    if x < 26.7 or x > 62.7:
        return 0.0
    if x <= 52.9:
        u = (x - 26.7) / 26.2
    else:
        u = (62.7 - x) / 9.8
    return -peak * u * u * (3.0 - 2.0 * u)


def test_ideal_zhang_torque_follows_the_profile_on_the_estimated_phase(params):
    walk, dev = ma.assistance_walk(ma.Assistance("zhang", zhang_peak_nm_per_kg=0.3),
                                   params=params, duration_s=4.0)
    assert dev is None
    r = walk.record
    peak = 0.3 * r.body_mass_kg
    tau = r.device_moment_nm
    assert tau.min() < -0.9 * peak and tau.max() <= 0.0
    # the phase estimate: time since the last right heel strike over the mean of the
    # stride durations seen so far (up to three) that lie within 0.4 … 3 s (a foot that
    # bounces at its first contact makes a shorter one), from the first such stride on
    hs = np.asarray(r.events.heel_strikes_s[0])
    assert len(hs) >= 3
    checked = 0
    for k in range(0, len(r.time_s), 7):
        t = r.time_s[k] - r.sample_period_s            # the torque was set at the step start
        past = hs[hs <= t + 1e-9]
        strides = np.diff(past)
        strides = strides[(strides >= 0.4) & (strides <= 3.0)][-3:]
        if len(strides) == 0:
            assert tau[k, 0] == 0.0
            continue
        ph = min((t - past[-1]) / strides.mean(), 1.0)
        # only while the foot switch reads stance (the last event at or before t a heel
        # strike): none in swing
        offs = [x for x in r.events.toe_offs_s[0] if x <= t + 1e-9]
        stance = not offs or offs[-1] < past[-1]
        want = _zhang_by_hand(ph, peak) if stance else 0.0
        assert tau[k, 0] == pytest.approx(want, abs=0.02 * peak)
        checked += 1
    assert checked > 30
    # the gate by itself: strides of 1 s measured, then at 40 % of a stride the torque is the
    # profile's with the foot on the ground and none with it off (an early toe off)
    dev = ma.ideal_device(ma.Assistance("zhang", zhang_peak_nm_per_kg=0.3), 75.0)

    def ideal(t, angle2, velocity2, stance2):
        return dev.begin_step(t, angle2, velocity2, stance2)[0]

    zero2 = np.zeros(2)
    for t in np.arange(0.0, 2.4, 0.01):
        ideal(t, zero2, zero2, np.array([(t % 1.0) < 0.6, False]))
    on = ideal(2.4, zero2, zero2, np.array([True, False]))[0]
    assert on == pytest.approx(_zhang_by_hand(0.4, 0.3 * 75.0), abs=0.01 * 0.3 * 75.0)
    assert on < -0.3 * 0.3 * 75.0
    assert ideal(2.41, zero2, zero2, np.array([False, False]))[0] == 0.0


def test_clutched_spring_engages_slack_and_resists_dorsiflexion_only_in_stance(params):
    """Collins et al.'s clutch: engaged once per stance with the spring slack, so within a
    stance ``θ + τ/K`` (the engagement angle) is one constant wherever the spring pulls;
    no torque past the engagement angle in plantarflexion, none in swing."""
    a = ma.Assistance("clutched_spring", spring_nm_per_rad=150.0)
    walk, _ = ma.assistance_walk(a, params=params, duration_s=10.0)
    r = walk.record
    # sample k's torque was set with the angle recorded at sample k − 1 (the step's start)
    tau = r.device_moment_nm[1:, 0]
    ang = r.joint_angle_rad[:-1, 0, 2]
    t = r.time_s[1:]
    assert tau.min() < -5.0 and tau.max() <= 0.0
    hs = np.asarray(r.events.heel_strikes_s[0])
    stances = 0
    for a_, b_ in zip(hs[:-1], hs[1:]):
        sel = (t >= a_) & (t < b_) & (tau < 0.0)
        if sel.sum() < 10:
            continue
        engaged_at = ang[sel] + tau[sel] / 150.0
        assert np.ptp(engaged_at) < 1e-9, np.ptp(engaged_at)
        stances += 1
    assert stances >= 3
    swings = 0
    for to in r.events.toe_offs_s[0]:
        nxt = [h for h in r.events.heel_strikes_s[0] if h > to]
        if nxt:
            sw = (t > to + 2e-3) & (t < nxt[0])
            assert np.all(tau[sw] == 0.0)
            swings += 1
    assert swings >= 2


def test_hafo_on_the_muscle_walker_closes_its_ledger_and_drives_the_ankle(params):
    walk, dev = ma.assistance_walk(ma.Assistance("hafo"), params=params, duration_s=2.5)
    r = walk.record
    led = dev.ledger(0)
    assert abs(led["balance_error_rel"]) < 1e-9
    assert set(led["losses_j"]) and all(v >= -1e-9 for v in led["losses_j"].values())
    # the record's device torque is the HAFO's delivered torque, on the right ankle only
    log = dev.log.arrays()
    n = min(len(r.time_s), len(log["delivered_torque_nm"]))
    np.testing.assert_array_equal(r.device_moment_nm[:n, 0], log["delivered_torque_nm"][:n, 0])
    assert np.all(r.device_moment_nm[:, 1] == 0.0)
    # its worn masses are on the body: heavier than the bare walker by the device's mass
    bare = run_muscle_walk(WalkerParams(), params, 0.01)
    assert walk.record.body_mass_kg == bare.record.body_mass_kg      # body mass is the person
    assert dev.mass_total_kg > 3.0


def test_worn_mass_condition_only_adds_mass(params):
    walk, dev = ma.assistance_walk(ma.Assistance("worn_mass"), params=params, duration_s=0.3)
    assert dev is None and np.all(walk.record.device_moment_nm == 0.0)
    plain = run_muscle_walk(WalkerParams(), params, 0.3)
    assert not np.array_equal(walk.record.qpos, plain.record.qpos)


def test_weakness_scales_the_maximum_force_of_the_named_muscles_only():
    T = rl.muscle_table(1e-3)
    W = muscle_table_scaled(1e-3, {"soleus": 0.5, "gastrocnemius": 0.5})
    for m, name in enumerate(rl.MUSCLES):
        f = 0.5 if name in ("soleus", "gastrocnemius") else 1.0
        assert W[m, rl.T_FMAX] == T[m, rl.T_FMAX] * f
        assert W[m, rl.T_MASS] == T[m, rl.T_MASS]
    with pytest.raises(ValueError, match="max_force_scale\\['calf'\\]"):
        muscle_table_scaled(1e-3, {"calf": 0.5})
    with pytest.raises(ValueError, match="allowed: 0 < factor <= 2"):
        muscle_table_scaled(1e-3, {"soleus": 0.0})


def test_weak_plantarflexors_cap_the_soleus_force(params):
    weak = run_muscle_walk(WalkerParams(), params, 2.0,
                           max_force_scale={"soleus": 0.5, "gastrocnemius": 0.5})
    i = rl.MUSCLES.index("soleus")
    fmax = rl.muscle_table(1e-3)[i, rl.T_FMAX]
    # the tendon force of a CE at full activation is bounded by F_max f_V ≤ 1.8 F_max (the
    # eccentric plateau of Geyer & Herr's f_V): halved here
    assert weak.force_n[:, :, i].max() < 1.8 * 0.5 * fmax


def test_summary_rates_against_the_arrays_summed_by_hand(params):
    walk, _ = ma.assistance_walk(ma.Assistance("none"), params=params, duration_s=8.0)
    s = ma.assistance_summary(walk, settle_s=3.0)
    r = walk.record
    hs = np.asarray(r.events.heel_strikes_s[0])
    hs = hs[hs > 3.0]
    sel = (r.time_s > hs[0]) & (r.time_s <= hs[-1])
    net = walk.metabolic_umberger_w[sel].sum(axis=(1, 2)).mean() / r.body_mass_kg
    assert s["net_metabolic_w_per_kg"] == pytest.approx(net, rel=1e-12)
    gross = walk.metabolic_rate_w("umberger")[sel].mean() / r.body_mass_kg
    assert gross - s["net_metabolic_w_per_kg"] == pytest.approx(BASAL_W_PER_KG, rel=1e-9)
    assert s["strides"] == len(hs) - 1
    assert s["net_cost_of_transport_j_per_kg_m"] == pytest.approx(
        s["net_metabolic_w_per_kg"] / s["speed_m_s"], rel=1e-9)
    bh = walk.metabolic_bhargava_w[sel].sum(axis=(1, 2)).mean() / r.body_mass_kg
    assert s["net_cost_of_transport_bhargava_j_per_kg_m"] == pytest.approx(
        bh / s["speed_m_s"], rel=1e-9)
    # push-off: the peak of the right ankle's power averaged stride by stride on the phase
    p = r.joint_moment_nm[:, 0, 2] * r.joint_velocity_rad_s[:, 0, 2]
    peaks = []
    for a, b in zip(hs[:-1], hs[1:]):
        k = (r.time_s > a) & (r.time_s <= b)
        peaks.append(np.interp(np.linspace(0, 1, 101), (r.time_s[k] - a) / (b - a), p[k]))
    assert s["ankle_peak_power_w_per_kg"] == pytest.approx(
        np.mean(peaks, axis=0).max() / r.body_mass_kg, rel=2e-3)


def test_bad_assistance_is_named():
    with pytest.raises(ValueError, match="assistance.kind = 'spring'; allowed: none"):
        ma.Assistance("spring")
    with pytest.raises(ValueError, match="assistance.sides"):
        ma.Assistance("zhang", sides=("right", "right"))
    with pytest.raises(ValueError, match="assistance.zhang_peak_nm_per_kg = 5"):
        ma.Assistance("zhang", zhang_peak_nm_per_kg=5)
    assert not math.isnan(GaitObjective(assistance=ma.Assistance("hafo")).target_speed_m_s)


def test_robust_objective_penalises_each_variant_that_falls(params):
    """The shipped 1.25 set (optimised without variants) falls with 15 % more or less body
    mass: the robust cost is its plain cost plus 50 + 10 × (12 s − time walked) for each
    variant that fell, and nothing for one that walked (the unchanged body, which must)."""
    from afo_mj.human.walker import WornMass
    from afo_mj.studies.gait_optimization import WalkVariant, gait_cost
    plain, _ = gait_cost(params, GaitObjective())
    variants = (WalkVariant("light", 0.85), WalkVariant("same", 1.0),
                WalkVariant("heavy", 1.15))
    cost, info = gait_cost(params, GaitObjective(variants=variants))
    falls = info["variant_falls_s"]
    assert falls and "same" not in falls
    assert cost == pytest.approx(plain + sum(50.0 + 10.0 * (12.0 - t) for t in falls.values()),
                                 rel=1e-12)
    # a fallen variant is the same walk as run_muscle_walk of that walker
    name, fell = sorted(falls.items())[0]
    scale = {"light": 0.85, "heavy": 1.15}[name]
    walk = run_muscle_walk(WalkerParams(body_mass_kg=75.0 * scale), params, 12.0)
    assert walk.record.events.fall_time_s == fell
    with pytest.raises(ValueError, match="body_mass_scale = 2.0"):
        WalkVariant("x", 2.0)
    # extra worn masses reach the walk
    w1, _ = ma.assistance_walk(ma.Assistance("none"), params=params, duration_s=0.3,
                               worn_masses=(WornMass("ankle_axis_r", 1.0, "w"),))
    w0, _ = ma.assistance_walk(ma.Assistance("none"), params=params, duration_s=0.3)
    assert not np.array_equal(w1.record.qpos, w0.record.qpos)


def test_muscles_scale_with_stature_by_geometric_similarity():
    from afo_mj.gait import reflex_law as rl
    T = rl.muscle_table(1e-3)
    C = muscle_table_scaled(1e-3, None, 1.2)
    s = 1.2 / 1.75
    np.testing.assert_allclose(C[:, rl.T_LOPT], s * T[:, rl.T_LOPT], rtol=1e-12)
    np.testing.assert_allclose(C[:, rl.T_FMAX], s * s * T[:, rl.T_FMAX], rtol=1e-12)
    np.testing.assert_allclose(C[:, rl.T_MASS], s ** 3 * T[:, rl.T_MASS], rtol=1e-12)
    np.testing.assert_allclose(C[:, rl.T_PATH + 2], s * T[:, rl.T_PATH + 2], rtol=1e-12)
    np.testing.assert_array_equal(C[:, rl.T_VMAX], T[:, rl.T_VMAX])
    assert np.array_equal(muscle_table_scaled(1e-3, None, 1.75), T)
    # a child walker starts balanced (every CE at its static equilibrium) and steps at 0.5 ms
    walk = run_muscle_walk(WalkerParams(body_mass_kg=25.0, height_m=1.2, timestep_s=5e-4),
                           None, 0.05)
    assert np.all(np.isfinite(walk.force_n)) and walk.record.sample_period_s == 5e-4


def test_ramp_scales_the_ideal_torque_by_the_strides_measured(params):
    """ramp_strides = 4: the torque is the unramped profile × (strides measured so far)/4,
    full from the fourth measured stride on."""
    from afo_mj.control import assistance as asst
    a0 = ma.Assistance("zhang", zhang_peak_nm_per_kg=0.2)
    a4 = ma.Assistance("zhang", zhang_peak_nm_per_kg=0.2, ramp_strides=4)
    d0, d4 = ma.ideal_device(a0, 75.0), ma.ideal_device(a4, 75.0)
    rng = np.random.default_rng(3)
    t = 0.0
    seen = set()
    for k in range(6000):
        t = k * 1e-3
        stance = np.array([(t % 1.1) < 0.65, ((t + 0.55) % 1.1) < 0.65])
        ang, vel = rng.normal(0, 0.1, 2), rng.normal(0, 1, 2)
        full = d0.begin_step(t, ang, vel, stance)[0].copy()
        ramped = d4.begin_step(t, ang, vel, stance)[0].copy()
        n = d4.phase[0, asst.PH_N]
        np.testing.assert_allclose(ramped[0], full[0] * min(1.0, n / 4), rtol=1e-12)
        if full[0] != 0.0:
            seen.add(int(n))
    assert {1, 2, 3, 4} <= seen
    with pytest.raises(ValueError, match="ramp_strides = -1"):
        ma.Assistance("zhang", ramp_strides=-1)


def test_a_diverging_condition_is_a_row_of_the_comparison(monkeypatch, params):
    """A condition whose walk diverges (FloatingPointError from the walk) comes back as a row
    with its time and the error, so that the other conditions' rows are kept."""
    def diverge(*args, **kwargs):
        raise FloatingPointError("muscle walk: the simulation diverged at t = 5.0940 s "
                                 "(MuJoCo reset its state)")
    monkeypatch.setattr(ma, "assistance_walk", diverge)
    row = ma._compare_one((ma.Assistance("zhang"), None, params, 6.0, 3.0, None))
    assert row["diverged"] is True and row["fell_s"] == 5.094
    assert "diverged at t = 5.0940 s" in row["error"] and row["strides"] == 0


ADAPTED = files("afo_mj") / "data" / "adapted"
ADAPTED_WEAK = files("afo_mj") / "data" / "adapted_weak"
FREE_SPEED = files("afo_mj") / "data" / "free_speed"


def _adapted_summary(folder, kind):
    """The shipped set re-optimised with condition ``kind`` walked 20 s with it (as recorded
    in its file: the assistance and the weakness it was optimised with)."""
    import json
    path = folder / f"{kind}.json"
    doc = json.loads(path.read_text())
    a = ma.Assistance(**{k: (tuple(v) if isinstance(v, list) else v)
                         for k, v in doc["assistance"].items()})
    walk, dev = ma.assistance_walk(a, None, load_reflex_set(path), 20.0,
                                   max_force_scale=doc.get("max_force_scale") or None)
    assert walk.record.events.fall_time_s is None, kind
    return ma.assistance_summary(walk, 3.0, dev)


@pytest.fixture(scope="module")
def adapted():
    return {k: _adapted_summary(ADAPTED, k) for k in ma.KINDS}


@pytest.mark.slow
def test_adapted_wearer_meets_each_device_as_it_acts(adapted):
    """Issue 22, each condition with a wearer re-optimised with it worn (the shipped
    ``afo_mj/data/adapted`` sets; README): the ideal Zhang torque does positive work on the
    ankle and the adapted muscles hand it more than 40 % of their positive ankle work; the
    clutched spring returns what it stores (no net work over a stride); the driven HAFO's
    ledger closes with every loss named. (The metabolic changes: the next tests.)"""
    none, zhang = adapted["none"], adapted["zhang"]
    assert zhang["ankle_device_net_work_j_per_stride"] > 5.0
    assert (zhang["ankle_muscle_positive_work_j_per_stride"]
            < 0.6 * none["ankle_muscle_positive_work_j_per_stride"])
    assert abs(adapted["clutched_spring"]["ankle_device_net_work_j_per_stride"]) < 1.0
    led = adapted["hafo"]["device_ledger"]
    assert abs(led["balance_error_rel"]) < 1e-9 and len(led["losses_j"]) >= 8
    for kind in ma.KINDS:
        assert abs(adapted[kind]["speed_m_s"] - 1.25) < 0.1, kind


SEEDS = (1, 2, 3)


@pytest.mark.slow
def test_adapted_metabolic_rate_falls_with_assistance_and_rises_with_worn_mass(adapted):
    """Issue 22, the adapted wearers searched by one protocol (``tools/muscle_adapted.py``)
    with three CMA-ES seeds, each against the control searched with its seed. In every
    search the ideal Zhang torque lowers the net metabolic rate (Umberger 2010) below the
    control's and the clutched spring's, and worn mass alone raises it (Zhang et al. 2017;
    Browning et al. 2007): effects whose range over the three seeds excludes zero (Zhang
    -7.7 … -15.6 %, worn mass +0.3 … +11.5 %, Zhang against the spring -5.9 … -13.5 %).
    The spring's own effect is not asserted: its seeds' range straddles zero (-1.8, -5.5,
    +1.5 %; README); the adaptation protocol's restarts settle its sign
    (docs/muscle_walker.md), not these single searches."""
    kinds = ("none", "worn_mass", "zhang", "clutched_spring")
    rates = []
    for seed in SEEDS:
        s = adapted if seed == 1 else {k: _adapted_summary(ADAPTED, f"{k}_seed{seed}")
                                       for k in kinds}
        rate = {k: s[k]["net_metabolic_w_per_kg"] for k in kinds}
        assert rate["zhang"] < min(rate["clutched_spring"], rate["none"]), (seed, rate)
        assert rate["none"] < rate["worn_mass"], (seed, rate)
        rates.append(rate)
    mean = {k: float(np.mean([r[k] for r in rates])) for k in kinds}
    assert mean["zhang"] < min(mean["clutched_spring"], mean["none"]), mean
    assert mean["none"] < mean["worn_mass"], mean


@pytest.mark.slow
def test_weak_plantarflexors_push_off_less_and_the_device_restores_it(adapted):
    """Issue 22: the wearer with half the plantarflexors' force (re-optimised with it, the
    shipped ``afo_mj/data/adapted_weak`` sets) holds the speed it is asked for but pushes off
    with less peak ankle power and at a higher metabolic rate than the healthy adapted
    wearer; the ideal Zhang torque gives part of the push-off back."""
    weak = {k: _adapted_summary(ADAPTED_WEAK, k) for k in ("none", "zhang")}
    healthy = adapted["none"]
    assert weak["none"]["ankle_peak_power_w_per_kg"] < 0.9 * healthy["ankle_peak_power_w_per_kg"]
    assert weak["none"]["net_metabolic_w_per_kg"] > healthy["net_metabolic_w_per_kg"]
    assert weak["zhang"]["ankle_peak_power_w_per_kg"] > weak["none"]["ankle_peak_power_w_per_kg"]


@pytest.mark.slow
def test_weak_wearer_choosing_its_speed_walks_slower_and_the_device_speeds_it_up():
    """Issue 22: with no speed target (the shipped ``afo_mj/data/free_speed`` sets, each
    optimised for the cheapest metre at near-normal kinematics from the same start, 120
    generations), the wearer with half the plantarflexors' force walks slower than the
    healthy one, with longer strides and less push-off; the ideal Zhang torque makes the weak
    wearer faster again and cheaper per metre than without it. (At 60 generations the weak
    wearer was still the faster: README.)"""
    s = {k: _adapted_summary(FREE_SPEED, k) for k in ("healthy", "weak", "weak_zhang")}
    assert s["weak"]["speed_m_s"] < 0.95 * s["healthy"]["speed_m_s"]
    assert s["weak"]["ankle_peak_power_w_per_kg"] < s["healthy"]["ankle_peak_power_w_per_kg"]
    assert s["weak_zhang"]["speed_m_s"] > s["weak"]["speed_m_s"]
    assert (s["weak_zhang"]["net_cost_of_transport_j_per_kg_m"]
            < s["weak"]["net_cost_of_transport_j_per_kg_m"])
