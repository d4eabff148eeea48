"""Cost of a whole calibration: a 20 s bench record at 1 kHz, the full effect library, one core.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/calibrate.py [duration_s] [kind]``. Writes a
synthetic HAFO bench record (``afo_mj.calibration.synthetic_records``, default 20 s at 1 kHz) with
one undeclared effect (piston leakage) and a declared-parameter mismatch, then runs
``calibrate`` on it with every candidate of the library (target: ≤ 120 s on one core, issue 7).
Threads are pinned to one (``NUMBA_NUM_THREADS``, BLAS) before anything is imported, and a
warm-up replay compiles the kernels first (numba's cache makes that a one-off per machine).
Prints the wall time, the number of replays, the cost per replay, the verdict and the held-out
error drop; the last line is a JSON object.
"""

from __future__ import annotations

import os

for _v in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"

import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402


def main() -> None:
    duration = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
    kind = sys.argv[2] if len(sys.argv) > 2 else "hafo"
    from afo_mj.calibration.calibrate import CalibrationOptions, calibrate
    from afo_mj.calibration.synthetic_records import generate_record
    from afo_mj.experiments.bench_replay import BenchReplay

    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        data = generate_record(Path(tmp) / "bench.csv", kind,
                               effects={"piston_leakage": {"leakage_conductance_m3": 1.5e-14}},
                               mismatch={"seal_coulomb_force_n": 1.5,
                                         "liquid_bulk_modulus_pa": 0.8},
                               duration_s=duration, fs_hz=1000.0, seed=3)
        rep = BenchReplay(data.source["preset"])
        inputs = {c: data.channels[c] for c in rep.check_inputs(data.channels)}
        rep.simulate(data.time_s[:50], {c: v[:50] for c, v in inputs.items()})  # compile
        t0 = time.perf_counter()
        rep.simulate(data.time_s, inputs)
        replay_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        report = calibrate(data, options=CalibrationOptions())
        wall = time.perf_counter() - t0
    n_cand = len(report["candidates"])
    print(f"record: {kind}, {duration:g} s at 1 kHz ({data.n_samples} samples), "
          f"{len(report['outputs'])} outputs, {n_cand} candidate effects")
    print(f"one full replay: {replay_s * 1e3:.0f} ms")
    print(f"calibrate: {wall:.1f} s wall on one core, {report['evaluations']} replays "
          f"({wall / report['evaluations'] * 1e3:.0f} ms each incl. fitting overhead)")
    print(f"verdict {report['verdict']}, "
          f"effects {[s['effect'] for s in report['effects_selected']]}"
          f", held-out NRMSE {report['error_before']['overall']:.4f} -> "
          f"{report['error_after']['overall']:.4f}")
    print(f"target: <= 120 s -> {'met' if wall <= 120.0 else 'MISSED'}")
    print(json.dumps({"benchmark": "calibrate", "kind": kind, "duration_s": duration,
                      "samples": int(data.n_samples), "candidates": n_cand,
                      "wall_s": round(wall, 2), "replays": int(report["evaluations"]),
                      "replay_ms": round(replay_s * 1e3, 1), "verdict": report["verdict"],
                      "effects": [s["effect"] for s in report["effects_selected"]],
                      "error_before": report["error_before"]["overall"],
                      "error_after": report["error_after"]["overall"],
                      "target_s": 120.0, "met": bool(wall <= 120.0)}))


if __name__ == "__main__":
    main()
