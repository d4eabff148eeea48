"""The gymnasium environment over the steppable walk (issue 23): gymnasium's own checker, the
torque action is Walk.step's action (bitwise), a fall terminates, the HAFO mode drives its
hydraulics and books its electrical power, the default reward worked by hand, the vector form,
and bad settings named. On a muscle scenario (issue 39 item 2) the environment steps the muscle
walker: a zero-action episode is afo-mj run's walk bit for bit, the torque action is the
stepper's action, the HAFO mode drives its hydraulics there too."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from afo_mj.experiments import walk_env as we
from afo_mj.gait.walk import Walk

ROOT = Path(__file__).resolve().parents[1]
SC = str(ROOT / "scenarios" / "walk_healthy.toml")
SHORT = ["gait.strides=2", "gait.analyse_strides=[1, 2]"]
MUSCLE = str(ROOT / "scenarios" / "walk_muscle_healthy.toml")


def test_gymnasium_env_checker():
    """gymnasium's checker passes (it only recommends a normalised action space; the
    action here is a torque in N·m, as the module docstring says)."""
    import warnings
    from gymnasium.utils.env_checker import check_env
    env = we.AnkleAssistEnv(SC, overrides=SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    assert all("symmetric and normalized space" in str(w.message) for w in caught), \
        [str(w.message) for w in caught]


def test_torque_action_is_the_walks_action():
    env = we.AnkleAssistEnv(SC, control_rate_hz=50.0, overrides=SHORT)
    obs, _ = env.reset(seed=1)
    assert obs.shape == (len(we.OBSERVATION_NAMES),)
    sc = env.scenario
    w = Walk(sc.walker, env.reference, env.cycle_time_s, sc.strides, sc.controller_params())
    rng = np.random.default_rng(0)
    for _ in range(30):
        a = rng.uniform(-30, 30, 2)
        obs, r, term, trunc, info = env.step(a)
        for _ in range(20):                  # 50 Hz control, 1 ms steps
            w.step(a)
    np.testing.assert_array_equal(env.unwrapped.walk.record().qpos, w.record().qpos)
    np.testing.assert_array_equal(obs[:6], w.joint_angles_rad.ravel())
    assert obs[-2] == pytest.approx(a[0]) and obs[-1] == pytest.approx(a[1])
    # the default reward from its terms, worked here
    last = env.last
    assert r == pytest.approx(-(last["track_rad2"] + last["effort"] + 0.1 * last["energy"]))
    mg = 75.0 * 9.81
    ph = w.phase
    ref = np.stack([env.reference.angles_rad(ph[s]) for s in range(2)])
    assert last["track_rad2"] == pytest.approx(np.mean((w.joint_angles_rad - ref) ** 2))
    tau = w.record().joint_moment_nm[-1, :, 2]
    assert last["effort"] == pytest.approx(np.sum((tau / (mg * 1.75 * 0.53)) ** 2))


def test_a_fall_terminates():
    """200 N·m of dorsiflexion on the right ankle throws the walker (at 4.4 s)."""
    env = we.AnkleAssistEnv(SC, max_torque_nm=200.0,
                            overrides=["gait.strides=6", "gait.analyse_strides=[1, 6]"])
    env.reset(seed=0)
    for _ in range(1500):
        *_, term, trunc, info = env.step(np.array([200.0, 0.0]))
        if term or trunc:
            break
    assert term and info["fell"] and not trunc


def test_hafo_mode_delivers_through_the_hydraulics():
    env = we.AnkleAssistEnv(SC, mode="hafo", overrides=SHORT)
    env.reset(seed=0)
    for _ in range(150):
        obs, r, term, trunc, info = env.step(np.array([-15.0, 0.0]))
    dev = env.device
    assert dev is not None and dev.mass_total_kg > 3.0
    # the commanded torque reached the device, and it delivered a plantarflexion torque
    assert np.all(dev.W[0, dev.k.W_CMD] == -15.0)
    assert obs[we.OBSERVATION_NAMES.index("right_ankle_device_torque_nm")] < -5.0
    assert info["energy"] > 0.0 and np.isfinite(r)
    led = dev.ledger(0)
    assert abs(led["balance_error_rel"]) < 1e-9 and led["input_j"] > 0.0
    # the device's states follow the named observation entries
    names = env.observation_names
    assert len(obs) == len(names) == len(we.OBSERVATION_NAMES) + dev.Y.size
    i = names.index("right_device.chamber_a")
    assert obs[i] == dev.Y[0, dev.cc.index("chamber_a")]
    assert env.observation_space.contains(obs)


def test_vector_form():
    envs = gym.make_vec(we.ENV_ID, num_envs=2, vectorization_mode="sync", scenario=SC,
                        overrides=SHORT)
    obs, _ = envs.reset(seed=[0, 1])
    assert obs.shape == (2, len(we.OBSERVATION_NAMES))
    obs, r, term, trunc, _ = envs.step(np.array([[0.0, 0.0], [-20.0, -20.0]]))
    assert r.shape == (2,) and not np.array_equal(obs[0], obs[1])
    envs.close()


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="mode = 'valve'"):
        we.AnkleAssistEnv(SC, mode="valve")
    with pytest.raises(ValueError, match="control_rate_hz = 300"):
        we.AnkleAssistEnv(SC, control_rate_hz=300.0)
    env = we.AnkleAssistEnv(SC, overrides=SHORT)
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(2))
    env.reset()
    with pytest.raises(ValueError, match="two finite torques"):
        env.step(np.array([np.nan, 0.0]))


@pytest.mark.slow
def test_tuning_example_beats_the_generic_profile():
    """examples/tune_assistance_env.py with 3 generations: the tuned profile's objective is
    below the generic one's, and re-evaluating the tuned profile gives its objective again
    (the episodes are deterministic). Measured with 8 generations: 3.776 -> 2.647 (-30 %)."""
    import sys
    sys.path.insert(0, str(ROOT / "examples"))
    import tune_assistance_env as ex
    out = ex.main(3)
    assert out["tuned_objective"] < out["generic_objective"] < 1e3
    assert ex.objective(np.array(out["tuned"])) == out["tuned_objective"]


# --- the muscle walker ---------------------------------------------------------------------------

def _same_muscle_walk(a, b):
    import dataclasses

    from afo_mj.gait.muscle_walk import MuscleWalk
    from afo_mj.gait.record import GaitRecord
    for cls, x, y in ((MuscleWalk, a, b), (GaitRecord, a.record, b.record)):
        for f in dataclasses.fields(cls):
            u, v = getattr(x, f.name), getattr(y, f.name)
            if isinstance(u, np.ndarray):
                assert u.shape == v.shape and np.array_equal(u, v), f.name
    assert a.record.events.heel_strikes_s == b.record.events.heel_strikes_s
    assert a.record.events.toe_offs_s == b.record.events.toe_offs_s


def test_muscle_episode_with_zero_action_is_afo_mj_runs_walk():
    """A whole episode of walk_muscle_healthy.toml with a zero action, 100 Hz: truncated (no
    fall) when afo-mj run's walk ends, and the stepped record is that walk's
    (walk_muscle_scenario, i.e. run_muscle_walk), every array equal."""
    from afo_mj.gait.muscle_scenario import walk_muscle_scenario
    env = gym.make(we.ENV_ID, scenario=MUSCLE, overrides=SHORT)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (len(we.OBSERVATION_NAMES),)
    n = 0
    while True:
        obs, r, term, trunc, info = env.step(np.zeros(2))
        n += 1
        assert env.observation_space.contains(obs) and np.isfinite(r)
        if term or trunc:
            break
    assert trunc and not term and not info["fell"]
    u = env.unwrapped
    ref = walk_muscle_scenario(u.scenario)
    steps = len(ref.record.time_s)
    assert n == math.ceil(steps / 10) and n > 300
    got = u.walk.record()
    _same_muscle_walk(got, ref)
    assert len(ref.record.events.heel_strikes_s[0]) >= 3
    # the last observation is the record's last sample
    r_ = ref.record
    assert np.array_equal(obs[:6], r_.joint_angle_rad[-1].ravel())
    assert np.array_equal(obs[6:12], r_.joint_velocity_rad_s[-1].ravel())
    assert np.array_equal(obs[12:14], r_.gait_phase[-1])
    assert obs[we.OBSERVATION_NAMES.index("pelvis_speed_m_s")] == r_.pelvis_velocity_m_s[-1, 0]
    assert not obs[-2:].any()


def test_muscle_torque_action_is_the_steppers_action():
    """The action on the muscle walker is MuscleWalkStepper.step's action, held over the
    control period; the reward's terms from the stepper's state."""
    from afo_mj.gait.muscle_scenario import muscle_scenario_stepper
    env = we.AnkleAssistEnv(MUSCLE, control_rate_hz=50.0, overrides=SHORT)
    env.reset(seed=1)
    w = muscle_scenario_stepper(env.scenario)
    rng = np.random.default_rng(0)
    # (the reflex walker is fragile so early in the walk: these torques throw it, which
    # terminates the episode at the stepper's fall)
    for _ in range(100):
        a = rng.uniform(-3, 3, 2)
        obs, r, term, trunc, info = env.step(a)
        before = w.steps
        for _ in range(20):                  # 50 Hz control, 1 ms steps
            if w.done:
                break
            w.step(a)
        if term or trunc:
            break
    assert term and w.fallen and info["fell"] and w.done and not trunc
    n_last = w.steps - before
    assert 1 <= n_last <= 20
    rec = w.record().record
    np.testing.assert_array_equal(env.walk.record().record.qpos, rec.qpos)
    np.testing.assert_array_equal(obs[:6], w.joint_angles_rad.ravel())
    assert np.array_equal(obs[-2:], a) and np.array_equal(rec.device_moment_nm[-1], a)
    last = env.last
    assert r == pytest.approx(-(last["track_rad2"] + last["effort"] + 0.1 * last["energy"]))
    ph = w.phase
    ref = np.stack([env.reference.angles_rad(ph[s]) for s in range(2)])
    assert last["track_rad2"] == pytest.approx(np.mean((w.joint_angles_rad - ref) ** 2))
    mg = 75.0 * 9.81
    tau = rec.joint_moment_nm[-1, :, 2]
    assert last["effort"] == pytest.approx(np.sum((tau / (mg * 1.75 * 0.53)) ** 2))
    # the action's positive power at each step's end velocity, over the last control period,
    # per m g v (v: the pelvis speed at the period's start, at least 0.3 m/s)
    power = np.sum(np.maximum(a * rec.joint_velocity_rad_s[-n_last:, :, 2], 0.0), axis=1)
    speed = max(rec.pelvis_velocity_m_s[-n_last - 1, 0], 0.3)
    assert last["energy"] == pytest.approx(power.mean() / (mg * speed))


def test_muscle_env_passes_gymnasiums_checker():
    import warnings
    from gymnasium.utils.env_checker import check_env
    env = we.AnkleAssistEnv(MUSCLE, overrides=SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    assert all("symmetric and normalized space" in str(w.message) for w in caught), \
        [str(w.message) for w in caught]


def test_hafo_mode_on_the_muscle_walker():
    """The HAFO drives the muscle walker's ankles: the command reaches it, it delivers about
    the commanded plantarflexion torque, its ledger closes and its worn masses are on the
    body. (The reflex walker is fragile under it: with this constant command it falls at
    about 1.6 s, with a zero command at about 0.4 s; 1.2 s are stepped here.)"""
    env = we.AnkleAssistEnv(MUSCLE, mode="hafo", overrides=SHORT)
    env.reset(seed=0)
    delivered = []
    for _ in range(120):
        obs, r, term, trunc, info = env.step(np.array([-15.0, 0.0]))
        delivered.append(obs[we.OBSERVATION_NAMES.index("right_ankle_device_torque_nm")])
    assert not term
    dev = env.device
    assert np.all(dev.W[0, dev.k.W_CMD] == -15.0)
    assert np.median(delivered) < -5.0
    assert info["energy"] > 0.0 and np.isfinite(r)
    led = dev.ledger(0)
    assert abs(led["balance_error_rel"]) < 1e-9 and led["input_j"] > 0.0
    assert env.observation_space.contains(obs)
    plain = we.AnkleAssistEnv(MUSCLE, overrides=SHORT)
    plain.reset()
    assert env.walk.phys.body_mass_kg == pytest.approx(plain.walk.phys.body_mass_kg
                                                       + dev.mass_total_kg)


def test_a_walker_model_without_an_entry_is_named(monkeypatch):
    from afo_mj.gait import walkers
    monkeypatch.setattr(walkers, "WALKER_MODELS", {"torque": walkers.WALKER_MODELS["torque"]})
    with pytest.raises(ValueError, match="walker.model = 'muscle'; allowed in .*'torque'"):
        we.AnkleAssistEnv(MUSCLE, overrides=SHORT)
