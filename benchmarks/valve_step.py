"""Cost of one coupled 1 ms step of the valve-controlled / digital-valve orthosis on the stand.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/valve_step.py``. For every preset of
:data:`afo_mj.devices.valve_afo.VALVE_PRESETS`: wall time per step (MuJoCo stand + device, one
side) of a 2 s imposed-sinusoid run with a 0 → 40 N·m torque command (after a warm-up run of
the same preset that compiles or loads its generated circuit), the share of steps re-done in
sub-steps, Newton iterations per step and the ledger's relative balance error; and, where the
repository's tests are present, the same run on the hand-written valve kernel the generated
circuits replaced (``tests/kernel_reference``), alternated with it, medians of 3. The last
line is a JSON object.
"""

from __future__ import annotations

import json
import math
import statistics
import sys
import time
from pathlib import Path

from afo_mj.devices.valve_afo import VALVE_PRESETS, ValveAfoDevice
from afo_mj.human.test_stand import AnkleTestStand, ImposedTrajectory, StandLoad


def _reference_device():
    """The hand-written kernel's device class, if the tests are beside this script."""
    tests = Path(__file__).resolve().parents[1] / "tests"
    if not (tests / "kernel_reference").is_dir():
        return None
    sys.path.insert(0, str(tests))
    from kernel_reference.kernel_devices import ValveKernelDevice
    return ValveKernelDevice


def run(preset: str, duration_s: float = 2.0, timestep_s: float = 1e-3,
        device=ValveAfoDevice) -> dict:
    f = 1.0
    stand = AnkleTestStand(load=StandLoad(kind="imposed",
                                          trajectory=ImposedTrajectory.sinusoid(0.25, f)),
                           timestep_s=timestep_s)
    dev = device(VALVE_PRESETS[preset], timestep_s=timestep_s,
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


def main(repeats: int = 3) -> None:
    ref = _reference_device()
    result = {}
    for preset in VALVE_PRESETS:
        run(preset, 0.05)                   # warm-up: compile / load this preset's circuit
        if ref is not None:
            run(preset, 0.05, device=ref)
        gen, old = [], []
        for _ in range(repeats):
            gen.append(run(preset))
            if ref is not None:
                old.append(run(preset, device=ref))
        r = dict(gen[-1], us_per_step=statistics.median(g["us_per_step"] for g in gen))
        line = (f"{preset:24s} {r['us_per_step']:7.1f} us/step  substepped "
                f"{100 * r['substepped_fraction']:5.1f} %  "
                f"Newton {r['newton_iterations_per_step']:.2f}/step  "
                f"balance {r['balance_error_rel']:.1e}")
        if old:
            r["hand_written_us_per_step"] = statistics.median(o["us_per_step"] for o in old)
            r["hand_written_newton_per_step"] = old[-1]["newton_iterations_per_step"]
            line += (f"  | hand-written {r['hand_written_us_per_step']:5.1f} us/step, "
                     f"Newton {r['hand_written_newton_per_step']:.2f}/step")
        result[preset] = r
        print(line)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
