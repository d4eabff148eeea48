#!/usr/bin/env bash
# Regenerate the sample figures of docs/figures/ (see README.md there): each scenario kind run
# once with its shipped settings, then one PNG of each figure kind copied here, reduced to a
# 256-colour palette and, where still over 200 kB, to 75 % of its size.
# Usage (from the repository root): bash docs/figures/make_samples.sh [WORK_DIR]
set -euo pipefail
work=${1:-/tmp/afo_mj_figure_samples}
py=${PYTHON:-.venv/bin/python}
export MUJOCO_GL=${MUJOCO_GL:-egl}
for s in walk_healthy gait_assist_hafo gait_assist_valve gait_stiffness_emulation bench_hafo \
         stiffness_bench; do
  "$py" -m afo_mj.cli run "scenarios/$s.toml" --out "$work/$s" > "$work.$s.log"
done
"$py" -m afo_mj.cli compare scenarios/gait_assist_hafo.toml scenarios/gait_assist_valve.toml \
  --strides 5 --out "$work/compare" > "$work.compare.log"
"$py" - "$work" <<'PY'
import sys
from pathlib import Path

from PIL import Image

work, dest = Path(sys.argv[1]), Path("docs/figures")
samples = {
    "walk_healthy": ["gait_curves.png"],
    "gait_assist_hafo": ["gait_conditions.png", "ankle_angle_conditions.png",
                         "device_torque.png", "device_stride_hydraulics.png",
                         "device_power_flow.png"],
    "gait_assist_valve": ["device_stride_hydraulics.png", "device_power_flow.png"],
    "gait_stiffness_emulation": ["gait_conditions.png"],
    "bench_hafo": ["hafo_torque_velocity.png", "hafo_isometric_steps.png", "hafo_bode.png",
                   "hafo_position_step.png"],
    "stiffness_bench": ["stiffness_loops.png", "stiffness_timeseries.png"],
    "compare": ["comparison.png"],
}
for run, names in samples.items():
    for name in names:
        img = Image.open(work / run / name).convert("RGB")
        out = dest / f"{run}__{name}"
        while True:
            img.quantize(256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
            if out.stat().st_size < 200_000:
                break
            img = img.resize((int(img.width * 0.75), int(img.height * 0.75)), Image.LANCZOS)
        print(f"{out} {out.stat().st_size // 1000} kB {img.width}x{img.height}")
PY
