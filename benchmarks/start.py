"""Cold and cached start of a run (issue 21): wall time of whole ``afo-mj run`` commands.

Run: ``.venv/bin/python benchmarks/start.py``. For ``scenarios/walk_healthy.toml`` (the
walker alone) and ``scenarios/gait_assist_hafo.toml`` (walker and HAFO circuit, two
conditions), each in a fresh process:

* cold: empty numba cache and generated-circuit cache (``NUMBA_CACHE_DIR``,
  ``AFO_MJ_CACHE_DIR`` pointed at new temporary folders): every kernel is compiled (the
  walking controller, the compiled walk loop, the circuit's kernel and its C entry points);
* cached: the same command again, everything loaded from those caches.

The command is the user's, figures included. Target (issue 21): a cached start ≤ 3 s (the
healthy walk). The last line is a JSON object.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
AFO_MJ = str(Path(sys.executable).with_name("afo-mj"))


def _run(scenario: str, env: dict, out: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([AFO_MJ, "run", str(ROOT / "scenarios" / scenario), "--out", str(out),
                    "--quiet"], env=env, check=True,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    res = {}
    for scenario in ("walk_healthy.toml", "gait_assist_hafo.toml"):
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"),
                       NUMBA_CACHE_DIR=str(Path(tmp) / "numba"),
                       AFO_MJ_CACHE_DIR=str(Path(tmp) / "afo"))
            cold = _run(scenario, env, Path(tmp) / "a")
            cached = min(_run(scenario, env, Path(tmp) / f"b{k}") for k in range(2))
        res[scenario] = {"cold_s": round(cold, 2), "cached_s": round(cached, 2)}
        print(f"{scenario:24s} cold {cold:6.1f} s, cached {cached:5.1f} s (whole afo-mj run)")
    ok = res["walk_healthy.toml"]["cached_s"] <= 3.0
    print(f"cached start of the healthy walk <= 3 s: {'met' if ok else 'MISSED'}")
    print(json.dumps({"benchmark": "start", **res, "target_cached_s": 3.0,
                      "cached_target_met": ok}))


if __name__ == "__main__":
    main()
