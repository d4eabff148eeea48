"""Cost of one 1 ms step of the walker: bare ``mj_step`` vs the full walking driver.

The full driver adds the controller (phase, gait events, reference lookup, foot placement,
trunk control, residuals) and the per-step recording of the GaitRecord. Prints µs per step and
the real-time factor (simulated s per wall s); the last line is a JSON object.

Run: ``.venv/bin/python benchmarks/gait_step.py``
"""

from __future__ import annotations

import json
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from afo_mj.gait.reference import load_normative  # noqa: E402
from afo_mj.gait.walk import ControllerParams, run_walk  # noqa: E402
from afo_mj.human.walker import WalkerParams, WalkerPhysics, build_walker  # noqa: E402


def bare_step_us(n_steps: int = 20000) -> float:
    """µs per ``mj_step`` of the walker standing on the floor with constant PD targets."""
    phys = WalkerPhysics(build_walker())
    m, d = phys.model, phys.data
    d.ctrl[phys.pd_act] = 0.0
    mujoco.mj_forward(m, d)
    t0 = time.perf_counter()
    for _ in range(n_steps):
        mujoco.mj_step(m, d)
    return (time.perf_counter() - t0) / n_steps * 1e6


def driver_step_us(strides: int = 10) -> tuple[float, float, int]:
    """µs per step of the full healthy walk (model build excluded), and the run's sim time."""
    ref = load_normative("winter", "normal")
    t0 = time.perf_counter()
    build = WalkerPhysics(build_walker())  # model build cost, measured apart
    t_build = time.perf_counter() - t0
    del build
    t0 = time.perf_counter()
    rec = run_walk(WalkerParams(), ref, ref.cycle_time_s, strides, ControllerParams())
    wall = time.perf_counter() - t0 - t_build
    n = len(rec.time_s)
    return wall / n * 1e6, float(rec.time_s[-1]), n


def main() -> None:
    bare = min(bare_step_us() for _ in range(3))
    runs = [driver_step_us() for _ in range(3)]
    full, sim_s, n = min(runs)
    result = {
        "bare_mj_step_us": round(bare, 2),
        "driver_step_us": round(full, 2),
        "driver_overhead_us": round(full - bare, 2),
        "bare_real_time_factor": round(1e3 / bare, 1),
        "driver_real_time_factor": round(1e3 / full, 1),
        "steps": n,
        "simulated_s": round(sim_s, 3),
    }
    print(f"walker, 1 ms step: bare mj_step {bare:.1f} us ({1e3 / bare:.0f}x real time)")
    print(f"full driver (controller + events + recording): {full:.1f} us/step "
          f"({1e3 / full:.0f}x real time) over {n} steps / {sim_s:.2f} s simulated")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
