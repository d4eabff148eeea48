"""Where the spring's energy goes along a stiffness dose-response (issue 42 item 2): each
level's adapted wearer (every restart's best set of an ``afo-mj dose-response`` run of
``scenarios/studies/dose_spring_stiffness.toml``) walked 20 s with its own spring, strides
after 3 s, right leg: net metabolic rate (Umberger 2010), the ankle's loaded dorsiflexion
(from its stance minimum after the study's clutch engagement phase to its stance peak, and
the peak's phase; the control's from the same phase), the spring's returned work
and peak moment per stride, and the soleus' positive fibre work and metabolic energy per
stride and the gastrocnemius' metabolic energy (:mod:`afo_mj.experiments.spring_mechanics`).

Run::

    .venv/bin/python tools/dose_spring_mechanics.py results/dose_spring_stiffness

It prints a Markdown table (the one in docs/muscle_walker.md).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from afo_mj.experiments import spring_mechanics as sm  # noqa: E402
from afo_mj.experiments.muscle_assistance import (Assistance, assistance_summary,  # noqa: E402
                                                  assistance_walk)
from afo_mj.studies.dose_response import DoseResponseResult, load_reflex_set  # noqa: E402


def rows(out: Path) -> list[str]:
    res = DoseResponseResult.from_json(json.loads((out / "dose_response.json").read_text()))
    lines = ["| stiffness (N·m/rad) | restart | net metabolic (W/kg) | loaded dorsiflexion "
             "(deg) | stance peak at (% stride) | spring returned (J/stride) | spring peak "
             "moment (N·m) | soleus fibre + (J) | soleus metabolic (J) | gastrocnemius "
             "metabolic (J) |", "|---|---|---|---|---|---|---|---|---|---|"]
    engage = res.assistance.get("spring_engage_phase", Assistance().spring_engage_phase)
    for lv in res.levels:
        a = (Assistance("none") if lv is res.levels[0] else
             Assistance("clutched_spring", **res.assistance, spring_nm_per_rad=lv.dose))
        for r in lv.restarts:
            walk, dev = assistance_walk(a, None, load_reflex_set(
                Path(out) / lv.name / f"restart{r.restart}" / "reflex_params.json"), 20.0)
            s = assistance_summary(walk, 3.0, dev)
            if s["fell_s"] is not None:
                lines.append(f"| {lv.dose:g} | {r.restart} | falls at {s['fell_s']:.1f} s "
                             "| | | | | | | |")
                continue
            ank = sm.ankle_stance_profile(walk, engage)    # every row from the same phase
            mw = sm.muscle_stride_work(walk)
            sp = sm.spring_stride_energy(walk) if a.kind != "none" else None
            lines.append(
                f"| {lv.dose:g} | {r.restart} | {s['net_metabolic_w_per_kg']:.3f} | "
                f"{math.degrees(ank.loaded_dorsiflexion_rad):.1f} | "
                f"{100 * ank.peak_phase:.0f} | "
                + ("– | – | " if sp is None else
                   f"{sp.returned_j:.2f} | {sp.peak_moment_nm:.1f} | ")
                + f"{mw['soleus'].fibre_positive_j:.2f} | {mw['soleus'].metabolic_j:.1f} | "
                f"{mw['gastrocnemius'].metabolic_j:.1f} |")
    return lines


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: tools/dose_spring_mechanics.py RESULT_DIR")
    print("\n".join(rows(Path(sys.argv[1]))))
