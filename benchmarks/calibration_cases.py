"""Cost of the calibration acceptance cases (tests/test_calibration.py), one at a time.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/calibration_cases.py [case ...]`` (default:
``hafo-piston_leakage valve-spool_lag``; ``all`` runs the 13 cases). Each case writes the
test's synthetic bench record (6 s, the test's mismatch and seed) and calibrates it on one
core (threads pinned to one before anything is imported; a warm-up replay of each circuit
first, so numba's compilation, a one-off per machine, is not counted). Prints per case the
wall time, the replays, the verdict and the effects found; the last line is a JSON object.
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

ROOT = Path(__file__).resolve().parents[1]
# this checkout's afo_mj (and tests), not whichever one the environment has installed
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]


def cases() -> dict[str, tuple]:
    """name → (kind, effects, extra generate_record arguments), as the acceptance test."""
    import test_calibration as tc
    out = {f"{k}-{e}": (k, {e: v}, {}) for k, e, v in tc.SINGLE}
    out["pair"] = (tc.PAIR[0], tc.PAIR[1], {})
    out["mismatch_only"] = ("hafo", {}, {})
    out["resonance"] = ("hafo", {}, {"torque_sensor_resonance_hz": 25.0})
    return out


def main() -> None:
    names = sys.argv[1:] or ["hafo-piston_leakage", "valve-spool_lag"]
    from afo_mj.calibration.calibrate import calibrate
    from afo_mj.calibration.synthetic_records import generate_record
    import test_calibration as tc

    table = cases()
    if names == ["all"]:
        names = list(table)
    bad = [n for n in names if n not in table]
    if bad:
        raise SystemExit(f"unknown case(s) {bad}; allowed: all, {', '.join(table)}")
    warnings.simplefilter("ignore")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in sorted({table[n][0] for n in names}):     # compile outside the timing
            generate_record(Path(tmp) / f"warm-{kind}.csv", kind, duration_s=2.0)
        for name in names:
            kind, effects, extra = table[name]
            t0 = time.perf_counter()
            data = generate_record(Path(tmp) / f"{name}.csv", kind, effects=effects,
                                   mismatch=tc.MISMATCH, duration_s=tc.DURATION_S, seed=7,
                                   **extra)
            rep = calibrate(data)
            wall = time.perf_counter() - t0
            found = [s["effect"] for s in rep["effects_selected"]]
            rows.append({"case": name, "wall_s": round(wall, 2),
                         "replays": int(rep["evaluations"]), "verdict": rep["verdict"],
                         "effects": found,
                         "error_drop": round(1.0 - rep["error_after"]["overall"]
                                             / rep["error_before"]["overall"], 4)})
            print(f"{name:40s} {wall:6.1f} s  {rep['evaluations']:4d} replays  "
                  f"{rep['verdict']}  {found}", flush=True)
    total = sum(r["wall_s"] for r in rows)
    print(f"total {total:.1f} s on one core, {sum(r['replays'] for r in rows)} replays")
    print(json.dumps({"benchmark": "calibration_cases", "total_wall_s": round(total, 2),
                      "cases": rows}))


if __name__ == "__main__":
    main()
