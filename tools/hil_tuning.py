"""Zhang et al.'s (2017) human-in-the-loop tuning in simulation (:mod:`afo_mj.studies.
hil_tuning`): the control, the generic Zhang profile and the tuned profile (a joint CMA-ES over
the wearer's reflexes and the four profile parameters), each by ``--restarts`` searches of the
same budget and seeds; prints every arm's restarts, the tuned profiles, the changes (tuned vs
generic paired by restart, both vs the control) beside Zhang et al.'s figure, then a JSON line.

``--device hafo`` tunes the HAFO's command profile instead (the pump-driven orthosis, peak
searched in N·m/kg and commanded × body mass), with the battery as a second objective: one
tuned arm per ``--battery-weight`` (the joint search adds ``w ×`` the battery energy per kg and
metre walked to the wearer's cost); prints each arm with its battery energy per stride and mean
electrical power, then the front and a JSON line.

Run (resumable: the same ``--out`` continues every search; more ``--restarts`` or
``--generations`` extend it, another ``--battery-weight`` adds an arm)::

    .venv/bin/python tools/hil_tuning.py --out results/hil_zhang --restarts 2 \\
        --generations 80 --workers 1
    .venv/bin/python tools/hil_tuning.py --out results/hil_hafo --device hafo \\
        --battery-weight 0 0.25 1 --restarts 2 --generations 20 --popsize 10 --workers 1
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from afo_mj.outputs.console import hil_front_lines, hil_tuning_lines  # noqa: E402
from afo_mj.studies.adaptation import AdaptationProtocol  # noqa: E402
from afo_mj.studies.hil_tuning import (DEVICES, HilProtocol, ProfileBounds,  # noqa: E402
                                       tune_profile)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="output folder (resumable)")
    ap.add_argument("--device", default="zhang", help=f"one of {', '.join(DEVICES)}")
    ap.add_argument("--battery-weight", type=float, nargs="+", default=[0.0],
                    help="battery weights w, one tuned arm each (device hafo only)")
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
                    "(default afo_mj/data/adapted/<device>.json)")
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
            profile_sigma=args.profile_sigma, device=args.device,
            battery_weights=tuple(args.battery_weight))
        res = tune_profile(args.out, protocol, args.control_start, args.start, args.workers,
                           progress=lambda text: print(text, file=sys.stderr, flush=True))
    except ValueError as exc:
        print(f"hil_tuning: {exc}", file=sys.stderr)
        return 2
    lines = (hil_tuning_lines(res[0], args.out) if protocol.device == "zhang"
             else hil_front_lines(res, args.out))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
