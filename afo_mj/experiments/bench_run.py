"""A bench scenario run: the HAFO bench, the stiffness bench or a circuit bench, with the
summary ``afo-mj run`` writes for it (the ``bench.*``, ``stiffness.*`` and ``ledger`` names
documented in :mod:`afo_mj.scenarios.bench_scenario`)."""

from __future__ import annotations

from afo_mj.scenarios.bench_scenario import BenchScenario

__all__ = ["run_bench_scenario"]


def run_bench_scenario(bs: BenchScenario) -> tuple[dict, dict]:
    """Run the bench; returns ``(summary, series)`` with the ``bench.*`` names of issue 4
    (``bench.kind = "stiffness"``: the ``stiffness.*`` names, module docstring)."""
    if bs.bench_kind == "stiffness":
        return _run_stiffness_bench(bs)
    if bs.bench_kind == "circuit":
        return _run_circuit_bench(bs)
    from afo_mj.devices.hafo import HafoDevice
    from afo_mj.experiments.hafo_bench import run_bench
    res, series = run_bench(bs.params, bs.tests, bs.body_mass_kg, bs.height_m,
                            timestep_s=bs.timestep_s)
    # wall time is not a result (it goes to run_info.json): a rerun gives the same summary
    res.pop("wall_time_s", None)
    scalars = {k: v for k, v in res.items()
               if isinstance(v, (int, float)) and not isinstance(v, bool)}
    detail = {k: v for k, v in res.items() if k not in scalars and k != "published"}
    dev = HafoDevice(bs.params)
    summary = {
        "format": "afo_mj bench summary v1",
        "scenario": bs.as_dict(),
        "bench": scalars,
        "bench_detail": detail,
        "published": res["published"],
        "device": {"preset": bs.preset, "mass_total_kg": dev.mass_total_kg,
                   "mass_at_ankle_kg": dev.mass_at_ankle_kg},
        "energy": {"balance_error_rel": res["energy_error_max"],
                   "note": "largest |residual| / max(|electrical in|, |mechanical out|) "
                           "over every bench run"},
    }
    return summary, series


def _run_stiffness_bench(bs: BenchScenario) -> tuple[dict, dict]:
    from afo_mj.devices.valve_afo import ValveAfoDevice
    from afo_mj.experiments.stiffness_bench import run_stiffness_bench
    res, series = run_stiffness_bench(bs.params, bs.stiffness)
    dev = ValveAfoDevice(bs.params)
    worst = max(res["stiffness"].values(), key=lambda v: abs(v["energy_balance_error_rel"]))
    summary = {
        "format": "afo_mj stiffness bench summary v1",
        "scenario": bs.as_dict(),
        "stiffness": res["stiffness"],
        "sweep": res["sweep"],
        "acceptance": res["acceptance"],
        "device": {"preset": bs.preset, "mass_total_kg": dev.mass_total_kg,
                   "mass_at_ankle_kg": dev.mass_at_ankle_kg,
                   "max_torque_nm": bs.params.max_torque_nm,
                   "supply_pressure_set_pa": bs.params.supply_pressure_set_pa},
        "energy": {"balance_error_rel": worst["energy_balance_error_rel"],
                   "energy_error_max": res["energy_error_max"],
                   "newton_unconverged_steps": sum(v["newton_unconverged_steps"]
                                                   for v in res["stiffness"].values()),
                   "battery_overload_steps": sum(v["battery_overload_steps"]
                                                 for v in res["stiffness"].values()),
                   "note": "balance_error_rel: the largest |ledger residual| / battery energy "
                           "drawn over the sweeps; energy_error_max: the largest |residual| / "
                           "max(|electrical in|, |mechanical out|)"},
    }
    return summary, series


def _run_circuit_bench(bs: BenchScenario) -> tuple[dict, dict]:
    from afo_mj.experiments.circuit_bench import run_circuit_bench
    res, series = run_circuit_bench(bs.circuit, bs.tests, bs.circuit_bench)
    energy = res.pop("energy")
    ledger = res.pop("ledger")
    summary = {"format": "afo_mj circuit bench summary v1",
               "scenario": bs.as_dict(),
               "circuit": {"name": bs.circuit.circuit.name,
                           "controller": bs.circuit.circuit.controller.kind},
               "bench": res, "ledger": ledger, "energy": energy}
    return summary, series
