"""Cost of the HAFO device alone in a walk: its two compiled calls per step, without MuJoCo.

``scenarios/gait_assist_hafo.toml`` (assist condition, 10 strides) is walked once with the
device coupled, recording what the walker hands the device each step (time, ankle angles and
velocities, stance, and the velocities MuJoCo produced); that sequence is then replayed through
a fresh :class:`afo_mj.devices.hafo.HafoDevice` (``begin_step`` / ``end_step``, the device log
on), which reproduces the walk's device exactly (the replayed ledger's input energy is checked
against the walk's to 1e-9). Printed: µs per step of the replay (minimum and median over the
repeats), of the same Python loop calling two empty compiled functions with the same
arguments (the loop and call overhead), the difference (the compiled device work), and the
right-hand-side evaluations per step counted by the ledger's Newton figures.

Run: ``.venv/bin/python benchmarks/device_replay.py [repeats]``; the last line is a JSON object.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

import numba  # noqa: E402

from afo_mj.devices.hafo import HafoDevice  # noqa: E402
from afo_mj.gait.walk import run_walk  # noqa: E402
from afo_mj.scenarios.device_scenario import device_config  # noqa: E402
from afo_mj.scenarios.walk_scenario import load_scenario  # noqa: E402

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "gait_assist_hafo.toml"


def record_walk():
    """Walk once; returns the per-step device inputs, the device settings and its ledger."""
    sc = load_scenario(SCENARIO)
    cfg = device_config(sc)
    ref = sc.load_reference()
    T, dt = sc.cycle_time_s(ref), sc.walker.timestep_s
    steps = int(((sc.strides + 1.5) * T + 1.0) / dt) + 4
    dev = HafoDevice(cfg.params, sides=cfg.sides, profile=cfg.profile, timestep_s=dt,
                     max_steps=steps)
    rows, held = [], {}
    begin, end = dev.begin_step, dev.end_step

    def rec_begin(t, a, v, s):
        held["b"] = (t, a[0], a[1], v[0], v[1], s[0], s[1])
        return begin(t, a, v, s)

    def rec_end(v):
        rows.append(held["b"] + (v[0], v[1]))
        return end(v)

    dev.begin_step, dev.end_step = rec_begin, rec_end
    # the Python loop calls begin_step / end_step (the compiled loop calls the device's C
    # entry points directly, so these wrappers would see nothing); the record is the same
    run_walk(sc.walker, ref, T, sc.strides, sc.controller_params(),
             worn_masses=dev.worn_masses(), device=dev, loop="python")

    def make():
        return HafoDevice(cfg.params, sides=cfg.sides, profile=cfg.profile,
                          timestep_s=dt, max_steps=len(rows) + 2)

    return np.array(rows), make, dev.ledger(0), dt


def replay(rows, dev, begin, end) -> float:
    """Seconds to drive ``begin``/``end`` through the recorded rows."""
    a, v, s, vn = np.zeros(2), np.zeros(2), np.zeros(2, dtype=bool), np.zeros(2)
    t0 = time.perf_counter()
    for r in rows:
        a[0], a[1], v[0], v[1], s[0], s[1] = r[1], r[2], r[3], r[4], r[5], r[6]
        begin(r[0], a, v, s)
        vn[0], vn[1] = r[7], r[8]
        end(vn)
    return time.perf_counter() - t0


@numba.njit
def _empty_begin(t, a, v, s, buf, meta):
    return None


@numba.njit
def _empty_end(v, buf, meta, log, k, t):
    return 1


def main(repeats: int = 5) -> dict:
    rows, make, walk_ledger, dt = record_walk()
    n = len(rows)
    timed, dev = [], None
    for i in range(repeats + 1):
        dev = make()
        w = replay(rows, dev, dev.begin_step, dev.end_step)
        if i:                                   # the first replay warms up
            timed.append(w / n * 1e6)
    led = dev.ledger(0)
    if abs(led["input_j"] - walk_ledger["input_j"]) > 1e-9 * max(1.0, abs(walk_ledger["input_j"])):
        raise AssertionError(f"the replay is not the walk: input {led['input_j']} J against "
                             f"{walk_ledger['input_j']} J")
    # the loop and call overhead: the same loop calling two empty compiled functions
    buf, meta, log = dev._buf, dev._meta, dev._log_data
    k = [0]

    def e_begin(t, a, v, s):
        _empty_begin(t, a, v, s, buf, meta)

    def e_end(v):
        k[0] += 1
        return _empty_end(v, buf, meta, log, k[0], 0.0)

    replay(rows[:10], None, e_begin, e_end)
    overhead = min(replay(rows, None, e_begin, e_end) for _ in range(3)) / n * 1e6
    best, med = min(timed), statistics.median(timed)
    newton = led["newton_iterations"] / n
    result = {"steps": n, "replay_us_per_step": round(best, 2),
              "replay_median_us_per_step": round(med, 2),
              "loop_and_call_overhead_us_per_step": round(overhead, 2),
              "compiled_device_us_per_step": round(best - overhead, 2),
              "newton_iterations_per_step": round(newton, 3),
              "substepped_steps": led["substepped_steps"], "repeats": repeats,
              "scenario": SCENARIO.name}
    print(f"{SCENARIO.name}, assist, {n} steps of {dt * 1e3:g} ms replayed through a fresh "
          f"HafoDevice (device log on), {repeats} repeats:")
    print(f"  replay:                        {best:6.2f} us/step (median {med:.2f})")
    print(f"  loop + two empty compiled calls: {overhead:4.2f} us/step")
    print(f"  compiled device work:          {best - overhead:6.2f} us/step "
          f"({newton:.2f} Newton iterations per step)")
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
