"""A controller walk's record is views of the walk's buffers where it can be (no copies of a
walk: issue 39's step cost includes the record), with the values the gathered copies hold;
a run builds it once; the gait phase of times in any order is the phase of the same times
in order."""

from __future__ import annotations

import numpy as np
import pytest

from afo_mj.gait.muscle_walk import MuscleWalkStepper
from afo_mj.gait.record import GaitEvents, phase_from_events


@pytest.fixture(scope="module")
def walked():
    w = MuscleWalkStepper(duration_s=0.3)
    return w, w.run().record


def test_record_columns_are_read_only_views_of_the_walk(walked):
    w, r = walked
    phys, k, b = w.phys, w.steps, w._buf
    qq, vv, sens = b["qpos"][:k], b["qvel"][:k], b["sens"][:k]
    expected = {   # field: (the buffer it views, the values gathered by fancy indexing)
        "time_s": (b["time"], b["time"][:k]),
        "qpos": (b["qpos"], qq),
        "joint_angle_rad": (b["qpos"], qq[:, phys.leg_qpos]),
        "joint_velocity_rad_s": (b["qvel"], vv[:, phys.leg_dof]),
        "joint_moment_nm": (b["tau"], b["tau"][:k]),
        "device_moment_nm": (b["dev"], b["dev"][:k]),
        "contact_force_n": (b["sens"], sens[:, phys.touch_adr]),
        "pelvis_velocity_m_s": (b["qvel"], vv[:, phys.pelvis_dof[:2]]),
        "pelvis_tilt_rad": (b["qpos"], qq[:, phys.pelvis_qpos[2]]),
        "residual_force_n": (b["res"], b["res"][:k, :2]),
        "residual_moment_nm": (b["res"], b["res"][:k, 2]),
    }
    for name, (buf, values) in expected.items():
        got = getattr(r, name)
        assert np.shares_memory(got, buf), name
        assert not got.flags.writeable, name
        assert got.shape == values.shape and np.array_equal(got, values), name
    grf = -sens[:, np.stack([phys.foot_force_adr, phys.foot_force_adr + 2], 1)]
    assert np.array_equal(r.grf_n, grf)
    z = b["qpos"][:k, phys.pelvis_qpos[1]] + phys.pelvis_height_offset_m
    assert np.array_equal(r.pelvis_position_m, np.column_stack([qq[:, phys.pelvis_qpos[0]], z]))


def test_run_builds_the_record_once(monkeypatch):
    calls = []
    record = MuscleWalkStepper.record

    def counted(self):
        calls.append(1)
        return record(self)

    monkeypatch.setattr(MuscleWalkStepper, "record", counted)
    MuscleWalkStepper(duration_s=0.05).run()
    assert len(calls) == 1


def test_phase_of_times_in_any_order_is_the_phase_in_order():
    rng = np.random.default_rng(3)
    t = np.arange(2001) * 1e-3
    for _ in range(20):
        e = GaitEvents()
        for s in range(2):
            e.heel_strikes_s[s].extend(sorted(rng.uniform(0.0, 2.0, rng.integers(0, 6))
                                              .round(3).tolist()))
        perm = rng.permutation(len(t))
        assert np.array_equal(phase_from_events(t[perm], e), phase_from_events(t, e)[perm])
