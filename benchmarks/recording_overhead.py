"""Cost of a rerun recording: wall time of ``afo-mj run`` with ``--rrd`` against the same run
without it.

Each scenario is run through the command-line entry point (:func:`afo_mj.cli.main`) in this
process, recorded and unrecorded alternately so both see the same machine load, after one
untimed warm-up of each (numba's cache, imports, rerun's start-up). What a run costs includes
the simulation, the gait analysis, the figures and the results directory; the recorded run
adds :func:`afo_mj.outputs.recording.write_recording` (3D replay of every body, every signal
column-wise, the blueprint, the file). Scenarios: ``walk_healthy`` (no device, 10 strides) and
``gait_assist_hafo`` (three conditions, 10 strides each, every device signal).

Target: recorded ≤ 1.25 × unrecorded (median over repeats). The run-to-run difference is
blurred by the machine's load, so the recorder's own time (``write_recording`` timed inside
the recorded runs) is reported beside it as a fraction of the unrecorded run; the target is
checked on the worse of the two. Prints the figures; the last line
is a JSON object.
Run: ``.venv/bin/python benchmarks/recording_overhead.py [repeats]`` (the recording's size and
the viewer's load time: ``benchmarks/recording.py``)
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import afo_mj.outputs.recording as recording  # noqa: E402
from afo_mj.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("walk_healthy", "gait_assist_hafo")
TARGET_OVERHEAD = 0.25
_RECORDING_S: list[float] = []
_write = recording.write_recording


def _timed_write(*a, **k):
    """write_recording, timed: its own cost, which the machine's load blurs less than the
    difference of two whole runs."""
    t0 = time.perf_counter()
    try:
        return _write(*a, **k)
    finally:
        _RECORDING_S.append(time.perf_counter() - t0)


recording.write_recording = _timed_write


def _run(scenario: str, work: Path, record: bool) -> float:
    out = work / f"{scenario}_{'rec' if record else 'plain'}"
    args = ["run", str(ROOT / "scenarios" / f"{scenario}.toml"), "--out", str(out)]
    if record:
        args += ["--rrd", str(work / f"{scenario}.rrd")]
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        rc = main(args)
    wall = time.perf_counter() - t0
    if rc != 0:
        raise SystemExit(f"afo-mj {' '.join(args)} failed (exit {rc})")
    return wall


def main_bench(repeats: int = 3) -> dict:
    work = Path(tempfile.mkdtemp(prefix="afo_mj_recbench_"))
    result: dict = {"benchmark": "recording", "repeats": repeats,
                    "target_overhead": TARGET_OVERHEAD, "scenarios": {}}
    try:
        for sc in SCENARIOS:
            _run(sc, work, False)
            _run(sc, work, True)                        # warm-up of both paths
            plain, rec = [], []
            _RECORDING_S.clear()
            for _ in range(repeats):
                plain.append(_run(sc, work, False))
                rec.append(_run(sc, work, True))
            mp, mr = statistics.median(plain), statistics.median(rec)
            size = (work / f"{sc}.rrd").stat().st_size
            over = mr / mp - 1.0
            own = statistics.median(_RECORDING_S)
            result["scenarios"][sc] = {"unrecorded_s": mp, "recorded_s": mr,
                                       "overhead": over, "recording_s": own,
                                       "recording_fraction": own / mp, "rrd_mb": size / 1e6,
                                       "unrecorded_min_s": min(plain),
                                       "recorded_min_s": min(rec)}
            print(f"{sc:18s} unrecorded {mp:6.2f} s (min {min(plain):.2f}), recorded "
                  f"{mr:6.2f} s (min {min(rec):.2f}): overhead {100 * over:+5.1f} % "
                  f"(target ≤ {100 * TARGET_OVERHEAD:.0f} %); write_recording itself {own:.2f} s "
                  f"= {100 * own / mp:.1f} % of the unrecorded run; file {size / 1e6:.1f} MB")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    # the worse of the two measures of the cost: whole-run difference and own time
    worst = max(max(v["overhead"], v["recording_fraction"])
                for v in result["scenarios"].values())
    result["worst_overhead"] = worst
    result["meets_target"] = worst <= TARGET_OVERHEAD
    return result


if __name__ == "__main__":
    r = main_bench(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
    print(json.dumps(r))
