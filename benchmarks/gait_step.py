"""Cost of one 1 ms step of the walker: bare ``mj_step`` vs the full walking driver.

* bare: the same healthy 10-stride walk replayed step by step with the controls the driver
  chose (``data.ctrl`` and the Hill-limited ankle torque range written, then ``mj_step``): the
  physics cost of walking, with contacts, and nothing else;
* driver: :func:`afo_mj.gait.walk.run_walk` (controller, gait events, reference lookup, foot
  placement, trunk control, residuals, recording of the GaitRecord), model build excluded.

Prints µs per step and real-time factors (simulated s per wall s); the last line is a JSON
object. Run: ``.venv/bin/python benchmarks/gait_step.py``
"""

from __future__ import annotations

import json
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from afo_mj.gait import walk  # noqa: E402
from afo_mj.gait.reference import load_normative  # noqa: E402
from afo_mj.human.walker import WalkerParams, WalkerPhysics, build_walker  # noqa: E402


def _walk_once(strides: int):
    ref = load_normative("winter", "normal")
    return walk.run_walk(WalkerParams(), ref, ref.cycle_time_s, strides, walk.ControllerParams())


def driver_step_us(strides: int = 10) -> tuple[float, float, int]:
    """µs per step of the full healthy walk, model build excluded."""
    t0 = time.perf_counter()
    WalkerPhysics(build_walker())                       # the build the driver also does
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    rec = _walk_once(strides)
    wall = time.perf_counter() - t0 - t_build
    n = len(rec.time_s)
    return wall / n * 1e6, float(rec.time_s[-1]), n


def bare_step_us(strides: int = 10) -> float:
    """µs per ``mj_step`` replaying a driver run's controls (captured by wrapping mj_step)."""
    captured: list[tuple[np.ndarray, np.ndarray]] = []
    start: dict[str, np.ndarray] = {}
    original = walk.mujoco.mj_step

    def capture(model, data):
        if not start:
            start.update(qpos=data.qpos.copy(), qvel=data.qvel.copy(), model=model)
        captured.append((data.ctrl.copy(), model.jnt_actfrcrange.copy()))
        original(model, data)

    walk.mujoco.mj_step = capture
    try:
        _walk_once(strides)
    finally:
        walk.mujoco.mj_step = original
    model = start["model"]
    data = mujoco.MjData(model)
    data.qpos[:] = start["qpos"]
    data.qvel[:] = start["qvel"]
    mujoco.mj_forward(model, data)
    ctrl, rng = data.ctrl, model.jnt_actfrcrange
    t0 = time.perf_counter()
    for c, r in captured:
        ctrl[:] = c
        rng[:] = r
        mujoco.mj_step(model, data)
    return (time.perf_counter() - t0) / len(captured) * 1e6


def main() -> None:
    bare = min(bare_step_us() for _ in range(3))
    full, sim_s, n = min(driver_step_us() for _ in range(3))
    result = {
        "bare_mj_step_us": round(bare, 2),
        "driver_step_us": round(full, 2),
        "driver_overhead_us": round(full - bare, 2),
        "bare_real_time_factor": round(1e3 / bare, 1),
        "driver_real_time_factor": round(1e3 / full, 1),
        "steps": n,
        "simulated_s": round(sim_s, 3),
    }
    print(f"walker, 1 ms step, healthy 10-stride walk ({n} steps, {sim_s:.2f} s simulated)")
    print(f"  bare mj_step (replayed controls): {bare:6.1f} us/step ({1e3 / bare:5.0f}x real time)")
    print(f"  full driver:                      {full:6.1f} us/step ({1e3 / full:5.0f}x real time)")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
