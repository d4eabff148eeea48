"""The muscle walker's assistance table (README, issue 22): every condition of
:mod:`afo_mj.experiments.muscle_assistance` walked by the naive wearer (one reflex set) and,
when given, by the adapted wearer (a set re-optimised with each condition worn).

Run::

    .venv/bin/python tools/muscle_assistance_table.py \\
        --naive afo_mj/data/reflex_params_1.25_emg.json [--adapted DIR] [--weak 0.5]

``DIR/<kind>/reflex_params.json`` are the adapted sets (``afo-mj optimize-gait --assistance
KIND --start NAIVE --out DIR/KIND``; ``DIR/none`` is the control: the same generations
without a device), or ``DIR/<kind>.json`` as shipped in ``afo_mj/data/adapted`` and
``afo_mj/data/adapted_weak``. ``--weak F`` adds the naive rows of a walker whose soleus and
gastrocnemius have ``F`` of their maximum force; ``--weak-adapted DIR`` the rows of sets
optimised with that weakness (``--plantarflexor-strength F``). Changes are against the
table's first (``none``) row. Prints markdown tables and, last, a JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from afo_mj.experiments.muscle_assistance import (KINDS, Assistance,  # noqa: E402
                                                  assistance_comparison, assistance_summary,
                                                  assistance_walk)
from afo_mj.studies.gait_optimization import load_reflex_set  # noqa: E402


def _fmt(v, f=".2f"):
    return "–" if v is None else format(v, f)


def rows_table(rows, title):
    head = ("| condition | walks | speed m/s | net metabolic W/kg (Umberger) | change | "
            "net COT J/(kg m) | change | Bhargava W/kg | Bhargava COT J/(kg m) | "
            "ankle muscle +work J/stride | "
            "device net work J/stride | push-off peak (stride mean) W/kg |")
    out = [f"**{title}**", "", head, "|" + "---|" * 12]
    for r in rows:
        walks = ("yes" if r["fell_s"] is None else
                 f"{'diverges' if r.get('diverged') else 'falls'} at {r['fell_s']:.1f} s")
        if r["fell_s"] is not None:
            # a walk that fell has no steady rates: its strides before the fall are not one
            r = {k: r[k] for k in ("label", "fell_s")}
        ch = r.get("metabolic_change_pct")
        cc = r.get("cot_change_pct")
        out.append(f"| {r['label']} | {walks} | {_fmt(r.get('speed_m_s'))} | "
                   f"{_fmt(r.get('net_metabolic_w_per_kg'))} | "
                   f"{'–' if ch is None else f'{ch:+.1f} %'} | "
                   f"{_fmt(r.get('net_cost_of_transport_j_per_kg_m'))} | "
                   f"{'–' if cc is None else f'{cc:+.1f} %'} | "
                   f"{_fmt(r.get('net_metabolic_bhargava_w_per_kg'))} | "
                   f"{_fmt(r.get('net_cost_of_transport_bhargava_j_per_kg_m'))} | "
                   f"{_fmt(r.get('ankle_muscle_positive_work_j_per_stride'), '.1f')} | "
                   f"{_fmt(r.get('ankle_device_net_work_j_per_stride'), '.1f')} | "
                   f"{_fmt(r.get('ankle_peak_power_w_per_kg'))} |")
    return "\n".join(out)


def _changes(rows):
    base = rows[0] if rows and rows[0]["kind"] == "none" and rows[0]["fell_s"] is None else None
    for r in rows:
        if base and r["fell_s"] is None and "net_metabolic_w_per_kg" in r:
            r["metabolic_change_pct"] = 100.0 * (r["net_metabolic_w_per_kg"]
                                                 / base["net_metabolic_w_per_kg"] - 1.0)
            r["cot_change_pct"] = 100.0 * (r["net_cost_of_transport_j_per_kg_m"]
                                           / base["net_cost_of_transport_j_per_kg_m"] - 1.0)
    return rows


def adapted_rows(directory: Path, duration_s: float):
    """Each ``directory/<kind>/reflex_params.json`` (an optimisation's folder) or
    ``directory/<kind>.json`` (the shipped sets, ``afo_mj/data/adapted``) walked with its
    condition as recorded in the file (and the weakness its optimisation had)."""
    rows = []
    for kind in KINDS:
        f = directory / kind / "reflex_params.json"
        if not f.is_file():
            f = directory / f"{kind}.json"
        if not f.is_file():
            continue
        doc = json.loads(f.read_text())
        # the condition as the set was optimised with it (its peak, ramp, …)
        a = Assistance(**{k: (tuple(v) if isinstance(v, list) else v)
                          for k, v in doc.get("assistance", {"kind": kind}).items()})
        scale = doc.get("max_force_scale") or None
        try:
            walk, dev = assistance_walk(a, None, load_reflex_set(f), duration_s,
                                        max_force_scale=scale)
        except FloatingPointError as exc:         # a diverged walk is reported, not hidden
            t = float(str(exc).split("t = ")[1].split(" ")[0]) if "t = " in str(exc) else 0.0
            rows.append({"label": a.label, "kind": kind, "fell_s": t, "diverged": True})
            continue
        rows.append(dict(assistance_summary(walk, 3.0, dev), label=a.label, kind=kind))
    return _changes(rows)


def pooled_rows(directory: Path, duration_s: float):
    """The adapted wearer with the search's own spread taken out: for each condition, every
    adapted set in ``directory`` is walked with it and scored by the objective the sets were
    optimised with (that condition in place of its own); the wearer is the set that scores
    best. The control (``none``) is so the best of all the sets walked with no device: a
    person keeps the best gait known to them."""
    from afo_mj.studies.gait_optimization import GaitObjective, gait_cost
    sets = {}
    for kind in KINDS:
        f = directory / kind / "reflex_params.json"
        if not f.is_file():
            f = directory / f"{kind}.json"
        if f.is_file():
            sets[kind] = (json.loads(f.read_text()), load_reflex_set(f))
    rows = []
    for kind, (doc, _) in sets.items():
        a = Assistance(**{k: (tuple(v) if isinstance(v, list) else v)
                          for k, v in doc.get("assistance", {"kind": kind}).items()})
        best = None
        for src, (sdoc, params) in sets.items():
            obj = {k: v for k, v in sdoc["objective"].items()}
            cost, _ = gait_cost(params, GaitObjective(**obj, assistance=a))
            if best is None or cost < best[0]:
                best = (cost, src, params)
        walk, dev = assistance_walk(a, None, best[2], duration_s)
        rows.append(dict(assistance_summary(walk, 3.0, dev), label=f"{a.label} (set {best[1]})",
                         kind=kind))
    return _changes(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--naive", required=True, help="the naive wearer's reflex_params.json")
    ap.add_argument("--adapted", default=None, help="folder of adapted sets, one per kind")
    ap.add_argument("--weak", type=float, default=None, help="plantarflexor force factor")
    ap.add_argument("--weak-adapted", default=None,
                    help="folder of sets adapted to a weakness (and device), one per kind")
    ap.add_argument("--duration", type=float, default=20.0, help="walk seconds")
    ap.add_argument("--pooled", action="store_true",
                    help="also each condition's best adapted set (pooled_rows)")
    args = ap.parse_args(argv)
    params = load_reflex_set(args.naive)
    result = {"naive": _changes(assistance_comparison(params, duration_s=args.duration))}
    print(rows_table(result["naive"], f"Naive wearer ({Path(args.naive).name})"))
    if args.weak is not None:
        scale = {"soleus": args.weak, "gastrocnemius": args.weak}
        conds = [Assistance("none"), Assistance("zhang"), Assistance("hafo")]
        result["weak_naive"] = _changes(assistance_comparison(
            params, conds, duration_s=args.duration, max_force_scale=scale))
        print()
        print(rows_table(result["weak_naive"],
                         f"Plantarflexors at {args.weak:g} of their maximum force, naive"))
    if args.adapted and args.pooled:
        result["adapted_pooled"] = pooled_rows(Path(args.adapted), args.duration)
        print()
        print(rows_table(result["adapted_pooled"], "Adapted wearer, the best of the adapted "
                         "sets for each condition"))
    for key, title in (("adapted", "Adapted wearer (re-optimised with each condition)"),
                       ("weak_adapted", "Weak plantarflexors, adapted")):
        folder = getattr(args, key)
        if folder:
            result[key] = adapted_rows(Path(folder), args.duration)
            print()
            print(rows_table(result[key], title))
    for rows in result.values():
        for r in rows:
            r.pop("device_ledger", None)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
