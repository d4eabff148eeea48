"""Why the clutched spring does little on the muscle walker, measured (issue 42 item 3).

Walks (16 s each, strides after 3 s scored, right leg) of the shipped reflex sets
``adapted/none`` and ``adapted/clutched_spring`` without and with Collins et al.'s spring
(180 N·m/rad, clutch at 10 % of the stride, open by 62 %), and the adapted spring wearer with
the spring's stiffness and engagement tuned (naive: the same reflex set, not re-adapted).
For each: net metabolic rate (Umberger 2010), the spring's absorbed and returned work per
stride and the phase of its peak stored energy, the soleus' and gastrocnemius' fibre and
tendon work and metabolic energy per stride, and the ankle's loaded dorsiflexion (from the
clutch's engagement to its stance peak) beside Winter's
(:mod:`afo_mj.experiments.spring_mechanics`).

Run::

    .venv/bin/python tools/spring_mechanics.py           # print the tables
    .venv/bin/python tools/spring_mechanics.py --write   # rewrite docs/muscle_walker.md's block
    .venv/bin/python tools/spring_mechanics.py --check   # exit 1 naming a difference

``--check`` compares with the block of docs/muscle_walker.md between
``<!-- spring-mechanics:begin -->`` and ``<!-- spring-mechanics:end -->`` at the printed
precision (``tools/readme_tables.py``'s rule). The last line printed without an option is a
JSON object.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from doc_block import mode_parser, write_or_check  # noqa: E402
from afo_mj.experiments import spring_mechanics as sm  # noqa: E402
from afo_mj.experiments.muscle_assistance import (Assistance, assistance_summary,  # noqa: E402
                                                  assistance_walk)
from afo_mj.gait.muscle_walk import load_reflex_set  # noqa: E402
from afo_mj.gait.reference import load_normative  # noqa: E402

DATA = ROOT / "afo_mj" / "data" / "adapted"
DOC = ROOT / "docs" / "muscle_walker.md"
BEGIN, END = "<!-- spring-mechanics:begin -->", "<!-- spring-mechanics:end -->"
DURATION_S = 16.0
SETTLE_S = 3.0
WEARERS = ("none", "clutched_spring")
#: loaded dorsiflexion is measured from the lowest stance angle after this phase (foot flat)
STANCE_FROM = 0.02
STIFFNESSES = (60.0, 120.0, 180.0, 270.0, 400.0, 600.0)
#: the clutch variants of the tuning grid: (column label, engagement phase, ratchet)
CLUTCHES = (("ratchet from 2 %", 0.02, True), ("clutch at 5 %", 0.05, False),
            ("clutch at 10 %", 0.10, False), ("clutch at 15 %", 0.15, False))
#: the spring conditions of the first table: (label, Assistance keywords)
SPRINGS = (("none", {"kind": "none"}),
           ("180 N·m/rad, clutch at 10 %", {"kind": "clutched_spring"}),
           ("180 N·m/rad, ratchet from 2 %", {"kind": "clutched_spring",
                                               "spring_engage_phase": 0.02,
                                               "spring_ratchet": True}))


def measure(params, a: Assistance) -> dict:
    """One walk's figures (module docstring); a fall gives ``{"fell_s": t}``."""
    walk, _ = assistance_walk(a, params=params, duration_s=DURATION_S)
    s = assistance_summary(walk, SETTLE_S)
    if s["fell_s"] is not None or s["strides"] < 2:
        return {"fell_s": s["fell_s"]}
    spring = sm.spring_stride_energy(walk, SETTLE_S)
    mus = sm.muscle_stride_work(walk, ("soleus", "gastrocnemius"), SETTLE_S)
    st = sm.ankle_stance_profile(walk, STANCE_FROM, SETTLE_S)
    return {"fell_s": None, "net_w_per_kg": s["net_metabolic_w_per_kg"],
            "speed_m_s": s["speed_m_s"], "spring": spring, "muscles": mus, "stance": st}


def analyse() -> dict:
    res = {"winter": sm.reference_stance_profile(load_normative(), STANCE_FROM), "walks": {},
           "grid": {}}
    for wearer in WEARERS:
        p = load_reflex_set(DATA / f"{wearer}.json")
        for label, kw in SPRINGS:
            res["walks"][(wearer, label)] = measure(p, Assistance(**kw))
    p = load_reflex_set(DATA / "clutched_spring.json")
    for k in STIFFNESSES:
        for label, e, ratchet in CLUTCHES:
            res["grid"][(k, label)] = measure(p, Assistance(
                "clutched_spring", spring_nm_per_rad=k, spring_engage_phase=e,
                spring_ratchet=ratchet))
    return res


def _deg(x: float) -> str:
    return f"{math.degrees(x):.1f}"


