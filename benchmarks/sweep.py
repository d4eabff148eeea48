"""Throughput of ``afo-mj sweep``: runs per minute with 1 and 2 local workers, and the speed-up.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/sweep.py [runs] [strides]``. A gait study
(the healthy walk, ``strides`` strides, default 10 as in the shipped scenario, ``runs``
Latin-hypercube points over the ankle controller's stiffness, default 32) is swept twice into
fresh directories, with 1 and with 2 worker processes (each sweep's wall time includes starting
its workers). Since points run in-process without figures (issue 19) a 4-stride walk takes
~0.13 s, so a handful of short runs measures worker start-up more than throughput.
Target (issue 8): speed-up ≥ 1.7 with 2 workers on a 2-core machine. The last line is a JSON object.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 32
    strides = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    os.environ.setdefault("MUJOCO_GL", "egl")
    from afo_mj.studies.study import load_study
    from afo_mj.app.sweep_point import run_point
    from afo_mj.studies.sweep import Sweep

    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "bench_study.toml"
        f.write_text(
            f'name = "bench"\ndescription = "sweep benchmark"\n'
            f'scenario = "{(ROOT / "scenarios" / "walk_healthy.toml").as_posix()}"\n'
            f'set = ["gait.strides={strides}", '
            f'"gait.analyse_strides=[{max(2, strides - 6)}, {strides}]"]\n'
            f'[design]\nkind = "lhs"\nsamples = {runs}\nseed = 0\n'
            '[[parameter]]\nkey = "controller.ankle_kp_nm_per_rad"\nrange = [250.0, 350.0]\n')
        study = load_study(f)
        out = {}
        for workers in (1, 2):
            t0 = time.perf_counter()
            rows = Sweep(study, Path(tmp) / f"w{workers}", workers=workers,
                         progress=False, runner=run_point).run()
            wall = time.perf_counter() - t0
            ok = sum(r["status"] == "ok" for r in rows)
            out[workers] = {"wall_s": wall, "runs": len(rows), "ok": ok,
                            "runs_per_min": 60.0 * len(rows) / wall,
                            "mean_run_s": sum(r["wall_time_s"] for r in rows) / len(rows)}
            print(f"{workers} worker(s): {len(rows)} runs ({ok} ok) in {wall:.1f} s = "
                  f"{out[workers]['runs_per_min']:.1f} runs/min "
                  f"(mean run {out[workers]['mean_run_s']:.2f} s)")
    speedup = out[2]["runs_per_min"] / out[1]["runs_per_min"]
    print(f"speed-up with 2 workers: {speedup:.2f} "
          f"(target >= 1.7: {'met' if speedup >= 1.7 else 'MISSED'}); "
          f"{os.cpu_count()} cores")
    print(json.dumps({"benchmark": "sweep", "runs": runs, "strides": strides,
                      "cores": os.cpu_count(),
                      "runs_per_min_1": round(out[1]["runs_per_min"], 2),
                      "runs_per_min_2": round(out[2]["runs_per_min"], 2),
                      "speedup": round(speedup, 3), "target": 1.7, "met": speedup >= 1.7}))


if __name__ == "__main__":
    main()
