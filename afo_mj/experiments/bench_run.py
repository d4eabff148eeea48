"""A bench run: one set of protocols on any device that drives a joint, on the rig its
scenario names, with the summary ``afo-mj run`` writes (the ``bench.*``, ``stiffness.*`` and
``ledger`` names documented in :mod:`afo_mj.scenarios.bench_scenario`).

:func:`run_bench` takes a :class:`~afo_mj.circuits.device_spec.DeviceSpec` (a registered
device, :func:`afo_mj.devices.registry.device_spec`; a ``[circuit]`` description,
:meth:`DeviceSpec.from_circuit`; a scenario file's device,
:func:`afo_mj.scenarios.device_source.device_source`) and the protocols; each protocol's needs
are checked against the spec first (:func:`afo_mj.scenarios.bench_protocols.check_protocols`).
"""

from __future__ import annotations

from afo_mj.scenarios.bench_protocols import (RIGS, BenchError, LoadBenchConfig,
                                              StiffnessSweepConfig, check_protocols)
from afo_mj.scenarios.bench_scenario import BenchScenario

__all__ = ["run_bench", "run_bench_scenario", "published_figures"]


def run_bench(spec, protocols, rig: str = "stand", *, body_mass_kg: float = 75.0,
              height_m: float = 1.75, timestep_s: float | None = None,
              stiffness: StiffnessSweepConfig | None = None,
              load: LoadBenchConfig | None = None) -> tuple[dict, dict]:
    """Run ``protocols`` on device ``spec`` on ``rig``: the stand
    (:func:`afo_mj.experiments.bench_stand.run_stand`: ``body_mass_kg``, ``height_m``,
    ``timestep_s``, the ``stiffness`` sweep) or the simulated load
    (:func:`afo_mj.experiments.bench_load.run_load_bench`: ``load`` settings). Returns that
    rig's ``(result, series)``; a protocol the device cannot run raises
    :class:`~afo_mj.scenarios.bench_protocols.ProtocolError` naming it, the device and what
    the device lacks."""
    if rig not in RIGS:
        raise BenchError(f"rig = {rig!r}; allowed: {', '.join(RIGS)}")
    protocols = (protocols,) if isinstance(protocols, str) else tuple(protocols)
    check_protocols(spec, protocols, rig)
    if rig == "load":
        from afo_mj.experiments.bench_load import run_load_bench
        return run_load_bench(spec, protocols, LoadBenchConfig() if load is None else load)
    from afo_mj.experiments.bench_stand import run_stand
    return run_stand(spec, protocols, body_mass_kg, height_m, timestep_s=timestep_s,
                     stiffness=stiffness)


def published_figures(spec) -> dict | None:
    """The published figures a device is compared with (its spec's,
    :attr:`~afo_mj.circuits.device_spec.DeviceSpec.published`: the HAFO prototype's for the
    pump-controlled HAFO presets), else None."""
    return dict(spec.published) or None


def _device_summary(bs: BenchScenario) -> dict:
    from afo_mj.circuits.device import CircuitDevice
    spec = bs.spec
    dev = CircuitDevice(spec)
    out = {"preset": bs.preset, "name": spec.name,
           "controller": spec.circuit.controller.kind,
           "mass_total_kg": dev.mass_total_kg, "mass_at_ankle_kg": dev.mass_at_ankle_kg}
    for key in ("max_torque_nm", "supply_pressure_set_pa"):
        v = getattr(spec.params, key, None)
        if v is not None:
            out[key] = v
    return out


def run_bench_scenario(bs: BenchScenario) -> tuple[dict, dict]:
    """Run the bench scenario; returns ``(summary, series)``. The summary holds ``format``,
    ``scenario``, ``rig``, ``protocols``, ``device`` (its name, controller, masses), and

    * on the stand: ``bench`` (the scalar figures, the ``bench.*`` names of issue 4),
      ``bench_detail`` (per-level and per-run detail), ``published`` (the figures the
      device is compared with, where there are), with the stiffness protocol ``stiffness``
      (per ``k<K>``), ``sweep`` and ``acceptance``; ``energy.balance_error_rel``: the worst
      ``|residual| / max(|input|, |mechanical out|)`` of any run;
    * on the load: ``circuit`` (name, controller), ``bench`` (per protocol), ``ledger`` (per
      run) and ``energy`` (the worst ledger residual over its throughput)."""
    res, series = run_bench(bs.spec, bs.protocols, bs.rig, body_mass_kg=bs.body_mass_kg,
                            height_m=bs.height_m, timestep_s=bs.timestep_s,
                            stiffness=bs.stiffness, load=bs.load)
    summary = {"format": "afo_mj bench summary v2", "scenario": bs.as_dict(), "rig": bs.rig,
               "protocols": list(bs.protocols), "notes": list(bs.notes)}
    if bs.rig == "load":
        energy = res.pop("energy")
        ledger = res.pop("ledger")
        summary.update({"device": _device_summary(bs),
                        "circuit": {"name": bs.spec.circuit.name,
                                    "controller": bs.spec.circuit.controller.kind},
                        "bench": res, "ledger": ledger, "energy": energy})
        return summary, series
    rig_keys = ("stiffness", "sweep", "acceptance")
    scalars = {k: v for k, v in res.items()
               if isinstance(v, (int, float)) and not isinstance(v, bool)}
    detail = {k: v for k, v in res.items() if k not in scalars and k not in rig_keys}
    summary.update({"bench": scalars, "bench_detail": detail, "device": _device_summary(bs)})
    pub = published_figures(bs.spec)
    if pub is not None:
        summary["published"] = pub
    energy = {"balance_error_rel": res["energy_error_max"],
              "note": "largest |residual| / max(|input|, |mechanical out|) over every bench "
                      "run"}
    if "stiffness" in res:
        per = res["stiffness"].values()
        summary.update({k: res[k] for k in rig_keys})
        energy.update(
            stiffness_ledger_error_rel=max((v["energy_balance_error_rel"] for v in per),
                                           key=abs),
            newton_unconverged_steps=sum(v["newton_unconverged_steps"] for v in per),
            battery_overload_steps=sum(v["battery_overload_steps"] for v in per))
    summary["energy"] = energy
    return summary, series
