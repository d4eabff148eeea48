"""Does plantarflexor weakness slow the muscle walker when it chooses its own speed? (issue 22)

The shipped weak sets (``afo_mj/data/adapted_weak``) were optimised for 1.25 m/s, so their
speed says nothing about weakness. Here each wearer is re-optimised with no speed target
(``GaitObjective(speed_weight=0)``: kinematics against Winter's and the net metabolic cost of
transport by Umberger 2010 per metre, so the speed is the one that walks a metre cheapest),
from the same start (``afo_mj/data/reflex_params_1.25_emg.json``), with the same
generations, CMA-ES seed and population:

* ``healthy``: no weakness, no device;
* ``weak``: soleus and gastrocnemius at half their maximum isometric force;
* ``weak_zhang``: the same with the ideal Zhang ankle torque (0.5 N·m/kg, both sides).

Run::

    .venv/bin/python tools/muscle_free_speed.py --out results/free_speed [--generations 60]

Each search is resumable in ``OUT/<name>``. Prints one line per wearer (speed, stride, angle
RMS, net cost of transport of its best walk) and, last, a JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from afo_mj.experiments.muscle_assistance import Assistance  # noqa: E402
from afo_mj.studies.gait_optimization import GaitObjective, optimize_gait  # noqa: E402

START = Path(__file__).resolve().parents[1] / "afo_mj" / "data" / "reflex_params_1.25_emg.json"
WEAK = (("soleus", 0.5), ("gastrocnemius", 0.5))


def objectives() -> dict:
    """The three wearers' objectives (module docstring)."""
    base = dict(duration_s=16.0, tracking_weight=0.25, speed_weight=0.0)
    return {"healthy": GaitObjective(**base),
            "weak": GaitObjective(**base, max_force_scale=WEAK),
            "weak_zhang": GaitObjective(**base, max_force_scale=WEAK,
                                        assistance=Assistance("zhang", ramp_strides=3))}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for the three searches")
    ap.add_argument("--generations", type=int, default=60)
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args(argv)
    start = json.loads(START.read_text(encoding="utf-8"))["parameters"]
    out = {}
    for name, obj in objectives().items():
        t0 = time.perf_counter()
        r = optimize_gait(Path(a.out) / name, obj, generations=a.generations, popsize=16,
                          start=start, workers=a.workers, sigma0=0.2)
        q = r["quality"]
        out[name] = {"speed_m_s": q["speed_m_s"], "stride_s": q["stride_s"],
                     "angle_rms_deg": q["angle_rms_deg"], "cost": r["cost"],
                     "net_cost_of_transport_j_per_kg_m": q["net_cost_of_transport_j_per_kg_m"]}
        rms = q["angle_rms_deg"]
        print(f"{name:11s} {q['speed_m_s']:.2f} m/s, stride {q['stride_s']:.2f} s, RMS hip/knee/"
              f"ankle {rms['hip']:.1f}/{rms['knee']:.1f}/{rms['ankle']:.1f} deg, net COT "
              f"{q['net_cost_of_transport_j_per_kg_m']:.2f} J/(kg m), cost {r['cost']:.2f} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    print(json.dumps({"generations": a.generations, "wearers": out}))
    return out


if __name__ == "__main__":
    main()
