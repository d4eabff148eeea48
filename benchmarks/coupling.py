"""Cost of the HAFO coupling: µs per 1 ms step, bare walker vs the full coupled run.

Both from ``scenarios/gait_assist_hafo.toml`` (healthy 75 kg walker, 10 strides), in the same
process, alternated so that both see the same machine load:

* bare: :func:`afo_mj.gait.walk.run_walk` with no device (the walker with its controllers and
  the recording of the GaitRecord; model build included);
* coupled: the scenario's ``assist`` condition as
  :func:`afo_mj.experiments.device_walk.run_device_scenario` runs it: the
  :class:`~afo_mj.devices.hafo.HafoDevice` built, the walker (with the device's worn masses)
  stepped with the HAFO hydraulics coupled implicitly each step (phase estimate, assistance
  profile, torque controller, pump/hose/cylinder model, device log), then the gait analysis
  and the condition's summary metrics.

numba is warmed up (compiled or loaded from its cache) by one untimed run of each before the
timed repeats; the figures are medians over the repeats (the minimum is printed beside).
Target: coupled ≤ 1.5 × bare. Prints the figures; the last line is a JSON object.
Run: ``.venv/bin/python benchmarks/coupling.py [repeats]``
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from afo_mj.metrics.gait_metrics import GaitAnalysisError, analyse_gait  # noqa: E402
from afo_mj.devices.hafo import HafoDevice  # noqa: E402
from afo_mj.gait.walk import run_walk  # noqa: E402
from afo_mj.experiments.device_walk import condition_summary, device_config  # noqa: E402
from afo_mj.scenarios.walk_scenario import load_scenario  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "gait_assist_hafo.toml"
TARGET_RATIO = 1.5


def _setup():
    sc = load_scenario(SCENARIO)
    cfg = device_config(sc)
    ref = sc.load_reference()
    return sc, cfg, ref, sc.cycle_time_s(ref), sc.walker.timestep_s


def bare_run(sc, ref, T) -> tuple[float, int]:
    """Wall seconds and steps of the walker alone."""
    t0 = time.perf_counter()
    rec = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params())
    return time.perf_counter() - t0, len(rec.time_s)


def coupled_run(sc, cfg, ref, T, dt) -> tuple[float, float, int]:
    """Wall seconds of the whole assist condition, of its walk alone, and its steps."""
    t0 = time.perf_counter()
    steps = int(((sc.strides + 1.5) * T + 1.0) / dt) + 4
    dev = HafoDevice(cfg.params, sides=cfg.sides, profile=cfg.profile, timestep_s=dt,
                     max_steps=steps)
    rec = run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(),
                   worn_masses=dev.worn_masses(), device=dev)
    t_walk = time.perf_counter() - t0
    try:
        analysis = analyse_gait(rec, ref, sc.analyse_strides)
    except GaitAnalysisError:
        analysis = None
    condition_summary(rec, analysis, dev, cfg, sc.analyse_strides)
    return time.perf_counter() - t0, t_walk, len(rec.time_s)


def main(repeats: int = 7) -> dict:
    sc, cfg, ref, T, dt = _setup()
    bare_run(sc, ref, T)                      # warm-up: numba compile / cache load
    coupled_run(sc, cfg, ref, T, dt)
    bare, coupled, walk_only = [], [], []
    n_bare = n_coupled = 0
    for _ in range(repeats):
        w, n_bare = bare_run(sc, ref, T)
        bare.append(w / n_bare * 1e6)
        w, w_walk, n_coupled = coupled_run(sc, cfg, ref, T, dt)
        coupled.append(w / n_coupled * 1e6)
        walk_only.append(w_walk / n_coupled * 1e6)
    b, c, cw = (statistics.median(x) for x in (bare, coupled, walk_only))
    ratio = c / b
    result = {
        "bare_us_per_step": round(b, 2),
        "coupled_us_per_step": round(c, 2),
        "ratio": round(ratio, 3),
        "target_ratio": TARGET_RATIO,
        "meets_target": ratio <= TARGET_RATIO,
        "coupled_walk_us_per_step": round(cw, 2),
        "coupled_metrics_us_per_step": round(c - cw, 2),
        "bare_min_us_per_step": round(min(bare), 2),
        "coupled_min_us_per_step": round(min(coupled), 2),
        "ratio_of_minima": round(min(coupled) / min(bare), 3),
        "bare_steps": n_bare,
        "coupled_steps": n_coupled,
        "repeats": repeats,
        "scenario": SCENARIO.name,
        "condition": "assist",
        "device_preset": cfg.preset,
    }
    print(f"{SCENARIO.name}: {sc.strides} strides, 1 ms step, median of {repeats} repeats "
          f"(minimum in brackets)")
    print(f"  bare walker (no device):      {b:6.1f} us/step ({min(bare):5.1f}), "
          f"{n_bare} steps")
    print(f"  coupled HAFO run (assist):    {c:6.1f} us/step ({min(coupled):5.1f}), "
          f"{n_coupled} steps")
    print(f"    of which walk + device:     {cw:6.1f} us/step, metrics {c - cw:4.1f} us/step")
    print(f"  ratio coupled / bare:         {ratio:6.2f} (target <= {TARGET_RATIO})")
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 7)
