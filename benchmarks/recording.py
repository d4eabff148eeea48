"""Size of a typical rerun recording and the time rerun's web viewer takes to load it, in a
real browser (headless Chromium).

The typical run: ``scenarios/gait_assist_hafo.toml`` at its default strides (three conditions,
``no_device``, ``transparent``, ``assist``, side by side, about 13 s of walking, every device
signal). It is simulated once and recorded twice: as ``afo-mj run --rrd`` records it (signals
thinned to :data:`afo_mj.outputs.recording.SIGNAL_TOLERANCE` of their range) and with every
signal sample kept (``signal_tolerance=0``: the signal content recordings had before the
thinning). Each file is opened the way ``afo-mj view FILE --web`` opens it (``rerun
--serve-web FILE``, rerun's own web viewer served by the pinned rerun-sdk, renderer WebGL on
Chromium's software rasteriser) and timed by ``tools/rerun_web.py``: ``viewer_start_s`` from
navigation until the viewer's WebAssembly app runs, ``load_s`` from navigation until every
chunk of the file is in the viewer's store (an end marker appended to a copy of the file
shows up in the viewer's state), ``data_s`` the difference (what the recording itself costs),
and the page's main-thread CPU time by then (``task_cpu_s``; ``script_cpu_s`` of it JavaScript
and WebAssembly), which other load on the machine blurs less than the wall-clock times.
Medians over ``--repeats`` loads (the wall-clock times vary by 2× from run to run on a busy
2-core machine).
A screenshot of the loaded viewer is saved beside the JSON (``--shots DIR``).

Needs Chromium (Debian: ``apt-get install -y chromium``); nothing is downloaded.
Run: ``.venv/bin/python benchmarks/recording.py [--repeats N] [--shots DIR]``; the last line
is a JSON object. The figures depend on the machine's CPU (the viewer decodes and indexes the
data on one browser thread); README's "Viewing a recording" quotes them for this 2-core one.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import rerun_web as web  # noqa: E402

from afo_mj.app.run import record_run, run_scenario  # noqa: E402
from afo_mj.outputs.recording import write_recording  # noqa: E402

SCENARIO = ROOT / "scenarios" / "gait_assist_hafo.toml"


def _rows(path: Path) -> int:
    import rerun as rr
    store = rr.chunk.RrdReader(str(path)).stream().collect()
    return sum(ch.num_rows for ch in store.stream())


def _time_load(path: Path, work: Path, repeats: int, shot: Path | None) -> dict:
    marked = web.with_end_marker(path, work / f"{path.stem}.marked.rrd")
    runs = []
    for k in range(repeats):
        with web.serve(marked) as url:
            runs.append(web.open_and_time(url, screenshot=shot if k == 0 else None))
    if any(r["timed_out"] for r in runs):
        raise SystemExit(f"{path.name}: the viewer did not finish loading: {runs}")
    load = [r["loaded_s"] for r in runs]
    data = [r["loaded_s"] - r["started_s"] for r in runs]
    return {"load_s": statistics.median(load), "data_s": statistics.median(data),
            "viewer_start_s": statistics.median(r["started_s"] for r in runs),
            "task_cpu_s": statistics.median(r["task_cpu_s"] for r in runs),
            "script_cpu_s": statistics.median(r["script_cpu_s"] for r in runs),
            "load_all_s": load}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--shots", type=Path, default=None,
                    help="folder for a screenshot of each loaded recording")
    args = ap.parse_args(argv)
    web.chromium_path()                             # refuse early without a browser
    work = Path(tempfile.mkdtemp(prefix="afo_mj_recview_"))
    if args.shots:
        args.shots.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        res = run_scenario(SCENARIO, out_dir=work / "results", figures=False)
        sim_s = time.perf_counter() - t0
        files = {"thinned": work / "thinned.rrd", "every_sample": work / "every_sample.rrd"}
        t0 = time.perf_counter()
        record_run(res, files["thinned"])             # as afo-mj run --rrd writes it
        write_s = time.perf_counter() - t0
        sc = res.scenario
        write_recording(files["every_sample"], res.recorded_runs(), res.reference,
                        title=sc.name, signal_rate_hz=sc.record_signal_rate_hz,
                        transform_rate_hz=sc.record_transform_rate_hz, signal_tolerance=0.0)
        out: dict = {"benchmark": "recording", "scenario": SCENARIO.name,
                     "simulated_s": float(max(r.record.time_s[-1]
                                              for r in res.recorded_runs())),
                     "runs": [r.name for r in res.recorded_runs()], "simulate_s": sim_s,
                     "write_recording_s": write_s, "repeats": args.repeats, "files": {}}
        for key, path in files.items():
            shot = args.shots / f"{key}.png" if args.shots else None
            entry = {"mb": path.stat().st_size / 1e6, "rows": _rows(path)}
            entry.update(_time_load(path, work, args.repeats, shot))
            out["files"][key] = entry
            print(f"{key:13s} {entry['mb']:6.2f} MB, {entry['rows']:7d} rows: web viewer loaded "
                  f"in {entry['load_s']:5.1f} s from navigation ({entry['viewer_start_s']:.1f} s "
                  f"app start + {entry['data_s']:.1f} s data); page CPU "
                  f"{entry['task_cpu_s']:.1f} s (script {entry['script_cpu_s']:.1f} s)",
                  flush=True)
        a, b = out["files"]["thinned"], out["files"]["every_sample"]
        out["size_ratio"] = a["mb"] / b["mb"]
        out["data_time_ratio"] = a["data_s"] / b["data_s"]
        out["cpu_ratio"] = a["task_cpu_s"] / b["task_cpu_s"]
        print(f"thinned / every sample: size {out['size_ratio']:.2f}, data load time "
              f"{out['data_time_ratio']:.2f}, page CPU {out['cpu_ratio']:.2f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return out


if __name__ == "__main__":
    print(json.dumps(main()))
