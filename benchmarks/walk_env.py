"""Per-step cost of the steppable walk and of the gymnasium environment (issue 23).

``scenarios/walk_healthy.toml`` (4 strides), in one process, medians of the repeats:

* ``run_walk`` in its compiled loop (the reference: no Python per step);
* ``Walk.step()`` called from Python to the walk's end (the object API: one Python call, the
  compiled controller and ``mj_step`` through the bindings per step);
* ``Walk.step(action)`` with an ankle torque each step;
* ``AnkleAssistEnv.step`` at 100 Hz (10 MuJoCo steps per action, the default reward) and at
  1 kHz (one MuJoCo step per action), per MuJoCo step.

Prints the figures; the last line is a JSON object.
Run: ``.venv/bin/python benchmarks/walk_env.py [repeats]``
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from afo_mj.experiments.walk_env import AnkleAssistEnv  # noqa: E402
from afo_mj.gait.walk import Walk, run_walk  # noqa: E402
from afo_mj.scenarios.walk_scenario import load_scenario  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "walk_healthy.toml"
OVERRIDES = ["gait.strides=4", "gait.analyse_strides=[2, 4]"]


def main(repeats: int = 3) -> dict:
    sc = load_scenario(SCENARIO, overrides=OVERRIDES)
    ref = sc.load_reference()
    T = sc.cycle_time_s(ref)
    args = (sc.walker, ref, T, sc.strides, sc.controller_params())

    def compiled():
        t0 = time.perf_counter()
        r = run_walk(*args)
        return (time.perf_counter() - t0) / len(r.time_s)

    def stepped(action):
        w = Walk(*args)
        t0 = time.perf_counter()
        while not w.done:
            w.step(action)
        return (time.perf_counter() - t0) / w.steps

    def env_steps(rate):
        env = AnkleAssistEnv(SCENARIO, control_rate_hz=rate, overrides=OVERRIDES)
        env.reset(seed=0)
        a = np.zeros(2)
        t0 = time.perf_counter()
        while True:
            *_, term, trunc, _ = env.step(a)
            if term or trunc:
                break
        return (time.perf_counter() - t0) / env.walk.steps

    cases = {"run_walk_compiled": compiled, "walk_step": lambda: stepped(None),
             "walk_step_action": lambda: stepped(np.array([-5.0, -5.0])),
             "env_100hz": lambda: env_steps(100.0), "env_1khz": lambda: env_steps(1000.0)}
    for f in cases.values():                    # warm up (numba caches, first builds)
        f()
    us = {k: statistics.median(f() for _ in range(repeats)) * 1e6 for k, f in cases.items()}
    base = us["run_walk_compiled"]
    print(f"walk_healthy, 4 strides, 1 ms steps, median of {repeats}; µs per MuJoCo step "
          "(× the compiled run_walk):")
    for k, v in us.items():
        print(f"  {k:20s} {v:7.1f}  ({v / base:4.1f}×)")
    out = {f"{k}_us_per_step": round(v, 2) for k, v in us.items()}
    out["repeats"] = repeats
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
