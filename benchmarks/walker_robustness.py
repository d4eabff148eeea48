"""Robustness of the walking controller: 13 situations, each walked 10 strides with the default
controller and gains, reporting whether it falls and its gait figures over strides 4–10.

Situations: healthy; plantarflexor strength 50, 45, 40 %; foot drop (2 % dorsiflexors);
spasticity (150 N·m/rad, 3 N·m·s/rad); one-sided 0.97 kg at the ankle; HAFO-like 3.3 kg
(2.33 kg at the waist); healthy with 40 N·m push-off assist; 50 %-weak with 20 N·m assist;
starts at 0.8 and 1.3 m/s; a 25 kg, 1.2 m child at the Froude-scaled cadence.

Prints one line per situation; the last line is a JSON object.
Run: ``.venv/bin/python benchmarks/walker_robustness.py [--workers N]``
"""

from __future__ import annotations

import argparse
import json
import os
import time
from multiprocessing import Pool

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

CASES = ("healthy", "weak_50", "weak_45", "weak_40", "foot_drop", "spastic", "ankle_mass_r",
         "hafo_mass", "healthy_assist_40", "weak_50_assist_20", "start_0.8", "start_1.3", "child")


class _PushOffAssist:
    """Half-sine plantarflexion torque over 35–62 % of each stance leg's phase."""

    def __init__(self, peak_nm: float):
        self.peak_nm = peak_nm

    def torque_nm(self, t_s, angle_rad, velocity_rad_s, phase, stance):
        p = np.clip(phase, 0.35, 0.62)
        return np.where(stance & (phase > 0.35) & (phase < 0.62),
                        -self.peak_nm * np.sin(np.pi * (p - 0.35) / 0.27), 0.0)


def run_case(case: str) -> dict:
    from afo_mj.metrics.gait_metrics import analyse_gait
    from afo_mj.gait.reference import load_normative
    from afo_mj.gait.walk import ControllerParams, run_walk
    from afo_mj.human.walker import WalkerParams, WornMass

    ref = load_normative("winter", "normal")
    walker, ctrl, worn, device = {}, {}, (), None
    cycle_time = ref.cycle_time_s
    if case.startswith("weak_"):
        walker["plantarflexor_strength_fraction"] = int(case[5:7]) / 100.0
    if case == "foot_drop":
        walker["dorsiflexor_strength_fraction"] = 0.02
    if case == "spastic":
        walker.update(ankle_passive_stiffness_nm_per_rad=150.0,
                      ankle_passive_damping_nm_s_per_rad=3.0)
    if case in ("ankle_mass_r", "hafo_mass"):
        worn = (WornMass("shank_cuff_r", 0.50, "cuff"), WornMass("foot_plate_r", 0.47, "plate"))
        if case == "hafo_mass":
            worn += (WornMass("waist", 2.33, "supply"),)
    if case == "healthy_assist_40":
        device = _PushOffAssist(40.0)
    if case == "weak_50_assist_20":
        device = _PushOffAssist(20.0)
    if case.startswith("start_"):
        ctrl["initial_speed_m_s"] = float(case[6:])
    if case == "child":
        walker.update(body_mass_kg=25.0, height_m=1.2, timestep_s=0.0005)
        cycle_time *= (1.2 / 1.75) ** 0.5
    t0 = time.perf_counter()
    rec = run_walk(WalkerParams(**walker), ref, cycle_time, 10, ControllerParams(**ctrl),
                   worn_masses=worn, device=device)
    out = {"case": case, "fell": rec.events.fall_time_s is not None,
           "fall_time_s": rec.events.fall_time_s, "wall_s": round(time.perf_counter() - t0, 2)}
    if not out["fell"]:
        s = analyse_gait(rec, ref, (4, 10)).summary
        for key in ("hip_angle_rms_error_deg", "knee_angle_rms_error_deg",
                    "ankle_angle_rms_error_deg", "ankle_push_off_positive_work_j_per_kg",
                    "push_off_peak_plantarflexion_deg", "speed_m_s"):
            out[key] = round(s[key]["mean"], 3)
        out["residual_force_rms_percent_body_weight"] = round(
            s["residual_force_rms_percent_body_weight"]["over_analysed_span"], 2)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    with Pool(args.workers) as pool:
        results = pool.map(run_case, CASES)
    for r in results:
        if r["fell"]:
            print(f"{r['case']:<20s} FELL at {r['fall_time_s']:.2f} s")
        else:
            print(f"{r['case']:<20s} angle RMS {r['hip_angle_rms_error_deg']:4.1f} / "
                  f"{r['knee_angle_rms_error_deg']:4.1f} / "
                  f"{r['ankle_angle_rms_error_deg']:4.1f} deg"
                  f"  push-off work {r['ankle_push_off_positive_work_j_per_kg']:.3f} J/kg"
                  f"  push-off PF {r['push_off_peak_plantarflexion_deg']:5.1f} deg"
                  f"  speed {r['speed_m_s']:.2f} m/s"
                  f"  residual {r['residual_force_rms_percent_body_weight']:.1f} %BW")
    walked = sum(not r["fell"] for r in results)
    print(f"{walked}/{len(results)} situations walked 10 strides")
    print(json.dumps({"walked": walked, "cases": len(results), "results": results}))


if __name__ == "__main__":
    main()
