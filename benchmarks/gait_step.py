"""Cost of one 1 ms step of the walker: bare ``mj_step`` vs the full walking driver.

* bare, native: the same healthy 10-stride walk replayed step by step with the controls the
  driver chose (``data.ctrl`` and the Hill-limited ankle torque range written, then MuJoCo's
  C ``mj_step``) from a compiled loop: the physics cost of walking, with contacts, and
  nothing else (the floor for this model);
* bare, bindings: the same replay from Python through ``mujoco.mj_step`` (what a Python loop
  pays at least);
* driver, compiled: :func:`afo_mj.gait.walk.run_walk` with its default compiled loop
  (:mod:`afo_mj.gait.walk_loop`: controller, gait events, reference lookup, foot placement,
  trunk control, residuals, ``mj_step``, recording, checks), model build excluded;
* driver, Python loop: the same with ``loop="python"`` (the loop before issue 21).

All in the same process and run, best of 3. Prints µs per step, real-time factors (simulated
s per wall s) and the driver's ratio to the native bare step (issue 21 target ≤ 1.2); the
last line is a JSON object. Run: ``.venv/bin/python benchmarks/gait_step.py``
"""

from __future__ import annotations

import json
import math
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

from afo_mj.gait import walk  # noqa: E402
from afo_mj.gait.native_step import call_mj_step, native_step  # noqa: E402
from afo_mj.gait.reference import load_normative  # noqa: E402
from afo_mj.human.walker import WalkerParams, WalkerPhysics, build_walker  # noqa: E402


def _walk_once(strides: int, loop: str = "auto"):
    ref = load_normative("winter", "normal")
    return walk.run_walk(WalkerParams(), ref, ref.cycle_time_s, strides, walk.ControllerParams(),
                         loop=loop)


def driver_step_us(strides: int = 10, loop: str = "auto") -> tuple[float, float, int]:
    """µs per step of the full healthy walk, model build excluded."""
    # the build the driver also does, subtracted: its fastest of three, so that a pause of the
    # machine while it is timed cannot make the step look cheaper than it is
    t_build = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        WalkerPhysics(build_walker())
        t_build = min(t_build, time.perf_counter() - t0)
    t0 = time.perf_counter()
    rec = _walk_once(strides, loop)
    wall = time.perf_counter() - t0 - t_build
    n = len(rec.time_s)
    return wall / n * 1e6, float(rec.time_s[-1]), n


@numba.njit
def _native_replay(ctrls, ranges, ctrl, rng, fn, m_addr, d_addr):
    for i in range(ctrls.shape[0]):
        ctrl[:] = ctrls[i]
        rng[:, :] = ranges[i]
        call_mj_step(fn, m_addr, d_addr)


def bare_step_us(strides: int = 10) -> tuple[float, float]:
    """µs per ``mj_step`` replaying a driver run's controls (captured by wrapping mj_step in
    the Python loop): (native, from compiled code; through the Python bindings)."""
    captured: list[tuple[np.ndarray, np.ndarray]] = []
    start: dict[str, np.ndarray] = {}
    original = mujoco.mj_step

    def capture(model, data):
        if not start:
            start.update(qpos=data.qpos.copy(), qvel=data.qvel.copy(), model=model)
        captured.append((data.ctrl.copy(), model.jnt_actfrcrange.copy()))
        original(model, data)

    mujoco.mj_step = capture
    try:
        _walk_once(strides, "python")
    finally:
        mujoco.mj_step = original
    model = start["model"]

    def fresh():
        data = mujoco.MjData(model)
        data.qpos[:] = start["qpos"]
        data.qvel[:] = start["qvel"]
        mujoco.mj_forward(model, data)
        return data

    data = fresh()
    ctrl, rng = data.ctrl, model.jnt_actfrcrange
    t0 = time.perf_counter()
    for c, r in captured:
        ctrl[:] = c
        rng[:] = r
        mujoco.mj_step(model, data)
    bindings = (time.perf_counter() - t0) / len(captured) * 1e6
    ctrls = np.array([c for c, _ in captured])
    ranges = np.array([r for _, r in captured])
    fn = native_step().mj_step_address
    warm = fresh()
    _native_replay(ctrls[:2], ranges[:2], warm.ctrl, rng, fn, model._address, warm._address)
    data = fresh()
    t0 = time.perf_counter()
    _native_replay(ctrls, ranges, data.ctrl, rng, fn, model._address, data._address)
    native = (time.perf_counter() - t0) / len(captured) * 1e6
    return native, bindings


def main() -> None:
    bares = [bare_step_us() for _ in range(3)]
    bare = min(b[0] for b in bares)
    bare_py = min(b[1] for b in bares)
    full, sim_s, n = min(driver_step_us() for _ in range(3))
    full_py, _, _ = min(driver_step_us(loop="python") for _ in range(3))
    result = {
        "bare_mj_step_us": round(bare, 2),
        "bare_mj_step_bindings_us": round(bare_py, 2),
        "driver_step_us": round(full, 2),
        "driver_python_loop_step_us": round(full_py, 2),
        "driver_overhead_us": round(full - bare, 2),
        "driver_over_bare": round(full / bare, 3),
        "target_driver_over_bare": 1.2,
        "bare_real_time_factor": round(1e3 / bare, 1),
        "driver_real_time_factor": round(1e3 / full, 1),
        "steps": n,
        "simulated_s": round(sim_s, 3),
    }
    print(f"walker, 1 ms step, healthy 10-stride walk ({n} steps, {sim_s:.2f} s simulated)")
    print(f"  bare mj_step, native (replayed controls): {bare:6.1f} us/step "
          f"({1e3 / bare:5.0f}x real time)")
    print(f"  bare mj_step, Python bindings:            {bare_py:6.1f} us/step")
    print(f"  driver, compiled loop:                    {full:6.1f} us/step "
          f"({1e3 / full:5.0f}x real time), {full / bare:.2f}x the native bare step")
    print(f"  driver, Python loop:                      {full_py:6.1f} us/step")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
