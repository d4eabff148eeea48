"""The design search: the lightest designs that meet the requirements, or why none does.

The search (:func:`size_system`), pump-controlled architecture
---------------------------------------------------------------
Design variables: operating pressure ``p`` (fixed or a geometric grid over the allowed range),
cylinder bore ``D`` (grid step ``search.cylinder_bore_step_m``), pulley radius ``r``, hose bore,
pump displacement, oil grade and motor rated power ``P``. The stages, each vectorised with
numpy broadcasting and each pruning by constraints before the next multiplies the grid:

1. **actuator** (``p × D × r``): cable from its breaking load at the relief's full-open pressure,
   effective area ``A_e = n π/4 (D² − d_c²)``; torque constraint ``A_e r p ≥ τ_max`` (the largest
   torque asked); kept: for each ``(p, r)`` the bores whose ``A_e r`` is within
   ``BORE_WINDOW`` of the smallest that carries the torque (a bigger bore at the same pressure
   and arm only adds mass, friction and flow).
2. **hydraulic chain** (× hose bore × displacement × oil) at the constraint points, cold oil
   (ambient: the device starts cold, as the bench does): pump pressure ``|Δp_p| ≤ p``, pump
   and motor speed limits, laminar hoses (``Re ≤ 2000``: the compiled actuator's hoses are
   laminar), pump pressure rating; then the duty-cycle sums every motor needs
   (:mod:`afo_mj.design.design_screening`).
3. **motor** (× rated power): the winding's ``K`` is the largest that still reaches every
   constraint point at ``duty_max`` of the pack voltage at ``min_state_of_charge``
   (``v = K (T_m/k_m² + ω)``, so copper loss ``(T_m/k_m)²`` does not depend on ``K`` but the
   currents fall as ``K`` rises); the driver's current limit is the largest constraint current,
   so the stall torque is the torque asked. Motor thermal (mean loss ≤ its continuous
   rating) and peak (copper ≤ ``motor_peak_loss_ratio`` × continuous) limits, driver current,
   battery sized for the runtime energy and its C-rate, skin-safe pack surface temperature.
4. **exact evaluation** (:func:`~afo_mj.design.design_evaluation.evaluate_designs`) of the best
   screened designs (and the best per pressure and per oil, for the studies): oil at its
   steady temperature (fixed point with the pack's natural convection and radiation), the
   battery's Rint loss per sample, the winding and current limit recomputed with the actual
   voltage sag and hot and cold oil.
   Designs are ranked by total mass (one side: ankle parts + power supply at the waist).

The objective is mass alone: losses cost battery (and motor) mass through the runtime, so
``total mass`` is the mass + loss objective of the seed's tool.

Valve-controlled and digital circuits (``architecture = "valve" | "digital"``) go through the
same stages on the same worn parts, their supply modelled by
:func:`~afo_mj.design.design_models.supply_steady` (a servo valve also needs its pressure
margin on top of the load in stage 1); they are reported, not bench-tested: the
torque–velocity bench drives the pump-controlled kernel only.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np

from afo_mj.design.design_evaluation import (RE_LAMINAR, _base, _grids, _rated_power, _row,
                                              _supply_figures, actuator_geometry,
                                              evaluate_designs)
from afo_mj.design.design_models import DesignAssumptions
from afo_mj.design.design_requirements import DutyCycle, Requirements, duty_cycle
from afo_mj.design.design_screening import _pareto_samples, _screen


#: Bores kept per (pressure, arm): those whose ``A_e r`` is within this fraction of the smallest
#: that carries the torque (friction and line loss at speed need a little more).
BORE_WINDOW = 0.10
#: Designs carried from the screening into the exact evaluation (best by screened mass).
N_EXACT = 240
#: Larger motors tried beside the screened one in the exact pass.
MOTOR_ALTERNATIVES = 2
#: Rounds and breadth of the local search around the lightest exact designs.
REFINE_ROUNDS = 3
REFINE_TOP = 6


@dataclasses.dataclass
class DesignResult:
    """What :func:`size_system` found (its JSON form:
    :func:`afo_mj.design.design_document.design_summary`)."""

    requirements: Requirements
    assumptions: DesignAssumptions
    duty: DutyCycle
    feasible: bool
    designs: dict | None                 # evaluate_designs output for the ranked designs
    order: np.ndarray | None             # ranked feasible indices into ``designs``
    explanation: str | None
    binding: list[str]
    counts: dict                         # designs ruled out per constraint, per stage
    grid: dict
    screened: int
    wall_s: float
    best_limits: dict = dataclasses.field(default_factory=dict)

    def row(self, k: int = 0) -> dict:
        """The ``k``-th best design as a flat dict of scalars (SI units in the names)."""
        return _row(self.designs, int(self.order[k]), self.requirements)


def size_system(req: Requirements, assumptions: DesignAssumptions | None = None,
                n_exact: int = N_EXACT) -> DesignResult:
    """Search the design grid of ``req`` for the lightest feasible designs (module
    docstring); ``architecture = "valve" | "digital"`` goes through the same stages with its
    supply (:func:`~afo_mj.design.design_models.supply_steady`)."""
    t0 = time.perf_counter()
    a = assumptions or DesignAssumptions()
    base = _base()
    duty = duty_cycle(req)
    grids = _grids(req)
    counts: dict[str, int] = {}
    limits: dict[str, Any] = {}
    t_need = float(np.max(np.abs(duty.constraint_torque_nm)))
    # ---- stage 1: actuator ------------------------------------------------------------------
    P, B, R = np.meshgrid(grids["pressure_pa"], grids["bore_m"], grids["arm_m"], indexing="ij")
    geo = actuator_geometry(P, B, R, req.range_of_motion_rad, a, base)
    ok_cable = geo["cable_m"] <= 0.5 * B
    # the servo valve needs its margin on top of the load pressure
    p_load = P - (_supply_figures().margin_pa if req.architecture == "valve" else 0.0)
    cap = np.where(ok_cable, geo["torque_per_pressure_m3"] * p_load, 0.0)
    ok_t = ok_cable & (cap >= t_need)
    counts["cable"] = int(np.count_nonzero(~ok_cable))
    counts["torque"] = int(np.count_nonzero(ok_cable & ~ok_t))
    j = int(np.argmax(cap))
    limits["torque"] = {"torque_nm": t_need, "max_torque_nm": float(cap.flat[j]),
                        "at_pressure_pa": float(P.flat[j]), "at_bore_m": float(B.flat[j]),
                        "at_arm_m": float(R.flat[j]),
                        "at_cable_m": float(geo["cable_m"].flat[j]),
                        "max_torque_per_pressure_m3": float(
                            geo["torque_per_pressure_m3"].flat[j]),
                        "needed_torque_per_pressure_m3": t_need / float(p_load.flat[j]),
                        "load_pressure_pa": float(p_load.flat[j])}
    if not np.any(ok_t):
        return _infeasible(req, a, duty, grids, counts, limits, ["torque"], t0, 0)
    aer = np.where(ok_t, geo["torque_per_pressure_m3"], np.inf)
    aer_min = aer.min(axis=1, keepdims=True)
    keep = ok_t & (aer <= aer_min * (1.0 + BORE_WINDOW))
    ip, ib, ir = np.nonzero(keep)
    act = {"pressure_pa": grids["pressure_pa"][ip], "bore_m": grids["bore_m"][ib],
           "arm_m": grids["arm_m"][ir]}
    # ---- stages 2 and 3: × hose × oil (line), × displacement (pump), × motor ---------------
    screened = ip.size * grids["hose_bore_m"].size * len(grids["oil"]) \
        * grids["displacement_m3_rev"].size
    cidx = (np.arange(duty.constraint_torque_nm.size) if req.profile == "corner"
            else _pareto_samples(duty.constraint_torque_nm, duty.constraint_velocity_rad_s))
    sc = _screen(act, req, duty, a, base, grids, cidx, counts, limits)
    if sc is None:
        return _infeasible(req, a, duty, grids, counts, limits, limits["stage2_binding"], t0,
                           screened)
    spec_f, best_m, best_mass = sc
    ok = np.isfinite(best_mass)
    if not np.any(ok):
        return _infeasible(req, a, duty, grids, counts, limits,
                           limits.get("motor_binding", []), t0, screened)
    # ---- stage 4: exact evaluation of the best (overall, per pressure, per oil) -------------
    cand = np.flatnonzero(ok)
    order = cand[np.argsort(best_mass[cand], kind="stable")]
    pick = list(order[:n_exact])
    for key in ("pressure_pa", "oil", "displacement_m3_rev", "hose_bore_m"):
        vals = spec_f[key][order]
        _, first = np.unique(vals, return_index=True)
        pick.extend(order[first])
        if key == "pressure_pa":          # a few per pressure for the studies
            for v in np.unique(vals):
                pick.extend(order[vals == v][:16])
    pick = np.unique(np.asarray(pick, dtype=int))
    # each picked design with its screened motor and the next larger ones (the exact pass may
    # find a little more heat than the screening: a larger motor sheds less copper loss)
    nmot = grids["motor_power_w"].size
    reps = [np.minimum(best_m[pick] + j, nmot - 1) for j in range(MOTOR_ALTERNATIVES + 1)]
    spec_x = {k: np.concatenate([v[pick]] * len(reps)) for k, v in spec_f.items()}
    spec_x["motor_power_w"] = grids["motor_power_w"][np.concatenate(reps)]
    ev = evaluate_designs(spec_x, req, duty, a, base)
    ev = _refine(ev, grids, req, duty, a, base)
    ev["feasible"] = ev["feasible"] & _lightest_motor_only(ev)
    feas = np.flatnonzero(ev["feasible"])
    if feas.size == 0:
        worst = {}
        for k, v in ev["margins"].items():
            worst[k] = int(np.count_nonzero(v < -1e-9))
        counts.update({f"exact:{k}": v for k, v in worst.items() if v})
        binding = [max(worst, key=worst.get)] if worst else []
        res = _infeasible(req, a, duty, grids, counts, limits, binding, t0, screened)
        res.designs = ev
        return res
    ranked = feas[np.argsort(ev["total_kg"][feas], kind="stable")]
    return DesignResult(requirements=req, assumptions=a, duty=duty, feasible=True, designs=ev,
                        order=ranked, explanation=None, binding=[], counts=counts,
                        grid={k: (list(map(float, v)) if k != "oil" else v)
                              for k, v in grids.items()},
                        screened=screened, wall_s=time.perf_counter() - t0, best_limits=limits)


_AXES = ("pressure_pa", "bore_m", "arm_m", "hose_bore_m", "displacement_m3_rev",
         "motor_power_w")


def _hydraulic_key(spec: dict, i: int) -> tuple:
    return tuple(round(float(spec[k][i]), 12) for k in _AXES[:-1]) + (int(spec["oil"][i]),)


def _lightest_motor_only(ev: dict) -> np.ndarray:
    """Mask keeping, per hydraulic design (everything but the motor), its lightest feasible
    motor."""
    sp = ev["spec"]
    mass = np.where(ev["feasible"], ev["total_kg"], np.inf)
    best: dict[tuple, int] = {}
    for i in range(mass.size):
        k = _hydraulic_key(sp, i)
        if k not in best or mass[i] < mass[best[k]]:
            best[k] = i
    keep = np.zeros(mass.size, dtype=bool)
    for i in best.values():
        keep[i] = np.isfinite(mass[i])
    return keep


def _concat(x, y):
    """Two :func:`~afo_mj.design.design_evaluation.evaluate_designs` outputs joined design-wise."""
    if isinstance(x, dict):
        return {k: _concat(x[k], y[k]) for k in x}
    if isinstance(x, tuple):
        return tuple(_concat(u, v) for u, v in zip(x, y))
    if isinstance(x, np.ndarray) and x.ndim >= 1:
        return np.concatenate([x, y])
    return x


def _refine(ev: dict, grids: dict, req, duty, a, base, rounds: int = REFINE_ROUNDS,
            top: int = REFINE_TOP) -> dict:
    """Local search around the lightest exactly evaluated designs: each design variable one
    grid step either way (every other oil), evaluated exactly, for a few rounds or until the
    lightest design stops improving (the screening's approximations can miss a neighbour)."""
    seen = {tuple(_hydraulic_key(ev["spec"], i)) + (round(float(ev["spec"]["motor_power_w"][i]),
                                                          9),)
            for i in range(ev["total_kg"].size)}
    gv = {k: np.asarray(grids[k]) for k in _AXES}
    noil = len(grids["oil"])
    for _ in range(rounds):
        mass = np.where(ev["feasible"], ev["total_kg"], np.inf)
        if not np.any(np.isfinite(mass)):
            return ev
        best_before = float(mass.min())
        tops = np.argsort(mass, kind="stable")[:top]
        tops = tops[np.isfinite(mass[tops])]
        new = {k: [] for k in _AXES + ("oil",)}
        for i in tops:
            cur = {k: float(ev["spec"][k][i]) for k in _AXES}
            cur["oil"] = int(ev["spec"]["oil"][i])
            cands = []
            for k in _AXES:
                j = int(np.argmin(np.abs(gv[k] - cur[k])))
                for dj in (-1, 1):
                    if 0 <= j + dj < gv[k].size:
                        c = dict(cur)
                        c[k] = float(gv[k][j + dj])
                        cands.append(c)
            for o in range(noil):
                if o != cur["oil"]:
                    c = dict(cur)
                    c["oil"] = o
                    cands.append(c)
            for c in cands:
                key = tuple(round(c[k], 12) for k in _AXES[:-1]) + (c["oil"],) \
                    + (round(c["motor_power_w"], 9),)
                if key in seen:
                    continue
                seen.add(key)
                for k in new:
                    new[k].append(c[k])
        if not new["oil"]:
            return ev
        spec_n = {k: np.asarray(v, dtype=int if k == "oil" else float) for k, v in new.items()}
        ev = _concat(ev, evaluate_designs(spec_n, req, duty, a, base))
        mass = np.where(ev["feasible"], ev["total_kg"], np.inf)
        if float(mass.min()) >= best_before - 1e-9:
            return ev
    return ev


def _infeasible(req, a, duty, grids, counts, limits, binding, t0, screened) -> DesignResult:
    return DesignResult(requirements=req, assumptions=a, duty=duty, feasible=False, designs=None,
                        order=None, explanation=explain(req, grids, counts, limits, binding, a),
                        binding=list(binding), counts=counts,
                        grid={k: (list(map(float, v)) if k != "oil" else v)
                              for k, v in grids.items()},
                        screened=screened, wall_s=time.perf_counter() - t0, best_limits=limits)


def explain(req: Requirements, grids: dict, counts: dict, limits: dict, binding,
            a: DesignAssumptions) -> str:
    """A sentence per binding constraint, with the numbers that bind."""
    out = []
    plo, phi = req.pressure_range_pa
    for name in binding[:3]:
        if name == "torque":
            t = limits["torque"]
            pl = t.get("load_pressure_pa", phi)
            via = ("" if pl == phi else f" ({phi / 1e6:.1f} MPa less the servo valve's "
                   f"{(phi - pl) / 1e6:.1f} MPa margin)")
            out.append(
                f"torque {t['torque_nm']:.0f} N·m needs A_e r ≥ "
                f"{t['torque_nm'] / pl:.3g} m³ at {pl / 1e6:.1f} MPa{via} (the highest "
                f"operating pressure allowed); the largest bore "
                f"{grids['bore_m'].max() * 1e3:.1f} mm "
                f"(with a {t['at_cable_m'] * 1e3:.1f} mm cable) and arm "
                f"{grids['arm_m'].max() * 1e3:.0f} mm give A_e r = "
                f"{t['max_torque_per_pressure_m3']:.3g} m³, {t['max_torque_nm']:.0f} N·m at most"
                f" — raise operating_pressure_pa, search.cylinder_bore_range_m or "
                f"moment_arm_m [constraint: torque]")
        elif name == "cable":
            out.append("no bore holds a cable strong enough for its own piston force "
                       "[constraint: cable]")
        elif name == "pump_pressure":
            out.append(f"the operating pressure {plo / 1e6:.1f} MPa exceeds the pump rating "
                       f"{a.pump_max_pressure_pa / 1e6:.1f} MPa [constraint: pump_pressure]")
        elif name == "pressure":
            r_ = limits.get("stage2_best_ratio", {}).get("pressure", math.nan)
            out.append(f"at speed, seal friction and line loss (and a servo valve's margin) add "
                       f"to the load: the best design needs {r_:.3f} × the operating pressure "
                       f"at a constraint point — widen search.cylinder_bore_range_m or "
                       f"moment_arm_m [constraint: pressure]")
        elif name == "pump_speed":
            s = limits["speed"]
            out.append(
                f"speed {math.degrees(s['velocity_rad_s']):.0f} deg/s needs a pump flow of "
                f"{s['flow_needed_m3_s'] * 6e4:.2f} L/min with the smallest A_e r; the largest "
                f"pump {grids['displacement_m3_rev'].max() * 1e6:.2f} cm³/rev at the "
                f"{s['speed_limit_rad_s']:.0f} rad/s speed limit gives "
                f"{s['largest_flow_m3_s'] * 6e4:.2f} L/min — widen "
                f"search.pump_displacement_range_m3_rev [constraint: pump_speed]")
        elif name == "laminar":
            r_ = limits.get("stage2_best_ratio", {}).get("laminar", math.nan)
            out.append(f"even the widest hose {grids['hose_bore_m'].max() * 1e3:.1f} mm runs "
                       f"turbulent: Reynolds number {r_ * RE_LAMINAR:.0f} > {RE_LAMINAR:.0f} — "
                       f"widen search.hose_bore_range_m [constraint: laminar]")
        elif name == "surface_temperature":
            tmin = limits.get("motor", {}).get("min_surface_temperature_k", math.nan)
            rr = limits.get("motor_ratios", {}).get(name)
            if rr is not None:
                tmin = req.ambient_temperature_k + rr * (req.max_surface_temperature_k
                                                         - req.ambient_temperature_k)
            out.append(f"even the coolest design and motor tried reach a pack surface of "
                       f"{tmin:.1f} K "
                       f"({tmin - 273.15:.1f} °C) > the skin-safe "
                       f"{req.max_surface_temperature_k:.1f} K: the duty's losses cannot leave "
                       f"the pack by natural convection and radiation "
                       f"[constraint: surface_temperature]")
        elif name in ("motor_thermal", "motor_peak"):
            rr = limits.get("motor_ratios", {}).get(name, math.nan)
            what = ("mean loss over the duty cycle" if name == "motor_thermal"
                    else "peak copper loss")
            out.append(f"no motor of {grids['motor_power_w'].min():.0f}–"
                       f"{grids['motor_power_w'].max():.0f} W sheds the {what} within its "
                       f"rating: at best {rr:.2f} × the rating (the power asked, "
                       f"{_rated_power(req):.0f} W, is too much for the motor range) — widen "
                       f"search.motor_power_range_w or lower the requirement "
                       f"[constraint: {name}]")
        elif name == "driver_current":
            rr = limits.get("motor_ratios", {}).get(name, math.nan)
            out.append(f"the current limit would be at least {rr:.2f} × the driver's "
                       f"{a.driver_max_current_a:.0f} A [constraint: driver_current]")
        elif name == "winding":
            out.append("no realisable winding (K ≤ 10 N·m/A, R ≤ 100 Ω) [constraint: winding]")
        else:
            out.append(f"[constraint: {name}]")
    if not out:
        out.append("no design met every constraint")
    return "infeasible: " + "; ".join(out)
