"""The hydraulics demo: a loaded pump-controlled piston-cable cylinder (motor → pump → hoses
→ cylinder → 2 kg + 20 kN/m load) stepped at 1 ms with ROS2 substeps (the ``loaded`` case
of :mod:`afo_mj.hydraulics.verification`), its ranges and its energy chain."""

from __future__ import annotations

import time

import numpy as np

__all__ = ["hydraulics_demo"]


def hydraulics_demo(duration_s: float = 1.0, substeps: int = 4) -> dict:
    """Run the demo; returns the figures ``afo-mj hydraulics-demo`` prints (SI units):
    ``duration_s``, ``us_per_step``, ``substeps``, ``ranges`` (name → (min, max)),
    ``motor_speed_peak_rad_s``, ``oil_temperature_rise_k``, ``max_force_n`` and ``energy``
    (``input_j``, ``output_j``, ``heat_j`` by loss, ``stored_change_j``, ``residual_j``,
    ``relative_residual``)."""
    from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA
    from afo_mj.hydraulics.pump_cylinder import STATE_NAMES
    from afo_mj.hydraulics.verification import make_case, run_fixed_step

    if not duration_s > 0:
        raise ValueError(f"duration_s = {duration_s!r}; allowed: > 0")
    if int(substeps) != substeps or substeps < 1:
        raise ValueError(f"substeps = {substeps!r}; allowed: an integer >= 1")
    case = make_case("loaded")
    case.duration_s = duration_s
    t0 = time.perf_counter()
    t, ys, sim = run_fixed_step(case, dt=1e-3, substeps=int(substeps))
    wall = time.perf_counter() - t0
    idx = {n: i for i, n in enumerate(STATE_NAMES)}
    force = case.circuit.cylinder.hydraulic_force_n(ys[:, idx["chamber_a_pa"]],
                                                    ys[:, idx["chamber_b_pa"]])
    eb = sim.energy_balance()

    def span(x):
        return float(np.min(x)), float(np.max(x))
    return {"duration_s": float(t[-1]), "us_per_step": wall / (len(t) - 1) * 1e6,
            "wall_time_s": wall, "substeps": int(substeps),
            "ranges": {"chamber_a_gauge_pa": span(ys[:, idx["chamber_a_pa"]]
                                                  - ATMOSPHERIC_PRESSURE_PA),
                       "chamber_b_gauge_pa": span(ys[:, idx["chamber_b_pa"]]
                                                  - ATMOSPHERIC_PRESSURE_PA),
                       "force_n": span(force), "position_m": span(ys[:, idx["position_m"]])},
            "motor_speed_peak_rad_s": float(np.max(np.abs(ys[:, idx["speed_rad_s"]]))),
            "oil_temperature_rise_k": float(ys[-1, idx["fluid_temperature_k"]]
                                            - ys[0, idx["fluid_temperature_k"]]),
            "max_force_n": float(force.max()),
            "energy": {"input_j": float(eb["input_j"]), "output_j": float(eb["output_j"]),
                       "load_out_j": float(eb.get("load_out_j", eb["output_j"])),
                       "heat_j": {k: float(v) for k, v in eb["heat_j"].items()},
                       "stored_change_j": float(eb["stored_change_j"]),
                       "residual_j": float(eb["residual_j"]),
                       "relative_residual": float(eb["relative_residual"])}}
