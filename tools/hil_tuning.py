"""Zhang et al.'s (2017) human-in-the-loop tuning in simulation (:mod:`afo_mj.studies.
hil_tuning`): the control, the generic Zhang profile and the tuned profile (a joint CMA-ES over
the wearer's reflexes and the four profile parameters), each by ``--restarts`` searches of the
same budget and seeds; prints every arm's restarts, the tuned profiles, the changes (tuned vs
generic paired by restart, both vs the control) beside Zhang et al.'s figure, then a JSON line.

Run (resumable: the same ``--out`` continues every search; more ``--restarts`` or
``--generations`` extend it)::

    .venv/bin/python tools/hil_tuning.py --out results/hil_zhang --restarts 2 \\
        --generations 80 --workers 1
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from afo_mj.outputs.console import hil_tuning_lines  # noqa: E402
from afo_mj.studies.adaptation import AdaptationProtocol  # noqa: E402
from afo_mj.studies.hil_tuning import HilProtocol, ProfileBounds, tune_zhang  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="output folder (resumable)")
    ap.add_argument("--restarts", type=int, default=2)
    ap.add_argument("--generations", type=int, default=80)
    ap.add_argument("--popsize", type=int, default=16)
    ap.add_argument("--sigma0", type=float, default=0.04,
                    help="initial CMA-ES step of the reflex log factors")
    ap.add_argument("--profile-sigma", type=float, default=0.1,
                    help="initial step of the profile coordinates, a fraction of each bound")
    ap.add_argument("--peak-max", type=float, default=0.6,
                    help="upper bound of the tuned peak torque, N·m/kg")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--start", default=None, help="reflex set of the generic and tuned arms "
                    "(default afo_mj/data/adapted/zhang.json)")
    ap.add_argument("--control-start", default=None, help="reflex set of the control arm "
                    "(default afo_mj/data/adapted/none.json)")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    try:
        protocol = HilProtocol(
            adaptation=AdaptationProtocol(restarts=args.restarts, generations=args.generations,
                                          popsize=args.popsize, sigma0=args.sigma0,
                                          seed=args.seed),
            bounds=ProfileBounds(peak_nm_per_kg=(0.0, args.peak_max)),
            profile_sigma=args.profile_sigma)
        res = tune_zhang(args.out, protocol, args.control_start, args.start, args.workers,
                         progress=lambda text: print(text, file=sys.stderr, flush=True))
    except ValueError as exc:
        print(f"hil_tuning: {exc}", file=sys.stderr)
        return 2
    print("\n".join(hil_tuning_lines(res, args.out)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
