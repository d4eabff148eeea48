"""How far a shipped reflex set is from falling: the fraction of random perturbations of its
parameters that still walk (issue 22: "small gain changes flip runs between walking and
falling" was the torque walker's fault; this measures the muscle walker's).

Each trial multiplies every one of the set's parameters by ``exp(σ z)``, ``z`` standard
normal (fixed seed), and walks the result for ``--duration`` s on the nominal body; a trial
walks when it neither falls nor diverges. Prints a line per σ and, last, a JSON line.

Run::

    .venv/bin/python tools/muscle_parameter_sensitivity.py afo_mj/data/reflex_params_1.25.json \\
        [--sigma 0.02 0.05 0.1] [--trials 40] [--duration 10]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from afo_mj.experiments.batch import run_batch  # noqa: E402
from afo_mj.gait.muscle_walk import run_muscle_walk  # noqa: E402
from afo_mj.studies.gait_optimization import load_reflex_set  # noqa: E402


def _trial(item):
    params, duration = item
    try:
        walk = run_muscle_walk(None, params, duration)
    except FloatingPointError:
        return 0.0
    fell = walk.record.events.fall_time_s
    return duration if fell is None else float(fell)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("reflex_set", help="a reflex_params.json")
    ap.add_argument("--sigma", type=float, nargs="+", default=[0.02, 0.05, 0.1])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    base = load_reflex_set(args.reflex_set)
    rng = np.random.default_rng(args.seed)
    out = {"set": Path(args.reflex_set).name, "trials": args.trials,
           "duration_s": args.duration, "seed": args.seed, "walks_fraction": {},
           "median_time_walked_s": {}}
    for sigma in args.sigma:
        items = [(base * np.exp(sigma * rng.standard_normal(base.shape)), args.duration)
                 for _ in range(args.trials)]
        times = np.array([r.value if r.ok else 0.0 for r in run_batch(_trial, items)])
        frac = float(np.mean(times >= args.duration))
        out["walks_fraction"][f"{sigma:g}"] = frac
        out["median_time_walked_s"][f"{sigma:g}"] = float(np.median(times))
        print(f"sigma {sigma:g}: {frac:.0%} of {args.trials} perturbed sets walk "
              f"{args.duration:g} s (median {np.median(times):.1f} s walked)")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
