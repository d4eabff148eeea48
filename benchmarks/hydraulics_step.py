"""Cost of one 1 ms step of the pump-controlled cylinder circuit and its accuracy vs Radau.

Run: ``.venv/bin/python benchmarks/hydraulics_step.py`` (after ``./afo test`` or ``./afo demo``
has made the environment). Prints its figures; the last line is a JSON object.
"""

from __future__ import annotations

import json
import time

from afo_mj.hydraulics.verification import compare, make_case, run_fixed_step


def cost_us_per_step(substeps: int, duration_s: float = 0.5) -> float:
    case = make_case("loaded")
    case.duration_s = duration_s
    run_fixed_step(case, substeps=substeps)  # warm-up
    t0 = time.perf_counter()
    t, _, _ = run_fixed_step(case, substeps=substeps)
    return (time.perf_counter() - t0) / (len(t) - 1) * 1e6


def main() -> None:
    result = {}
    for sub in (1, 4):
        us = cost_us_per_step(sub)
        result[f"us_per_step_substeps{sub}"] = round(us, 1)
        print(f"cost of one 1 ms step, {sub} ROS2 substep(s): {us:.0f} us")
    for sub in (1, 4):
        r = compare("loaded", substeps=sub, duration_s=0.3)
        worst = max(r[k] for k in ("pump_a_pa", "pump_b_pa", "chamber_a_pa", "chamber_b_pa",
                                   "actuator_force_n"))
        result[f"nrmse_vs_radau_substeps{sub}"] = round(worst, 5)
        print(f"worst NRMSE vs Radau (pressures, actuator force), {sub} substep(s): "
              f"{100 * worst:.3f} %")
    for sub in (4, 8):
        case = make_case("loaded")
        _, _, sim = run_fixed_step(case, substeps=sub)
        rr = sim.energy_balance()["relative_residual"]
        result[f"energy_residual_substeps{sub}"] = float(f"{rr:.3g}")
        print(f"energy balance residual, {sub} substeps: {100 * rr:.3f} % of input")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
