"""Cost of the minimum-weight design tool (issue 9: "the design study runs in seconds").

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/design.py [repeats]``. On one core (threads
pinned before anything is imported), after one warm-up call (imports, numba caches):

* ``size_system`` on ``scenarios/design/hafo_requirements.toml`` (the HAFO corner, fixed
  13.8 MPa) and on ``gait_assist_requirements.toml`` (a normative profile over a 5–21 MPa
  pressure range), best of ``repeats``;
* the design-guideline studies of the HAFO requirements (pressure sweep of 8 points, every oil,
  five output powers);
* the whole ``afo-mj design`` (``afo_mj.app.design.design``: search, studies, hose-bore
  trade-off, bench prediction, every file written) for the HAFO requirements.

Prints one line per measurement and, last, a JSON object.
"""

from __future__ import annotations

import os

for _v in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"
os.environ.setdefault("MUJOCO_GL", "egl")

import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 10.0


def best_of(fn, n: int) -> float:
    best = float("inf")
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    from afo_mj.app.design import design as run_design
    from afo_mj.design.system_design import guideline_studies, load_requirements, size_system
    hafo = load_requirements(ROOT / "scenarios" / "design" / "hafo_requirements.toml")
    gait = load_requirements(ROOT / "scenarios" / "design" / "gait_assist_requirements.toml")
    size_system(hafo)                                   # warm-up
    res = size_system(hafo)
    t_hafo = best_of(lambda: size_system(hafo), repeats)
    res_g = size_system(gait)
    t_gait = best_of(lambda: size_system(gait), max(1, repeats - 1))
    t_study = best_of(lambda: guideline_studies(hafo), 1)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        out = run_design(ROOT / "scenarios" / "design" / "hafo_requirements.toml",
                         Path(tmp) / "design")
        t_run = time.perf_counter() - t0
    best = out.summary.best
    print(f"size_system, HAFO corner (13.8 MPa): {t_hafo:.2f} s, {res.screened} designs "
          f"screened, best {best.total_kg:.3f} kg")
    print(f"size_system, normative gait profile over 5-21 MPa: {t_gait:.2f} s, "
          f"{res_g.screened} designs screened, best {res_g.row(0)['total_kg']:.3f} kg")
    print(f"guideline studies (8 pressures, 3 oils, 5 output powers): {t_study:.2f} s")
    print(f"afo-mj design (app.design.design, every file): {t_run:.2f} s; target <= {TARGET_S:g} s "
          f"-> {'met' if t_run <= TARGET_S else 'MISSED'}")
    print(json.dumps({"benchmark": "design", "size_system_hafo_s": round(t_hafo, 3),
                      "designs_screened_hafo": res.screened,
                      "size_system_gait_profile_s": round(t_gait, 3),
                      "designs_screened_gait_profile": res_g.screened,
                      "guideline_studies_s": round(t_study, 3),
                      "run_design_s": round(t_run, 3), "target_s": TARGET_S,
                      "best_total_kg": round(best.total_kg, 4),
                      "predicted_stall_torque_nm": round(
                          out.summary.predicted_bench.stall_torque_nm, 3),
                      "predicted_no_load_speed_deg_s": round(
                          out.summary.predicted_bench.no_load_speed_deg_s, 3)}))


if __name__ == "__main__":
    main()
