"""The steppable walk (issue 23): Walk stepped by hand to its end is run_walk's record bit for
bit (no device, and a coupled HAFO), its accessors read MuJoCo's state, an action is an ankle
torque the physics feels and the record books, reset starts over, a finished walk refuses to
step."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from afo_mj.gait.walk import Walk, run_walk
from afo_mj.scenarios.walk_scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def scenario():
    sc = load_scenario(ROOT / "scenarios" / "walk_healthy.toml",
                       overrides=["gait.strides=3", "gait.analyse_strides=[2, 3]"])
    ref = sc.load_reference()
    return sc, ref, sc.cycle_time_s(ref)


def _walk(scenario, **kw):
    sc, ref, T = scenario
    return Walk(sc.walker, ref, T, sc.strides, sc.controller_params(), **kw)


def test_stepped_to_the_end_is_run_walk(scenario):
    sc, ref, T = scenario
    w = _walk(scenario)
    heel = {0: [], 1: []}
    while not w.done:
        codes = w.step()
        for s in (0, 1):
            if codes[s] == Walk.HEEL_STRIKE:
                heel[s].append(w.time_s)
    rec = w.record()
    want = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params())
    np.testing.assert_array_equal(rec.qpos, want.qpos)
    np.testing.assert_array_equal(rec.joint_moment_nm, want.joint_moment_nm)
    assert rec.events.heel_strikes_s == want.events.heel_strikes_s
    # the step's codes are the record's events (the event time is the step's start)
    assert len(heel[0]) == len(want.events.heel_strikes_s[0])
    with pytest.raises(RuntimeError, match="the walk is over"):
        w.step()


def test_accessors_read_the_state(scenario):
    w = _walk(scenario)
    for _ in range(400):
        w.step()
    q = w.data.qpos
    np.testing.assert_array_equal(w.joint_angles_rad, q[w.phys.leg_qpos])
    assert w.joint_angles_rad.shape == (2, 3) and w.joint_velocities_rad_s.shape == (2, 3)
    assert w.time_s == pytest.approx(0.4)
    assert w.steps == 400 and not w.fallen
    grf = w.grf_n
    assert grf.shape == (2, 2)
    # standing on at least one foot: the feet carry about the body's weight
    assert 0.3 < grf[:, 1].sum() / (w.phys.body_mass_kg * 9.81) < 3.0
    assert w.stance.dtype == bool and w.stance.any()
    assert 0.0 <= w.phase.min() and w.phase.max() <= 1.0
    assert 0.5 < w.pelvis_speed_m_s < 2.0
    rec = w.record()
    assert len(rec.time_s) == 400


def test_action_is_an_ankle_torque_the_record_books(scenario):
    a, b = _walk(scenario), _walk(scenario)
    for _ in range(200):
        a.step()
        b.step((-20.0, 0.0))
    ra, rb = a.record(), b.record()
    np.testing.assert_array_equal(rb.device_moment_nm[:, 0], -20.0)
    assert np.all(rb.device_moment_nm[:, 1] == 0.0) and np.all(ra.device_moment_nm == 0.0)
    assert not np.array_equal(ra.qpos, rb.qpos)
    # switching the action off stops it (nothing left applied)
    for _ in range(5):
        b.step()
    assert b.data.qfrc_applied[b.phys.leg_dof[0, 2]] == 0.0
    assert np.all(b.record().device_moment_nm[-5:] == 0.0)
    # reset: the same walk again from the start
    b.reset()
    for _ in range(200):
        b.step()
    np.testing.assert_array_equal(b.record().qpos, ra.qpos)


@pytest.mark.slow
def test_stepped_with_the_hafo_is_run_walk(scenario):
    """A coupled device through Walk.step is the compiled loop's walk, device log included."""
    from afo_mj.devices.hafo import HafoDevice, hafo_params
    from afo_mj.control.assistance import zhang_profile
    sc, ref, T = scenario

    def dev():
        return HafoDevice(hafo_params(preset="hafo_gait"), sides=("right",),
                          profile=zhang_profile(40.0, 52.9, 26.2, 9.8), max_steps=6000)
    d1, d2 = dev(), dev()
    w = _walk(scenario, worn_masses=d1.worn_masses(), device=d1)
    while not w.done:
        w.step()
    got = w.record()
    want = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(),
                    worn_masses=d2.worn_masses(), device=d2)
    np.testing.assert_array_equal(got.qpos, want.qpos)
    np.testing.assert_array_equal(got.device_moment_nm, want.device_moment_nm)
    assert d1.ledger(0)["input_j"] == d2.ledger(0)["input_j"]
    with pytest.raises(RuntimeError, match="a new Walk with a new device"):
        w.reset()
