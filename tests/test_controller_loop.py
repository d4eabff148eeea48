"""The compiled loop of any controller with a compiled step (issue 39 items 1-2,
:mod:`afo_mj.gait.controller_loop`): a controller's ``numba.cfunc`` of one fixed C signature,
called by address, walks what its Python step walks, bit for bit.

* The reflex controller's compiled step walks the muscle walker's walk (the dedicated stepper,
  an implementation written apart), plain and wearing the HAFO circuit.
* A user's numba controller (``tests/compiled_clock_controller.py``, written only against the
  interface) walks the same walk compiled and in Python, plain, wearing the HAFO, and stepped
  one step at a time with external actions between compiled steps; named from a scenario it
  runs compiled through ``afo-mj run``.
* What the compiled loop cannot honour is refused, naming why.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from afo_mj.gait import controller as gc
from afo_mj.gait.controller import ControllerSetup
from afo_mj.gait.controller_walk import ControllerWalk
from afo_mj.gait.muscle_walk import load_reflex_set, run_muscle_walk
from afo_mj.gait.reference import load_normative
from afo_mj.gait.reflex_controller import ReflexController, ReflexControllerParams, reflex_setup
from afo_mj.human.walker import WalkerParams

sys.path.insert(0, str(Path(__file__).parent))
from cli_helpers import run_cli  # noqa: E402
from clock_controller import ClockController, ClockParams  # noqa: E402
from compiled_clock_controller import NAME, CompiledClockController  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SET_125 = ROOT / "afo_mj" / "data" / "reflex_params_1.25.json"


def _records_equal(ra, rb):
    for f in ra.array_fields():
        assert np.array_equal(getattr(ra, f), getattr(rb, f)), f
    assert ra.events == rb.events
    assert ra.signals.keys() == rb.signals.keys()
    for name in ra.signals:
        assert np.array_equal(ra.signals[name], rb.signals[name]), name


def _reflex(P):
    return ReflexController(ReflexControllerParams(gains=tuple(P)), reflex_setup())


def _hafo(duration_s):
    from afo_mj.experiments.muscle_assistance import Assistance, hafo_device
    return hafo_device(Assistance(kind="hafo"), 1e-3, int(duration_s / 1e-3) + 4)


def _clock(cls=CompiledClockController):
    ref = load_normative("winter", "normal")
    return cls(ClockParams(), ControllerSetup(WalkerParams(), ref, ref.cycle_time_s, 4))


def test_reflex_controller_compiled_walks_the_muscle_walk_bit_for_bit():
    P = load_reflex_set(SET_125)
    dedicated = run_muscle_walk(params=P, duration_s=2.5, loop="python")
    w = ControllerWalk(_reflex(P), 2.5, loop="compiled")
    assert w.compiled
    rec = w.run()
    assert len(rec.events.heel_strikes_s[0]) >= 2
    _records_equal(dedicated.record, rec)
    python = ControllerWalk(_reflex(P), 2.5, loop="python").run()
    _records_equal(python, rec)


def test_reflex_controller_compiled_with_the_hafo_walks_the_muscle_walk_bit_for_bit():
    P = load_reflex_set(SET_125)
    d1, d2 = _hafo(1.5), _hafo(1.5)
    worn = tuple(d1.worn_masses())
    dedicated = run_muscle_walk(params=P, duration_s=1.5, worn_masses=worn, device=d1,
                                loop="python")
    w = ControllerWalk(_reflex(P), 1.5, worn_masses=worn, device=d2, loop="compiled")
    rec = w.run()
    assert np.abs(rec.device_moment_nm[:, 0]).max() > 1.0
    _records_equal(dedicated.record, rec)
    assert d1.steps == d2.steps


def test_a_users_numba_controller_walks_the_same_walk_compiled_and_in_python():
    a = ControllerWalk(_clock(), 5.0, 4, loop="compiled")
    b = ControllerWalk(_clock(), 5.0, 4, loop="python")
    assert a.compiled and not b.compiled
    ra, rb = a.run(), b.run()
    assert len(ra.events.heel_strikes_s[0]) >= 4 and ra.events.fall_time_s is None
    _records_equal(ra, rb)
    # its declared signal is what it commanded (an independent reading: the motors' controls
    # are clamped by the joints' strength, so they need not be equal to the moments applied)
    assert np.abs(ra.signals["commanded_torque_nm"]).max() > 10.0


def test_a_users_numba_controller_wearing_the_hafo_walks_the_same_walk_in_either_loop():
    d1, d2 = _hafo(3.0), _hafo(3.0)
    worn = tuple(d1.worn_masses())
    ra = ControllerWalk(_clock(), 3.0, worn_masses=worn, device=d1, loop="compiled").run()
    rb = ControllerWalk(_clock(), 3.0, worn_masses=worn, device=d2, loop="python").run()
    assert np.abs(ra.device_moment_nm[:, 0]).max() > 1.0
    _records_equal(ra, rb)


def test_stepping_with_actions_between_compiled_steps_is_the_python_walk():
    """step() runs a compiled step when no action is given and a Python step with one; the
    two take turns on the controller's own arrays, so the walk is the Python loop's."""
    a = ControllerWalk(_clock(), 1.5, loop="auto")
    b = ControllerWalk(_clock(), 1.5, loop="python")
    k = 0
    while not a.done:
        act = (3.0, -2.0) if (k // 100) % 3 == 1 else None
        a.step(act)
        b.step(act)
        k += 1
        if k % 50 == 0:
            assert np.array_equal(a.joint_angles_rad, b.joint_angles_rad)
            assert np.array_equal(a.device_moment_nm, b.device_moment_nm)
            assert np.array_equal(a.stance, b.stance)
    assert b.done
    _records_equal(a.record(), b.record())


def test_the_compiled_loop_refuses_what_it_cannot_honour():
    with pytest.raises(ValueError, match="has no compiled step"):
        ControllerWalk(_clock(ClockController), 1.0, loop="compiled")

    class PushOff:                      # an uncoupled AnkleDevice: a Python torque callback
        def torque_nm(self, t, angle, velocity, phase, stance):
            return np.zeros(2)
    with pytest.raises(ValueError, match="Python callback"):
        ControllerWalk(_clock(), 1.0, device=PushOff(), loop="compiled")
    w = ControllerWalk(_clock(), 0.3, device=PushOff())          # auto: the Python loop
    assert not w.compiled
    assert len(w.run().time_s) == 301
    with pytest.raises(ValueError, match="loop"):
        ControllerWalk(_clock(), 1.0, loop="fast")


def test_a_registered_numba_controller_runs_compiled_from_a_scenario(tmp_path):
    from afo_mj.gait.walkers import walker_model
    from afo_mj.scenarios.walk_scenario import load_scenario
    gc.register_controller(CompiledClockController)
    try:
        p = tmp_path / "c.toml"
        p.write_text(f'[walker]\nmodel = "{NAME}"\n[gait]\nstrides = 4\n'
                     'analyse_strides = [2, 4]\n', encoding="utf-8")
        sc = load_scenario(p)
        w = walker_model(sc).stepper(sc, sc.load_reference(), None, ())
        assert type(w).__name__ == "ControllerWalk" and w.compiled
        rc, out, err = run_cli(["run", str(p), "--out", str(tmp_path / "out")])
        assert rc == 0, err
        s = json.loads((tmp_path / "out" / "summary.json").read_text())
        clock = 120.0 / load_normative("winter", "normal").cycle_time_s
        assert s["cadence_steps_per_min"]["mean"] == pytest.approx(clock, rel=0.01)
    finally:
        gc.unregister_controller(NAME)
