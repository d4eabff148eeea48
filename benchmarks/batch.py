"""Throughput of many walks at once (issue 21): a batch of healthy walks on 1 worker and on
every core, and the speed-up.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/batch.py [walks] [strides]`` (defaults 8
walks of 10 strides). The walks are ``scenarios/walk_healthy.toml`` with the ankle servo's
stiffness spread over 250–350 N·m/rad (different parameters, as a study would run them),
through :func:`afo_mj.experiments.batch.walk_batch`; each batch's wall time includes starting
its workers. Two kinds of batch: each walk returning its gait summary (the analysis computed
in the worker, what studies keep) and each returning its whole GaitRecord (~5 MB for 10
strides, sent back through a pipe: the transfer is the parallel batch's overhead). The
results of the 1-worker and the parallel batch must be equal bit for bit (checked). Target
(issue 21): with 2 workers on 2 cores, ≥ 1.8 × one core's throughput. The last line is a
JSON object.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from types import MappingProxyType

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    walks = int(sys.argv[1]) if len(sys.argv) > 1 else 8
    strides = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    os.environ.setdefault("MUJOCO_GL", "egl")
    import numpy as np
    from afo_mj.experiments.batch import default_workers, walk_batch
    from afo_mj.scenarios.walk_scenario import load_scenario

    base = load_scenario(ROOT / "scenarios" / "walk_healthy.toml",
                         [f"gait.strides={strides}",
                          f"gait.analyse_strides=[{max(2, strides - 6)}, {strides}]"])
    kps = np.linspace(250.0, 350.0, walks)
    scenarios = [dataclasses.replace(base, controller=MappingProxyType(
        dict(base.controller, ankle_kp_nm_per_rad=float(kp)))) for kp in kps]
    walk_batch(scenarios[:1], workers=1, result="summary")   # compile / load the kernels
    cores = default_workers()
    res = {}
    for kind in ("summary", "record"):
        out, got = {}, {}
        for workers in (1, cores):
            t0 = time.perf_counter()
            got[workers] = walk_batch(scenarios, workers=workers, result=kind)
            wall = time.perf_counter() - t0
            out[workers] = {"wall_s": round(wall, 3),
                            "walks_per_min": round(60 * walks / wall, 1)}
            print(f"{kind:7s} {workers} worker(s): {walks} walks of {strides} strides in "
                  f"{wall:.2f} s = {out[workers]['walks_per_min']:.1f} walks/min")
        if kind == "record":
            same = all(np.array_equal(a.qpos, b.qpos) for a, b in zip(got[1], got[cores]))
        else:
            same = json.dumps(got[1], sort_keys=True) == json.dumps(got[cores], sort_keys=True)
        if not same:
            raise AssertionError(f"the {kind} batches differ: a walk is not deterministic")
        speedup = out[cores]["walks_per_min"] / out[1]["walks_per_min"]
        print(f"{kind:7s} speed-up with {cores} workers: {speedup:.2f} (target >= 1.8 on 2 "
              f"cores: {'met' if speedup >= 1.8 else 'MISSED'}); results equal: {same}")
        res[kind] = {"one_worker": out[1], "all_workers": out[cores],
                     "speedup": round(speedup, 3), "results_equal": same}
    print(json.dumps({"benchmark": "batch", "walks": walks, "strides": strides,
                      "cores": cores, **res, "target_speedup": 1.8}))


if __name__ == "__main__":
    main()
