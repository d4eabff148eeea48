"""The adapted wearers of issue 22 by one protocol: a control, then every condition from it.

A wearer adapting to a device minimises effort; here that is a CMA-ES search of the reflex
parameters with the condition worn (``GaitObjective(duration_s=16, tracking_weight=0.25,
assistance=…)``: 1.25 m/s, kinematics near Winter's, least net metabolic cost of transport
by Umberger 2010). A single search per condition from an older set compares the searches as
much as the conditions: each keeps finding cheaper gaits, whatever is worn. So the searches
are staged:

1. ``control``: the no-device wearer, searched from ``--start`` (default
   ``afo_mj/data/adapted/control_start.json``: the cheapest no-device gait known before this
   protocol, an earlier search's worn-mass wearer walked without its masses, 4.66 W/kg against
   the first control's 5.40) at step ``--sigma0``;
2. every condition in ``--kinds`` (``none`` included: the control searched once more, so
   that the no-device row has had the same search as the others), searched from the control
   with the same generations, step, population and seed.

Run::

    .venv/bin/python tools/muscle_adapted.py --out results/adapted2 [--generations 100]
        [--kinds none worn_mass zhang clutched_spring hafo] [--seeds 1 2]

Every search is resumable in ``OUT/<name>`` (``OUT/<kind>_seed<N>`` past the first seed);
``--ship DIR`` copies each search's ``reflex_params.json`` to ``DIR/<kind>.json`` (first seed)
and ``DIR/<kind>_seed<N>.json``. Prints one line per search, then (``--walk-s``, default 20 s)
every condition's set walked with it: the net metabolic rate (Umberger 2010, W/kg) and its
change against the ``none`` set of the same seed, per seed, so that the spread between searches
stands beside the effects; last, a JSON line. ``tools/muscle_assistance_table.py --adapted
DIR`` walks the full table of the shipped sets.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from afo_mj.experiments.muscle_assistance import (KINDS, Assistance,  # noqa: E402
                                                  assistance_summary, assistance_walk)
from afo_mj.studies.gait_optimization import load_reflex_set  # noqa: E402
from afo_mj.studies.gait_optimization import GaitObjective, optimize_gait  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "afo_mj" / "data"
START = DATA / "adapted" / "control_start.json"


def objective(kind: str) -> GaitObjective:
    """The adapted wearer's objective with condition ``kind`` (module docstring); the Zhang
    torque is ramped on over 3 strides, as devices ramp assistance on."""
    a = Assistance(kind, ramp_strides=3) if kind == "zhang" else Assistance(kind)
    return GaitObjective(duration_s=16.0, tracking_weight=0.25, assistance=a)


def _search(out: Path, kind: str, start: dict, a, seed: int) -> dict:
    t0 = time.perf_counter()
    r = optimize_gait(out, objective(kind), generations=a.generations, popsize=16,
                      start=start, workers=a.workers, sigma0=a.sigma0, seed=seed)
    q = r["quality"]
    rms = q["angle_rms_deg"]
    print(f"{out.name:22s} {q['speed_m_s']:.2f} m/s, RMS hip/knee/ankle {rms['hip']:.1f}/"
          f"{rms['knee']:.1f}/{rms['ankle']:.1f} deg, net COT "
          f"{q['net_cost_of_transport_j_per_kg_m']:.3f} J/(kg m), cost {r['cost']:.3f} "
          f"({time.perf_counter() - t0:.0f} s)", flush=True)
    return r


def spread(out: Path, kinds, seeds, walk_s: float) -> dict:
    """Each search's set walked ``walk_s`` s with its condition: ``{kind: {seed: (net
    metabolic W/kg by Umberger, change % against none of that seed or None)}}``; a walk that
    falls gives ``(None, None)``."""
    rates = {}
    for kind in kinds:
        for seed in seeds:
            name = kind if seed == seeds[0] else f"{kind}_seed{seed}"
            walk, dev = assistance_walk(objective(kind).assistance, None,
                                        load_reflex_set(out / name / "reflex_params.json"),
                                        walk_s)
            s = assistance_summary(walk, 3.0, dev)
            rates.setdefault(kind, {})[seed] = (None if s["fell_s"] is not None
                                                else s["net_metabolic_w_per_kg"])
    table = {}
    for kind in kinds:
        for seed in seeds:
            r, base = rates[kind][seed], rates.get("none", {}).get(seed)
            ch = None if r is None or base is None else 100.0 * (r / base - 1.0)
            table.setdefault(kind, {})[seed] = (r, ch)
    return table


def print_spread(table: dict, seeds) -> None:
    print("| condition | " + " | ".join(f"seed {s}: W/kg, change" for s in seeds)
          + " | mean change |")
    print("|---|" + "---|" * (len(seeds) + 1))
    for kind, by_seed in table.items():
        cells = ["falls" if r is None else f"{r:.2f}, {'–' if c is None else f'{c:+.1f} %'}"
                 for r, c in by_seed.values()]
        ch = [c for _, c in by_seed.values() if c is not None]
        mean = f"{sum(ch) / len(ch):+.1f} %" if len(ch) == len(seeds) else "–"
        print(f"| {kind} | " + " | ".join(cells) + f" | {mean} |", flush=True)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for the searches")
    ap.add_argument("--start", default=str(START), help="reflex_params.json of the control's "
                    "start")
    ap.add_argument("--generations", type=int, default=100)
    ap.add_argument("--sigma0", type=float, default=0.1)
    ap.add_argument("--kinds", nargs="+", default=["none", "worn_mass", "zhang",
                                                   "clutched_spring", "hafo"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1])
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--walk-s", type=float, default=20.0, help="length of the walks that "
                    "compare the sets (s; 0: none)")
    ap.add_argument("--ship", default=None, help="copy each search's set to "
                    "DIR/<kind>.json (first seed) and DIR/<kind>_seed<N>.json")
    a = ap.parse_args(argv)
    for k in a.kinds:
        if k not in KINDS:
            raise SystemExit(f"--kinds: {k!r}; allowed: {', '.join(KINDS)}")
    out = Path(a.out)
    start = json.loads(Path(a.start).read_text(encoding="utf-8"))["parameters"]
    control = _search(out / "control", "none", start, a, a.seeds[0])
    results = {"control": control}
    for seed in a.seeds:
        for kind in a.kinds:
            name = kind if seed == a.seeds[0] else f"{kind}_seed{seed}"
            results[name] = _search(out / name, kind, control["parameters"], a, seed)
    if a.ship:
        ship = Path(a.ship)
        ship.mkdir(parents=True, exist_ok=True)
        for seed in a.seeds:
            for kind in a.kinds:
                name = kind if seed == a.seeds[0] else f"{kind}_seed{seed}"
                shutil.copyfile(out / name / "reflex_params.json", ship / f"{name}.json")
    table = spread(out, a.kinds, a.seeds, a.walk_s) if a.walk_s > 0 else {}
    if table:
        print_spread(table, a.seeds)
    print(json.dumps({"searches": {name: {"cost": r["cost"], "quality": r["quality"]}
                                   for name, r in results.items()},
                      "net_metabolic_w_per_kg_and_change_pct": {
                          k: {str(s): v for s, v in t.items()} for k, t in table.items()}}))
    return results


if __name__ == "__main__":
    main()
