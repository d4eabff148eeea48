"""Speed of the muscle-driven walker (issue 22): real-time factor of a walk and the cost of
one optimiser evaluation.

Run: ``.venv/bin/python benchmarks/muscle_walk.py [reflex_params.json]`` (default: the
shipped 1.25 m/s set, ``afo_mj/data/reflex_params_1.25.json``, or Geyer & Herr's gains when
it is missing). A 10 s walk (fewer seconds if it falls) is timed after a warm-up, best of 3:
µs per 1 ms step and simulated seconds per wall second (target ≥ 20 on one core); then one
evaluation of :func:`afo_mj.studies.gait_optimization.gait_cost` (a 12 s walk and its gait
quality). The last line is a JSON object.
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


def main() -> None:
    from afo_mj.gait.muscle_walk import reflex_params, run_muscle_walk
    from afo_mj.studies.gait_optimization import GaitObjective, gait_cost, load_reflex_set
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "afo_mj/data/reflex_params_1.25.json"
    params = load_reflex_set(path) if path.exists() else reflex_params()
    run_muscle_walk(params=params, duration_s=0.5)              # compile / load
    best = None
    for _ in range(3):
        t0 = time.perf_counter()
        walk = run_muscle_walk(params=params, duration_s=10.0)
        wall = time.perf_counter() - t0
        n = len(walk.record.time_s)
        if best is None or wall / n < best[0] / best[1]:
            best = (wall, n)
    wall, n = best
    us = wall / n * 1e6
    rtf = n * 1e-3 / wall
    t0 = time.perf_counter()
    cost, _ = gait_cost(params, GaitObjective())
    t_eval = time.perf_counter() - t0
    print(f"muscle walker ({path.name if path.exists() else 'Geyer & Herr gains'}): "
          f"{n} steps, {us:.1f} us/step, {rtf:.0f}x real time (target >= 20)")
    print(f"one optimiser evaluation (12 s walk + gait quality): {t_eval:.2f} s, cost {cost:.2f}")
    print(json.dumps({"benchmark": "muscle_walk", "steps": n, "us_per_step": round(us, 2),
                      "real_time_factor": round(rtf, 1), "target_real_time_factor": 20,
                      "evaluation_s": round(t_eval, 3), "cost": cost}))


if __name__ == "__main__":
    main()
