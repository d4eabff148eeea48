"""Generated circuits: cold compile, cached start, and the cost of a generated HAFO in gait.

* cold compile: a fresh process with an empty circuit cache builds the HAFO_GAIT description
  (code generation, numba compilation of the module) and runs one coupled step;
* cached start: a second fresh process with the same cache directory does the same (the
  module text and numba's machine code are loaded from disk);
* walking (``scenarios/gait_assist_hafo.toml``, assist condition, 10 strides, in this
  process, alternated, medians over the repeats): µs per 1 ms step of the bare walker, of the
  walker coupled to the hand-written HAFO kernel the circuit replaced (kept as the tests'
  reference: ``tests/kernel_reference``, :class:`kernel_devices.HafoKernelDevice`),
  and of the walker coupled to the generated circuit of the same preset
  (:class:`afo_mj.circuits.device.CircuitDevice` with :func:`afo_mj.devices.hafo.hafo_circuit`),
  both with the device log on. Issue 18: the generated kernel must be no slower than the
  hand-written one (coupled/bare 1.79 when the issue was written).

Run: ``.venv/bin/python benchmarks/circuits.py [repeats]``; the last line is a JSON object.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "gait_assist_hafo.toml"

_START = """
import time, numpy as np
t0 = time.perf_counter()
from afo_mj.devices.hafo import HAFO_GAIT, hafo_circuit
from afo_mj.circuits.device import CircuitDevice
t1 = time.perf_counter()
dev = CircuitDevice(hafo_circuit(HAFO_GAIT), torque_fn=lambda *a: -10.0)
dev.begin_step(0.0, np.zeros(2), np.zeros(2), np.zeros(2, dtype=bool))
dev.end_step(np.zeros(2))
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def _start(cache: str) -> tuple[float, float]:
    env = dict(os.environ, AFO_MJ_CACHE_DIR=cache)
    out = subprocess.run([sys.executable, "-c", _START], env=env, capture_output=True,
                         text=True, check=True)
    imp, build = (float(x) for x in out.stdout.split()[-2:])
    return imp, build


def main(repeats: int = 5) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        cold_import, cold = _start(cache)
        warm_import, warm = _start(cache)

    from afo_mj.circuits.device import CircuitDevice
    from afo_mj.devices.hafo import HafoDevice, hafo_circuit
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from kernel_reference.kernel_devices import HafoKernelDevice
    from afo_mj.gait.walk import run_walk
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario
    sc = load_scenario(SCENARIO)
    cfg = device_config(sc)
    ref = sc.load_reference()
    T, dt = sc.cycle_time_s(ref), sc.walker.timestep_s
    steps = int(((sc.strides + 1.5) * T + 1.0) / dt) + 4
    compiled = CircuitDevice(hafo_circuit(cfg.params), timestep_s=dt).cc

    def walk(make):
        dev = make() if make else None
        worn = HafoDevice(cfg.params, sides=cfg.sides).worn_masses() if make else ()
        t0 = time.perf_counter()
        rec = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(),
                       worn_masses=worn, device=dev)
        return (time.perf_counter() - t0) / len(rec.time_s) * 1e6

    def old():
        return HafoKernelDevice(cfg.params, sides=cfg.sides, profile=cfg.profile,
                                timestep_s=dt, max_steps=steps)

    def new():
        return CircuitDevice(compiled, sides=cfg.sides, profile=cfg.profile, timestep_s=dt,
                             max_steps=steps)

    for m in (None, old, new):               # warm-up (numba caches)
        walk(m)
    bare, hand, gen = [], [], []
    for _ in range(repeats):
        bare.append(walk(None))
        hand.append(walk(old))
        gen.append(walk(new))
    b, h, g = (statistics.median(x) for x in (bare, hand, gen))
    result = {
        "cold_compile_s": round(cold, 2), "cold_import_s": round(cold_import, 2),
        "cached_start_s": round(warm, 3), "cached_import_s": round(warm_import, 2),
        "bare_us_per_step": round(b, 2), "hand_written_us_per_step": round(h, 2),
        "generated_us_per_step": round(g, 2),
        "ratio_hand_written": round(h / b, 3), "ratio_generated": round(g / b, 3),
        "generated_over_hand_written": round(g / h, 3),
        "repeats": repeats, "scenario": SCENARIO.name, "preset": cfg.preset,
        "states": len(compiled.state_names),
    }
    print(f"HAFO_GAIT circuit ({len(compiled.state_names)} states):")
    print(f"  cold compile (empty cache, build + first step): {cold:6.2f} s "
          f"(imports {cold_import:.2f} s)")
    print(f"  cached start (same cache, new process):         {warm:6.3f} s "
          f"(imports {warm_import:.2f} s)")
    print(f"{SCENARIO.name}, assist, {sc.strides} strides, median of {repeats}:")
    print(f"  bare walker:                 {b:6.1f} us/step")
    print(f"  hand-written HAFO kernel:    {h:6.1f} us/step (ratio {h / b:.2f})")
    print(f"  generated HAFO circuit:      {g:6.1f} us/step (ratio {g / b:.2f})")
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
