"""Cost of one 1 ms sample of the hydraulics demo (the library's lab bench circuit, generated
stepper, on a simulated foot) and how its figures move with the steps per sample.

Run: ``.venv/bin/python benchmarks/hydraulics_step.py`` (after ``./afo test`` or ``./afo demo``
has made the environment). Prints its figures; the last line is a JSON object. The generated
stepper's accuracy against a hand-written Radau reference of the same circuit is
``tests/test_circuit_accuracy.py``.
"""

from __future__ import annotations

import json

from afo_mj.app.hydraulics_demo import hydraulics_demo


def main() -> None:
    result = {}
    hydraulics_demo(0.05)  # compile or load the kernel
    runs = {}
    for sub in (1, 4, 16):
        d = runs[sub] = hydraulics_demo(1.0, substeps=sub)
        result[f"us_per_sample_substeps{sub}"] = round(d["us_per_step"], 1)
        print(f"cost of one 1 ms sample, {sub} stepper step(s): {d['us_per_step']:.0f} us")
    ref = runs[16]["ranges"]
    for sub in (1, 4):
        r = runs[sub]["ranges"]
        worst = max(abs(a - b) / max(abs(ref[k][1] - ref[k][0]), 1e-12)
                    for k in ("chamber_a_gauge_pa", "chamber_b_gauge_pa", "torque_nm")
                    for a, b in zip(r[k], ref[k]))
        result[f"range_change_vs_16_substeps{sub}"] = float(f"{worst:.3g}")
        print(f"pressure/torque range extremes vs 16 steps per sample, {sub} step(s): "
              f"{100 * worst:.3f} % of the range")
    rr = runs[1]["energy"]["relative_residual"]
    result["energy_residual_substeps1"] = float(f"{rr:.3g}")
    print(f"energy balance residual, 1 step per sample: {rr:.2e} of the throughput")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
