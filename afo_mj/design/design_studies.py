"""The design-guideline studies: lightest design per operating pressure, oil grade and output
power (:func:`guideline_studies`) and the hose-bore trade-off of the best design
(:func:`hose_bore_study`), each a search (:func:`~afo_mj.design.design_search.size_system`) or
an exact evaluation (:func:`~afo_mj.design.design_evaluation.evaluate_designs`) of designs
derived from the requirements.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from afo_mj.design.design_evaluation import _rated_power, _row, evaluate_designs
from afo_mj.design.design_models import DesignAssumptions
from afo_mj.design.design_requirements import Requirements
from afo_mj.design.design_search import DesignResult, size_system


def hose_bore_study(result: DesignResult, k: int = 0, bores=None) -> dict:
    """The hose bore trade-off of the ``k``-th best design: only the hose bore changes, the
    battery is re-sized for the energy the line loss costs. ``total_kg`` holds the motor too
    (the pure trade-off: hose wall and oil mass against the battery that pays for the viscous
    loss, the mass + loss objective); ``total_reoptimised_kg`` lets each bore take its lightest
    feasible motor of the grid (inf where none is feasible) and ``feasible`` says whether the
    held-motor design meets every constraint."""
    ev, i = result.designs, int(result.order[k])
    req = result.requirements
    bores = np.asarray(bores if bores is not None else np.geomspace(
        *req.search.hose_bore_range_m, 25), dtype=float)
    spec = {key: np.repeat(np.asarray(v)[i], bores.size) for key, v in ev["spec"].items()}
    spec["hose_bore_m"] = bores
    e2 = evaluate_designs(spec, req, result.duty, result.assumptions)
    powers = np.asarray(result.grid["motor_power_w"])
    spec_m = {key: np.repeat(v, powers.size) for key, v in spec.items()}
    spec_m["motor_power_w"] = np.tile(powers, bores.size)
    e3 = evaluate_designs(spec_m, req, result.duty, result.assumptions)
    m3 = np.where(e3["feasible"], e3["total_kg"], np.inf).reshape(bores.size, powers.size)
    return {"hose_bore_m": bores, "total_kg": e2["total_kg"],
            "battery_kg": e2["mass"]["battery"], "hoses_kg": e2["mass"]["hoses"],
            "line_loss_j_per_stride": e2["energy_j"]["line"],
            "system_efficiency": e2["system_efficiency"], "feasible": e2["feasible"],
            "surface_temperature_k": e2["surface_temperature_k"],
            "peak_reynolds": e2["peak_reynolds"], "total_reoptimised_kg": m3.min(axis=1),
            "motor_reoptimised_w": powers[np.argmin(m3, axis=1)]}


def _best_by(result: DesignResult, key: str) -> dict:
    """The lightest feasible exact-evaluated design per value of ``spec[key]``."""
    ev = result.designs
    vals = ev["spec"][key]
    out = {}
    for v in np.unique(vals):
        sel = np.flatnonzero((vals == v) & ev["feasible"])
        if sel.size:
            out[v.item() if hasattr(v, "item") else v] = int(sel[np.argmin(ev["total_kg"][sel])])
    return out


def _study_row(result: DesignResult, i: int) -> dict:
    row = _row(result.designs, i, result.requirements)
    return {"operating_pressure_pa": row["operating_pressure_pa"], "oil": row["oil"],
            "rated_output_power_w": row["rated_output_power_w"],
            "total_kg": row["total_kg"], "ankle_kg": row["ankle_kg"],
            "waist_kg": row["waist_kg"], "system_efficiency": row["system_efficiency"],
            "pump_efficiency": row["efficiency"]["pump"],
            "motor_efficiency": row["efficiency"]["motor"],
            "lines_efficiency": row["efficiency"]["lines"],
            "cylinders_efficiency": row["efficiency"]["cylinders"],
            "hydraulic_power_density_w_kg": row["hydraulic_power_density_w_kg"],
            "system_energy_density_wh_kg": row["system_energy_density_wh_kg"],
            "cylinder_bore_m": row["cylinder_bore_m"], "pulley_radius_m": row["pulley_radius_m"],
            "hose_bore_m": row["hose_bore_m"],
            "pump_displacement_m3_rev": row["pump_displacement_m3_rev"],
            "motor_rated_power_w": row["motor_rated_power_w"],
            "surface_temperature_k": row["surface_temperature_k"],
            "runtime_h": row["runtime_h"]}


def guideline_studies(req: Requirements, assumptions: DesignAssumptions | None = None,
                      pressure_range_pa=(4e6, 21e6), pressure_points: int = 8,
                      power_factors=(0.25, 0.5, 1.0, 2.0, 3.0)) -> dict:
    """The seed's design-guideline studies on ``req``: for each operating pressure (a sweep
    over ``pressure_range_pa``), each oil grade and each output power (the requirement's
    speed, or profile torque, scaled by ``power_factors``), the lightest feasible design's
    mass, efficiencies, hydraulic power density (rated output power / mass of motor, pump,
    manifold, hoses, cylinders and pulley) and system energy density (positive work over the
    runtime / total mass). The studies search a coarser grid than the design itself (at most
    12 motors, 7 arms, 60 duty samples). Returns
    ``{"pressure": [rows], "oil": [rows], "power": [rows]}``.
    """
    a = assumptions or DesignAssumptions()
    out = {"pressure": [], "oil": [], "power": []}
    g = req.search
    coarse = dataclasses.replace(                 # the studies' grid: coarser than the design's
        g, motor_power_points=min(g.motor_power_points, 12),
        moment_arm_points=min(g.moment_arm_points, 7),
        duty_samples=min(g.duty_samples, 60))
    req = req.with_changes(search=coarse)
    sweep = req.with_changes(pressure_range_pa=tuple(pressure_range_pa),
                             search=dataclasses.replace(coarse,
                                                        pressure_points=pressure_points))
    res = size_system(sweep, a, n_exact=120)
    if res.feasible:
        for p, i in sorted(_best_by(res, "pressure_pa").items()):
            out["pressure"].append(_study_row(res, i))
        for o, i in sorted(_best_by(res, "oil").items()):
            out["oil"].append(_study_row(res, i))
    for f in power_factors:
        if req.profile == "corner":
            r2 = req.with_changes(peak_velocity_rad_s=req.peak_velocity_rad_s * f)
        elif req.profile == "normative":
            r2 = req.with_changes(torque_fraction=req.torque_fraction * f)
        else:
            r2 = req.with_changes(profile_torque_nm=tuple(np.asarray(req.profile_torque_nm) * f))
        rr = size_system(r2, a, n_exact=40)
        row = {"power_factor": f, "rated_output_power_w": _rated_power(r2, rr.duty),
               "feasible": rr.feasible}
        if rr.feasible:
            row.update(_study_row(rr, int(rr.order[0])))
        else:
            row["binding"] = rr.binding
        out["power"].append(row)
    return out
