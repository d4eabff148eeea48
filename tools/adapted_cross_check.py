"""Cross-check of the shipped adapted wearers: each walked with and without its own device.

An effect of assistance is the adapted wearer's cost with the device against the control's
without it. That difference holds two things: what the device does, and how much cheaper a
gait the condition's search found than the control's. Walking each condition's adapted
wearer *without* its device separates them: if it is cheaper than the control, the control
was not the cheapest no-device gait known (the control search had not converged) and part of
the "effect" is the search. Per shipped set ``afo_mj/data/adapted/<kind>[_seed<N>].json``:
the net cost of transport (Umberger 2010, J/(kg·m), strides after 3 s of a 16 s walk) with
the speed and the net metabolic rate (W/kg). The shares are ratios of costs of transport: a
wearer without its device may walk at another speed, where rates do not compare with the
condition worn, without it (``none``, same reflexes), and the control's of the same seed.

Run::

    .venv/bin/python tools/adapted_cross_check.py           # print the table
    .venv/bin/python tools/adapted_cross_check.py --write   # rewrite docs/muscle_walker.md's block
    .venv/bin/python tools/adapted_cross_check.py --check   # exit 1 naming a difference
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from doc_block import mode_parser, write_or_check  # noqa: E402
from afo_mj.experiments.muscle_assistance import (Assistance, assistance_summary,  # noqa: E402
                                                  assistance_walk)
from afo_mj.gait.muscle_walk import load_reflex_set  # noqa: E402

DATA = ROOT / "afo_mj" / "data" / "adapted"
DOC = ROOT / "docs" / "muscle_walker.md"
BEGIN, END = "<!-- adapted-cross-check:begin -->", "<!-- adapted-cross-check:end -->"
DURATION_S = 16.0
KINDS = ("zhang", "clutched_spring", "hafo")
SEEDS = (1, 2, 3)


def _name(kind: str, seed: int) -> str:
    return kind if seed == 1 else f"{kind}_seed{seed}"


def _rate(params, a: Assistance):
    walk, dev = assistance_walk(a, params=params, duration_s=DURATION_S)
    s = assistance_summary(walk, 3.0, dev)
    return None if s["fell_s"] is not None else (s["net_cost_of_transport_j_per_kg_m"],
                                                 s["speed_m_s"], s["net_metabolic_w_per_kg"])


def objective_assistance(kind: str) -> Assistance:
    """The condition as the adapted sets were searched with it (tools/muscle_adapted.py)."""
    return Assistance(kind, ramp_strides=3) if kind == "zhang" else Assistance(kind)


def analyse() -> dict:
    rows = {}
    for seed in SEEDS:
        control = _rate(load_reflex_set(DATA / f"{_name('none', seed)}.json"), Assistance())
        for kind in KINDS:
            p = load_reflex_set(DATA / f"{_name(kind, seed)}.json")
            rows[(kind, seed)] = {"control": control,
                                  "with": _rate(p, objective_assistance(kind)),
                                  "without": _rate(p, Assistance())}
    return rows


def _pct(a, b) -> str:
    return "–" if a is None or b is None else f"{100.0 * (a[0] / b[0] - 1.0):+.1f} %"


def _w(x) -> str:
    return "falls" if x is None else f"{x[0]:.2f} ({x[1]:.2f} m/s, {x[2]:.2f} W/kg)"


def format_table(rows: dict) -> str:
    lines = ["| condition | seed | control: J/(kg·m) (speed, rate) | adapted wearer with the "
             "device | same wearer without it | effect as reported (with vs control) | search "
             "share (without vs control) | device share (with vs without) |",
             "|---|---|---|---|---|---|---|---|"]
    for (kind, seed), r in rows.items():
        c, w, wo = r["control"], r["with"], r["without"]
        lines.append(f"| {kind} | {seed} | {_w(c)} | {_w(w)} | {_w(wo)} | {_pct(w, c)} | "
                     f"{_pct(wo, c)} | {_pct(w, wo)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    args = mode_parser(__doc__.split("\n\n")[0]).parse_args(argv)
    rows = analyse()
    body = format_table(rows)
    if not (args.check or args.write):
        print(body)
        print(json.dumps({f"{k}/{s}": {c: None if v is None else v[0] for c, v in r.items()}
                          for (k, s), r in rows.items()}))
        return 0
    return write_or_check(DOC, BEGIN, END, body, "adapted-cross-check", args.write)


if __name__ == "__main__":
    raise SystemExit(main())
