"""Command-line interface: ``afo-mj``.

Until the gait scenarios exist the main job is ``afo-mj demo``: a loaded pump-controlled
cylinder (motor → pump → hoses → piston-cable cylinder → load) stepped at 1 ms, with its
energy chain and accuracy against a Radau reference printed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np


def _demo(args: argparse.Namespace) -> int:
    from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA
    from afo_mj.hydraulics.pump_cylinder import STATE_NAMES
    from afo_mj.hydraulics.verification import make_case, run_fixed_step

    case = make_case("loaded")
    case.duration_s = args.duration_s
    t0 = time.perf_counter()
    t, ys, sim = run_fixed_step(case, dt=1e-3, substeps=args.substeps)
    wall = time.perf_counter() - t0
    idx = {n: i for i, n in enumerate(STATE_NAMES)}
    bar = lambda p: (p - ATMOSPHERIC_PRESSURE_PA) / 1e5  # noqa: E731
    cyl = case.circuit.cylinder
    force = cyl.hydraulic_force_n(ys[:, idx["chamber_a_pa"]], ys[:, idx["chamber_b_pa"]])
    eb = sim.energy_balance()
    print("afo_mj hydraulic demo: pump-controlled piston-cable cylinder, 2 kg + 20 kN/m load")
    print(f"  simulated {t[-1]:.2f} s at 1 ms steps ({args.substeps} ROS2 substeps) "
          f"in {wall:.2f} s wall ({wall / (len(t) - 1) * 1e6:.0f} us/step)")
    print(f"  chamber a pressure     {bar(ys[:, idx['chamber_a_pa']]).min():7.1f} .. "
          f"{bar(ys[:, idx['chamber_a_pa']]).max():7.1f} bar (gauge)")
    print(f"  chamber b pressure     {bar(ys[:, idx['chamber_b_pa']]).min():7.1f} .. "
          f"{bar(ys[:, idx['chamber_b_pa']]).max():7.1f} bar (gauge)")
    print(f"  actuator force         {force.min():7.1f} .. {force.max():7.1f} N")
    print(f"  piston position        {ys[:, idx['position_m']].min() * 1e3:7.2f} .. "
          f"{ys[:, idx['position_m']].max() * 1e3:7.2f} mm")
    print(f"  motor speed peak       {np.abs(ys[:, idx['speed_rad_s']]).max() * 60 / 2 / np.pi:7.0f} rpm")
    print(f"  oil temperature rise   {(ys[-1, idx['fluid_temperature_k']] - ys[0, idx['fluid_temperature_k']]) * 1e3:7.2f} mK")
    print("  energy chain (J):")
    print(f"    electrical input     {eb['input_j']:9.4f}")
    for k, v in eb["heat_j"].items():
        print(f"    loss {k:<22s}{v:9.4f}  ({100 * v / eb['input_j']:5.1f} %)")
    print(f"    stored change        {eb['stored_change_j']:9.4f}")
    print(f"    delivered to load    {eb['load_out_j'] if 'load_out_j' in eb else eb['output_j']:9.4f}")
    print(f"    balance residual     {eb['residual_j']:9.2e}  ({100 * eb['relative_residual']:.3f} % of input)")
    summary = {"duration_s": float(t[-1]), "us_per_step": wall / (len(t) - 1) * 1e6,
               "max_force_n": float(force.max()), "energy": {
                   "input_j": float(eb["input_j"]), "output_j": float(eb["output_j"]),
                   "heat_j": {k: float(v) for k, v in eb["heat_j"].items()},
                   "relative_residual": float(eb["relative_residual"])}}
    if args.json:
        print(json.dumps(summary))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="afo-mj", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the hydraulic demo headless and print results")
    demo.add_argument("--duration-s", type=float, default=1.0, dest="duration_s")
    demo.add_argument("--substeps", type=int, default=4)
    demo.add_argument("--json", action="store_true", help="also print a JSON summary line")
    demo.set_defaults(func=_demo)
    args = parser.parse_args(argv)
    if getattr(args, "duration_s", 1.0) <= 0:
        parser.error(f"--duration-s = {args.duration_s}; allowed: > 0")
    if getattr(args, "substeps", 1) < 1:
        parser.error(f"--substeps = {args.substeps}; allowed: integer >= 1")
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
