"""Cost of wearing a device on the muscle-driven walker (issue 39 target: muscle walker + HAFO
circuit ≤ 1.5× the muscle walker alone per step).

Run: ``.venv/bin/python benchmarks/muscle_device.py [seconds]`` (default 8 s walks). In one
process, on one core (threads pinned before anything is imported), after a warm-up of each:
the muscle walker alone and wearing the HAFO (``hafo_gait``, Zhang assistance 40 N·m, the
wearer adapted to it: reflex set ``adapted/hafo``, i.e. ``scenarios/gait_muscle_hafo.toml``'s
assist condition), each walk timed best of 3 as µs per 1 ms step. Both walks are built as
``afo-mj run`` builds them (:func:`afo_mj.gait.muscle_scenario.muscle_scenario_stepper`, the
device by :func:`afo_mj.experiments.device_walk.make_device`); the step figures time the walk
itself (:meth:`~afo_mj.gait.muscle_walk.MuscleWalkStepper.run`: the compiled loop and the
record), the build (the walker's model, the device and its log) is timed apart. Prints both,
the ratio (``device_over_alone``) and the real-time factors; the last line is a JSON
object.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

for _v in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_v] = "1"
os.environ.setdefault("MUJOCO_GL", "egl")

ROOT = Path(__file__).resolve().parents[1]
TARGET_RATIO = 1.5


def _best_us_per_step(walk_once, repeats: int = 3) -> tuple[float, int]:
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        n = walk_once()
        wall = time.perf_counter() - t0
        if best is None or wall / n < best[0] / best[1]:
            best = (wall, n)
    wall, n = best
    return wall / n * 1e6, n


def main() -> None:
    from afo_mj.experiments.device_walk import make_device
    from afo_mj.gait.muscle_scenario import muscle_scenario_stepper
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario

    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 8.0
    strides = max(int(seconds / 1.1) - 2, 1)
    sc = load_scenario(ROOT / "scenarios" / "gait_muscle_hafo.toml",
                       overrides=[f"gait.strides={strides}",
                                  f"gait.analyse_strides=[1, {strides}]"])
    cfg = device_config(sc)
    dt = sc.walker.timestep_s

    def build_alone():
        return muscle_scenario_stepper(sc)

    def build_hafo():
        dev = make_device(cfg, "assist", dt, int((seconds + 5.0) / dt))
        return muscle_scenario_stepper(sc, device=dev, worn_masses=dev.worn_masses())

    def timed(build) -> tuple[float, int, float]:
        t0 = time.perf_counter()
        w = build()
        t1 = time.perf_counter()
        n = len(w.run().record.time_s)
        return time.perf_counter() - t1, n, t1 - t0

    def best(build, repeats: int = 3):
        runs = [timed(build) for _ in range(repeats)]
        wall, n, _b = min(runs, key=lambda r: r[0] / r[1])
        return wall / n * 1e6, n, min(r[2] for r in runs)

    timed(build_alone)
    timed(build_hafo)                              # compile / load both
    us_alone, n_alone, build_s_alone = best(build_alone)
    us_dev, n_dev, build_s_dev = best(build_hafo)
    ratio = us_dev / us_alone
    print(f"muscle walker alone: {n_alone} steps, {us_alone:.1f} us/step, "
          f"{1e3 / us_alone:.0f}x real time")
    print(f"muscle walker + HAFO (hafo_gait circuit, assist): {n_dev} steps, {us_dev:.1f} "
          f"us/step, {1e3 / us_dev:.0f}x real time")
    print(f"device over alone: {ratio:.2f}x per step (target <= {TARGET_RATIO})")
    print(f"build (model, device, log), not in the steps: alone {build_s_alone * 1e3:.0f} ms, "
          f"with the HAFO {build_s_dev * 1e3:.0f} ms")
    print(json.dumps({"benchmark": "muscle_device", "steps_alone": n_alone,
                      "steps_device": n_dev, "us_per_step_alone": round(us_alone, 2),
                      "us_per_step_device": round(us_dev, 2),
                      "device_over_alone": round(ratio, 3), "target": TARGET_RATIO,
                      "real_time_factor_alone": round(1e3 / us_alone, 1),
                      "real_time_factor_device": round(1e3 / us_dev, 1),
                      "build_s_alone": round(build_s_alone, 4),
                      "build_s_device": round(build_s_dev, 4)}))


if __name__ == "__main__":
    main()
