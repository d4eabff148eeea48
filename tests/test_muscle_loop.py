"""The muscle walk's compiled loop (the reflex controller's compiled step in
afo_mj.gait.controller_loop, issue 39): run_muscle_walk and
MuscleWalkStepper in the compiled loop give the walk of the Python step (the reference,
``loop="python"``) bit for bit — a plain walk of the shipped set, a walk wearing the coupled
HAFO (its log and state too), a walk that falls — and a stepper stepped one compiled step at a
time, with an action step between, reads as the Python one. Divergence, a non-finite state and
the refusals of ``loop="compiled"`` raise as the Python loop raises."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from afo_mj.gait import reflex_law as rl
from afo_mj.gait.muscle_walk import (MuscleWalk, MuscleWalkStepper, load_reflex_set,
                                     run_muscle_walk)
from afo_mj.gait.record import GaitRecord

SHIPPED = "afo_mj/data/reflex_params_1.25.json"


def assert_same_walk(a: MuscleWalk, b: MuscleWalk) -> None:
    """Every array of the two walks and their records equal (np.array_equal, shapes too),
    every other field and the gait events (heel strikes, toe offs, fall time) equal."""
    for obj_a, obj_b, cls in ((a, b, MuscleWalk), (a.record, b.record, GaitRecord)):
        for f in dataclasses.fields(cls):
            x, y = getattr(obj_a, f.name), getattr(obj_b, f.name)
            if isinstance(x, np.ndarray):
                assert x.shape == y.shape and np.array_equal(x, y), f.name
            elif f.name == "signals":
                assert x.keys() == y.keys()
                for name in x:
                    assert np.array_equal(x[name], y[name]), name
            elif f.name != "record":
                assert x == y, f.name
    ea, eb = a.record.events, b.record.events
    assert ea.heel_strikes_s == eb.heel_strikes_s and ea.toe_offs_s == eb.toe_offs_s
    assert ea.fall_time_s == eb.fall_time_s


@pytest.fixture(scope="module")
def params():
    return load_reflex_set(SHIPPED)


def test_plain_walk_is_the_python_loops(params):
    w = MuscleWalkStepper(params=params, duration_s=2.5, loop="compiled")
    assert w.compiled
    compiled = w.run()
    python = run_muscle_walk(params=params, duration_s=2.5, loop="python")
    assert len(python.record.time_s) == 2501 and python.record.events.fall_time_s is None
    assert len(python.record.events.heel_strikes_s[0]) >= 2
    assert_same_walk(compiled, python)


def test_hafo_walk_is_the_python_loops():
    """The HAFO (``hafo_gait``, 40 N·m Zhang profile) on the right ankle under the set
    adapted to it, as the assistance study walks it."""
    from afo_mj.experiments import muscle_assistance as ma
    from afo_mj.scenarios.walk_scenario import muscle_reflex_sets
    adapted = load_reflex_set(muscle_reflex_sets()["adapted/hafo"])
    hafo = ma.Assistance(kind="hafo", hafo_preset="hafo_gait", hafo_peak_torque_nm=40.0)

    def run(loop):
        dev = ma.hafo_device(hafo, 1e-3, max_steps=3000)
        return run_muscle_walk(params=adapted, duration_s=2.5, device=dev, loop=loop,
                               worn_masses=tuple(dev.worn_masses())), dev
    (compiled, dc), (python, dp) = run("compiled"), run("python")
    assert python.record.events.fall_time_s is None
    assert np.abs(python.record.device_moment_nm).max() > 5.0
    assert_same_walk(compiled, python)
    assert dc.steps == dp.steps == 2501 and dc.t_s == dp.t_s
    assert dc.log.n == dp.log.n == 2501
    assert np.array_equal(dc.log.data, dp.log.data)
    assert np.array_equal(dc.Y, dp.Y) and np.array_equal(dc.W, dp.W)


def test_a_fall_is_the_python_loops(params):
    kw = dict(params=params, duration_s=2.0,
              max_force_scale={"soleus": 0.3, "gastrocnemius": 0.3})
    compiled = run_muscle_walk(loop="compiled", **kw)
    python = run_muscle_walk(loop="python", **kw)
    t_fall = python.record.events.fall_time_s
    assert t_fall is not None and t_fall < 2.0
    assert compiled.record.events.fall_time_s == t_fall
    assert_same_walk(compiled, python)


def _accessors(w):
    return (w.steps, w.done, w.fallen, w.time_s, w.joint_angles_rad, w.joint_velocities_rad_s,
            w.grf_n, w.pelvis_speed_m_s, w.stance, w.phase, w.joint_moment_nm,
            w.device_moment_nm)


def test_one_step_at_a_time_reads_as_the_python_step(params):
    """``step()`` (compiled, one step per call) and ``step(action)`` (Python) mixed read
    the same state after every step as a stepper in the Python loop throughout."""
    a = MuscleWalkStepper(params=params, duration_s=1.5)
    b = MuscleWalkStepper(params=params, duration_s=1.5, loop="python")
    assert a.compiled and not b.compiled
    limited = 0
    while not a.done:
        action = (4.0, -2.0) if 500 <= a.steps < 520 else None
        a.step(action)
        b.step(action)
        for x, y in zip(_accessors(a), _accessors(b)):
            assert np.array_equal(x, y)
        assert np.array_equal(a.model.dof_damping, b.model.dof_damping)
        limited += bool(np.any(a._X[rl.X_LIMIT_DAMP:rl.X_LIMIT_DAMP + 6]))
    assert b.done and a.steps == 1501
    assert limited > 0          # the soft limits' damping was written and taken back
    assert_same_walk(a.record(), b.record())
    assert np.array_equal(a.record().record.device_moment_nm[505], [4.0, -2.0])


@pytest.mark.parametrize("spoil", ["qvel", "state"])
def test_divergence_and_a_non_finite_state_raise_as_the_python_step(params, spoil):
    """A huge velocity makes MuJoCo reset its state (time back to 0): 'diverged at t'; a NaN
    in the reflex state: 'non-finite state at t'. Same message, rows and end either way."""
    out = []
    for loop in ("compiled", "python"):
        w = MuscleWalkStepper(params=params, duration_s=1.0, loop=loop)
        for _ in range(300):
            w.step()
        if spoil == "qvel":
            w.data.qvel[0] = 1e12
        else:
            w._X[rl.X_THETA_TO] = math.nan
        with pytest.raises(FloatingPointError) as err:
            w.step()
        out.append((str(err.value), w.steps, w.done))
    assert out[0] == out[1]
    assert out[0][0].startswith("muscle walk: " + ("the simulation diverged at t = 0.3000 s"
                                                   if spoil == "qvel" else
                                                   "non-finite state at t = 0.3010 s"))
    assert out[0][1:] == ((300, True) if spoil == "qvel" else (301, True))


def test_compiled_is_refused_where_it_cannot_run(params):
    with pytest.raises(ValueError, match="loop = 'compiled' needs no device_torque"):
        MuscleWalkStepper(params=params, duration_s=0.1, loop="compiled",
                          device_torque=lambda t, a, v, s: np.zeros(2))
    from afo_mj.devices.ideal import ClutchedSpring, IdealDevice

    class PythonCoupled:
        """A coupled device with no compiled entry points (its step is Python only)."""
        coupled, timestep_s = True, 1e-3

    with pytest.raises(ValueError, match="compiled entry points"):
        MuscleWalkStepper(params=params, duration_s=0.1, loop="compiled",
                          device=PythonCoupled())
    # the ideal device has them (afo_mj.devices.ideal_step)
    assert MuscleWalkStepper(params=params, duration_s=0.1, loop="compiled",
                             device=IdealDevice(sides=("right",),
                                                spring=ClutchedSpring(100.0))).compiled
    w = MuscleWalkStepper(params=params, duration_s=0.1, loop="compiled")
    with pytest.raises(ValueError, match=r"step\(action\)"):
        w.step((1.0, 0.0))
    with pytest.raises(ValueError, match="loop = 'fast'; allowed"):
        run_muscle_walk(params=params, duration_s=0.1, loop="fast")
    # a Python device callable runs in the Python loop under 'auto'
    assert not MuscleWalkStepper(params=params, duration_s=0.1,
                                 device_torque=lambda t, a, v, s: np.zeros(2)).compiled
