"""The compiled walk loop (issue 21) against the Python loop it replaces.

The reference is the Python loop of :func:`afo_mj.gait.walk.run_walk` (``loop="python"``),
which calls MuJoCo through its Python bindings and the controller as a separate compiled
call: a separately written loop around the same physics. The compiled loop
(:mod:`afo_mj.gait.walk_loop`, MuJoCo's C ``mj_step`` called from numba) must give the same
record bit for bit: every signal, every gait event, a fall at the same time. Also: the raw
``mj_step`` call against the bindings' one on a free-falling box with contacts, and the
``mjData.time`` view.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numba
import numpy as np
import pytest

from afo_mj.gait import walk
from afo_mj.gait.native_step import call_mj_step, native_step, time_view
from afo_mj.gait.reference import load_normative
from afo_mj.human.walker import WalkerParams

ROOT = Path(__file__).resolve().parents[1]
SIGNALS = ("time_s", "qpos", "joint_angle_rad", "joint_velocity_rad_s", "joint_moment_nm",
           "device_moment_nm", "grf_n", "contact_force_n", "contact_height_m",
           "pelvis_position_m", "pelvis_velocity_m_s", "pelvis_tilt_rad", "residual_force_n",
           "residual_moment_nm", "gait_phase")


def _same(a, b):
    for name in SIGNALS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape, name
        assert np.array_equal(x, y), f"{name}: max |diff| {np.max(np.abs(x - y))}"
    assert a.events == b.events


@numba.njit
def _steps(n, fn, m, d):
    for _ in range(n):
        call_mj_step(fn, m, d)


BOX = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="1 1 .1"/>
<body pos="0 0 .3" euler="10 20 30"><freejoint/><geom type="box" size=".05 .07 .03"/></body>
</worldbody></mujoco>"""


def test_native_mj_step_equals_the_bindings():
    """200 steps of a box tumbling onto a plane (contacts): the C call from compiled code and
    ``mujoco.mj_step`` leave the same state, and the time view reads ``data.time``."""
    model = mujoco.MjModel.from_xml_string(BOX)
    a, b = mujoco.MjData(model), mujoco.MjData(model)
    b.qvel[:] = a.qvel[:] = [0.3, -0.2, 0.0, 2.0, 1.0, -3.0]
    view = time_view(b)
    for _ in range(200):
        mujoco.mj_step(model, a)
    _steps(200, native_step().mj_step_address, model._address, b._address)
    assert np.array_equal(a.qpos, b.qpos) and np.array_equal(a.qvel, b.qvel)
    assert a.ncon == b.ncon and a.ncon > 0
    assert a.time == b.time == view[0] == pytest.approx(0.4)
    b.time = 1.25
    assert view[0] == 1.25


def _walk(loop, strides=3, walker=None, controller=None, **kw):
    ref = load_normative("winter", "normal")
    return walk.run_walk(walker or WalkerParams(), ref, ref.cycle_time_s, strides,
                         controller or walk.ControllerParams(), loop=loop, **kw)


def test_compiled_loop_equals_python_loop_bitwise():
    a = _walk("python")
    b = _walk("compiled")
    _same(a, b)
    assert len(a.events.heel_strikes_s[0]) == 4 and a.events.fall_time_s is None
    _same(b, _walk("auto"))


def test_compiled_loop_is_bitwise_reproducible():
    _same(_walk("compiled", strides=2), _walk("compiled", strides=2))


def test_fall_is_recorded_at_the_same_time():
    """A walker with 0.5 N·m/kg of plantarflexor strength (a fifth of the default) falls:
    both loops stop at the same step and record the same fall time."""
    weak = dataclasses.replace(WalkerParams(), plantarflexor_strength_nm_per_kg=0.5)
    a = _walk("python", strides=6, walker=weak)
    b = _walk("compiled", strides=6, walker=weak)
    assert a.events.fall_time_s is not None
    _same(a, b)


def test_max_time_and_worn_mass():
    """A run cut by ``max_time_s`` with 1 kg worn at the right ankle (another model)."""
    from afo_mj.human.walker import WornMass
    worn = (WornMass("ankle_axis_r", 1.0, "test_mass"),)
    a = _walk("python", strides=5, max_time_s=1.5, worn_masses=worn)
    b = _walk("compiled", strides=5, max_time_s=1.5, worn_masses=worn)
    _same(a, b)
    assert len(b.time_s) == int(1.5 / 1e-3) + 2
    assert not np.array_equal(b.qpos, _walk("compiled", strides=5, max_time_s=1.5).qpos)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["walk_healthy", "walk_weak_plantarflexors", "walk_foot_drop",
                                  "walk_spastic_ankle", "walk_child_healthy",
                                  "walk_child_foot_drop", "walk_schwartz_free"])
