"""Cost of one coupled 1 ms step of the valve-controlled / digital-valve orthosis on the stand.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/valve_step.py``. For every preset of
:data:`afo_mj.devices.valve_afo.VALVE_PRESETS`: wall time per step (MuJoCo stand + device, one
side) of a 2 s imposed-sinusoid run with a 0 → 40 N·m torque command (after a warm-up run that
compiles and caches the kernel), the share of steps re-done in sub-steps, Newton iterations
per step and the ledger's relative balance error. The last line is a JSON object.
"""

from __future__ import annotations

import json
import math
import time

from afo_mj.devices.valve_afo import VALVE_PRESETS, ValveAfoDevice
from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad


def run(preset: str, duration_s: float = 2.0, timestep_s: float = 1e-3) -> dict:
    f = 1.0
    stand = AnkleTestStand(load=StandLoad(kind="imposed",
                                          trajectory=ImposedTrajectory.sinusoid(0.25, f)),
                           timestep_s=timestep_s)
    dev = ValveAfoDevice(VALVE_PRESETS[preset], timestep_s=timestep_s,
                         torque_fn=lambda t, q, v: -20.0 * (1.0 - math.cos(2 * math.pi * f * t)))
    n = int(round(duration_s / timestep_s))
    t0 = time.perf_counter()
    stand.run_device(dev, duration_s)
    wall = time.perf_counter() - t0
    led = dev.ledger()
    return {"us_per_step": round(wall / n * 1e6, 1),
            "substepped_fraction": round(led["substepped_steps"] / n, 4),
            "newton_iterations_per_step": round(led["newton_iterations"] / n, 2),
            "balance_error_rel": float(f"{led['balance_error_rel']:.3g}")}


def main() -> None:
    run("valve", 0.05)                      # warm-up: compile / load the kernel cache
    result = {}
    for preset in VALVE_PRESETS:
        r = run(preset)
        result[preset] = r
        print(f"{preset:24s} {r['us_per_step']:7.1f} us/step  substepped "
              f"{100 * r['substepped_fraction']:5.1f} %  "
              f"Newton {r['newton_iterations_per_step']:.2f}/step  "
              f"balance {r['balance_error_rel']:.1e}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