def format_tables(res: dict) -> str:
    w = res["winter"]
    base = {wr: res["walks"][(wr, "none")] for wr in WEARERS}
    lines = ["| wearer (reflex set) | spring | net metabolic (W/kg) | change | spring absorbed / "
             "returned (J/stride) | peak stored at (% stride) | loaded dorsiflexion from the "
             "stance minimum (deg) | stance minimum (deg) | peak dorsiflexion at (% stride) | "
             "soleus fibre +/− (J) | soleus tendon + (J) | soleus metabolic "
             "(J) | gastrocnemius fibre +/− (J) | gastrocnemius metabolic (J) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (wearer, label), m in res["walks"].items():
        if m["fell_s"] is not None:
            lines.append(f"| adapted/{wearer} | {label} | falls at {m['fell_s']:.1f} s |"
                         + " |" * 11)
            continue
        b = base[wearer]
        ch = 100.0 * (m["net_w_per_kg"] / b["net_w_per_kg"] - 1.0)
        sp, st = m["spring"], m["stance"]
        sol, gas = m["muscles"]["soleus"], m["muscles"]["gastrocnemius"]
        sp_txt = ("–" if sp.returned_j == 0.0 else f"{-sp.absorbed_j:.2f} / {sp.returned_j:.2f}")
        at = "–" if sp.returned_j == 0.0 else f"{100 * sp.peak_energy_phase:.0f}"
        lines.append(
            f"| adapted/{wearer} | {label} | {m['net_w_per_kg']:.2f} | {ch:+.1f} % | {sp_txt} "
            f"| {at} | {_deg(st.loaded_dorsiflexion_rad)} | {_deg(st.lowest_rad)} | "
            f"{100 * st.peak_phase:.0f} | "
            f"{sol.fibre_positive_j:.2f} / {sol.fibre_negative_j:.2f} | "
            f"{sol.tendon_positive_j:.2f} | {sol.metabolic_j:.1f} | "
            f"{gas.fibre_positive_j:.2f} / {gas.fibre_negative_j:.2f} | {gas.metabolic_j:.1f} |")
    low_at = int(np.argmin(w.angle_rad[:int(round(100 * w.peak_phase)) + 1])) / 100
    fixed = w.peak_rad - w.angle_rad[10]
    lines += ["", f"Winter's normal gait (the reference): from its lowest stance angle, "
              f"{_deg(w.lowest_rad)} deg at {100 * low_at:.0f} % of the stride (foot flat), the "
              f"ankle dorsiflexes under load to {_deg(w.peak_rad)} deg at "
              f"{100 * w.peak_phase:.0f} %: {_deg(w.loaded_dorsiflexion_rad)} deg, "
              f"{_deg(fixed)} deg from its angle at 10 %. A 180 N·m/rad spring stretched that "
              f"far would store {0.5 * 180.0 * w.loaded_dorsiflexion_rad ** 2:.2f} J "
              f"({0.5 * 180.0 * fixed ** 2:.2f} J from 10 %).", ""]
    base_g = res["walks"][("clutched_spring", "none")]["net_w_per_kg"]
    lines += ["Tuning on the adapted/clutched_spring wearer (naive: not re-adapted): net "
              "metabolic change against its no-device walk (%), and in brackets the spring's "
              "returned work (J/stride).", "",
              "| stiffness (N·m/rad) | " + " | ".join(c[0] for c in CLUTCHES) + " |",
              "|---|" + "---|" * len(CLUTCHES)]
    for k in STIFFNESSES:
        cells = []
        for label, _e, _r in CLUTCHES:
            m = res["grid"][(k, label)]
            if m["fell_s"] is not None:
                cells.append(f"falls at {m['fell_s']:.1f} s")
            else:
                cells.append(f"{100.0 * (m['net_w_per_kg'] / base_g - 1.0):+.1f} "
                             f"({m['spring'].returned_j:.2f})")
        lines.append(f"| {k:.0f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _summary(res: dict) -> dict:
    out = {}
    for (wearer, label), m in res["walks"].items():
        if m["fell_s"] is None:
            out[f"{wearer}/{label}"] = {
                "net_w_per_kg": m["net_w_per_kg"],
                "spring_returned_j": m["spring"].returned_j,
                "loaded_dorsiflexion_deg": math.degrees(m["stance"].loaded_dorsiflexion_rad),
                "peak_phase": m["stance"].peak_phase}
    return out


def main(argv=None) -> int:
    args = mode_parser(__doc__.split("\n\n")[0]).parse_args(argv)
    res = analyse()
    body = format_tables(res)
    if not (args.check or args.write):
        print(body)
        print(json.dumps(_summary(res)))
        return 0
    return write_or_check(DOC, BEGIN, END, body, "spring-mechanics", args.write)


if __name__ == "__main__":
    raise SystemExit(main())