def test_shipped_walk_scenarios_equal(name):
    """Every shipped walk scenario without a device: compiled == Python loop, bit for bit."""
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    ref = sc.load_reference()
    runs = [walk.run_walk(sc.walker, ref, sc.cycle_time_s(ref), sc.strides,
                          sc.controller_params(), loop=loop) for loop in ("python", "compiled")]
    _same(*runs)


def test_bad_loop_names_the_choices():
    with pytest.raises(ValueError, match="loop = 'fast'.*'auto', 'compiled', 'python'"):
        _walk("fast")


def test_python_callback_device_refuses_the_compiled_loop():
    class Flat:
        def torque_nm(self, t_s, angle_rad, velocity_rad_s, phase, stance):
            return np.zeros(2)

    with pytest.raises(ValueError, match="Python callback"):
        _walk("compiled", device=Flat())
    # auto takes the Python loop for it
    assert len(_walk("auto", strides=1, device=Flat()).time_s) > 0


def _hafo_walk(loop, strides=2, **device_kw):
    from afo_mj.experiments.device_walk import make_device
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(ROOT / "scenarios" / "gait_assist_hafo.toml")
    ref = sc.load_reference()
    T, dt = sc.cycle_time_s(ref), sc.walker.timestep_s
    dev = make_device(device_config(sc), "assist", dt, int((strides + 2.5) * T / dt) + 4)
    for k, v in device_kw.items():
        setattr(dev, k, v)
    rec = walk.run_walk(sc.walker, ref, T, strides, sc.controller_params(),
                        worn_masses=dev.worn_masses(), device=dev, loop=loop)
    return rec, dev


def test_coupled_hafo_walk_compiled_equals_python_loop():
    """The HAFO coupled to the walker (assist): the compiled loop calls the generated
    circuit's C entry points (afo_mj.circuits.native_entry) where the Python loop calls
    begin_step / end_step; walk record, device log, step count, time and energy ledger are
    the same bit for bit."""
    a, da = _hafo_walk("python")
    b, db = _hafo_walk("compiled")
    _same(a, b)
    assert np.any(b.device_moment_nm != 0.0)
    assert da.steps == db.steps == len(b.time_s)
    assert da.log.n == db.log.n == len(b.time_s)
    assert np.array_equal(da.log.data, db.log.data)
    assert da.t_s == db.t_s
    assert da.ledger(0) == db.ledger(0)
    _same(b, _hafo_walk("auto")[0])


def test_python_command_device_takes_the_python_loop():
    """A circuit device whose command is a Python function has no C entry points: ``auto``
    walks it in the Python loop, ``compiled`` is refused with the reason."""
    from afo_mj.circuits.device import CircuitDevice
    rec, dev = _hafo_walk("auto", strides=1, torque_fn=lambda t, th, thd: 0.0)
    assert dev.native_coupling() is None and dev.steps == len(rec.time_s)
    with pytest.raises(ValueError, match="Python callback"):
        _hafo_walk("compiled", strides=1, torque_fn=lambda t, th, thd: 0.0)
    assert issubclass(type(dev), CircuitDevice)


DEVICE_SCENARIOS = ["gait_assist_hafo", "gait_assist_hafo_prototype", "gait_assist_valve",
                    "gait_assist_digital", "gait_lab_bench", "gait_pump_accumulator",
                    "gait_spring_return", "gait_stiffness_emulation",
                    "gait_weak_plantarflexors_hafo"]


@pytest.mark.slow
@pytest.mark.parametrize("name", DEVICE_SCENARIOS)
def test_shipped_device_scenarios_equal(name):
    """Every shipped device scenario, each of its device conditions, 2 strides: the compiled
    loop (the circuit's C entry points) equals the Python loop bit for bit, device log
    included."""
    from afo_mj.experiments.device_walk import make_device
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(ROOT / "scenarios" / f"{name}.toml", ["gait.strides=2",
                                                            "gait.analyse_strides=[1, 2]"])
    ref = sc.load_reference()
    T, dt = sc.cycle_time_s(ref), sc.walker.timestep_s
    cfg = device_config(sc)
    conditions = [c for c in cfg.conditions if c != "no_device"]
    assert conditions
    for cond in conditions:
        runs = []
        for loop in ("python", "compiled"):
            dev = make_device(cfg, cond, dt, int(4.5 * T / dt) + 4)
            worn = dev.worn_masses() if hasattr(dev, "worn_masses") else ()
            rec = walk.run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(),
                                worn_masses=worn, device=dev, loop=loop)
            runs.append((rec, dev))
        (a, da), (b, db) = runs
        _same(a, b)
        assert np.array_equal(da.log.data[:da.log.n], db.log.data[:db.log.n]), cond
        assert da.steps == db.steps
