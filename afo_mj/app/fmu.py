"""``afo-mj export-fmu``: a scenario's circuit as an FMI 2.0 co-simulation FMU
(:mod:`afo_mj.outputs.fmu_export`).

The scenario is a walking or bench scenario file with a ``[circuit]`` description or a
``[device]`` preset that is a circuit (the pump-controlled HAFO presets, the valve presets),
or the bare name of such a preset. A preset is exported as the bench replay builds it
(:class:`afo_mj.experiments.bench_replay.BenchReplay`): the HAFO with its torque controller,
a valve circuit with its initial rail charge.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from afo_mj.app.errors import InvalidInput, RunFailed

__all__ = ["export_fmu", "scenario_circuit"]


def _preset_circuit(preset: str, params, key: str):
    """``(circuit, initial state)`` of a device preset's parameters."""
    from afo_mj.devices.hafo import PumpAnkleParams, hafo_circuit
    from afo_mj.devices.valve_afo import ValveAnkleParams, valve_circuit, valve_initial_state
    if isinstance(params, ValveAnkleParams):      # (a PumpAnkleParams subclass: first)
        return valve_circuit(params), valve_initial_state(params)
    if isinstance(params, PumpAnkleParams):
        return hafo_circuit(params, mode="torque"), {}
    raise InvalidInput(f"{key} = {preset!r} is not a circuit (nothing to export as an FMU); "
                       f"allowed: {', '.join(_circuit_presets())} or a [circuit] description")


def _circuit_presets() -> list[str]:
    from afo_mj.devices.hafo import PRESETS as HAFO_PRESETS
    from afo_mj.devices.valve_afo import VALVE_PRESETS
    return list(HAFO_PRESETS) + list(VALVE_PRESETS)


def scenario_circuit(scenario: str, overrides: Sequence[str] = ()):
    """``(circuit, initial state, origin)`` of a scenario file or preset name (see the module
    docstring); :class:`InvalidInput` naming what is wrong."""
    from afo_mj.scenarios.bench_scenario import is_bench_document, load_bench_scenario
    from afo_mj.scenarios.device_scenario import device_config, device_params
    from afo_mj.scenarios.walk_scenario import ScenarioError, load_scenario
    path = Path(scenario)
    if not path.is_file():
        if scenario in _circuit_presets():
            ov = {}
            for item in overrides:
                k, sep, v = item.partition("=")
                if not sep or not k.startswith("device.params."):
                    raise InvalidInput(f"--set {item!r} with preset {scenario!r}; allowed: "
                                       "device.params.NAME=VALUE")
                ov[k[len("device.params."):]] = float(v) if _is_number(v) else v
            try:
                preset, params, _ = device_params({"preset": scenario, "params": ov},
                                                  "export-fmu")
            except ScenarioError as exc:
                raise InvalidInput(str(exc)) from None
            c, init = _preset_circuit(preset, params, "SCENARIO")
            return c, init, f"preset {scenario}"
        raise InvalidInput(f"SCENARIO = {scenario!r}: no such file; allowed: a scenario file "
                           "with a [circuit] or a [device] preset, or a preset name ("
                           f"{', '.join(_circuit_presets())})")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"SCENARIO = {scenario!r}: cannot read it ({exc})") from None
    try:
        if is_bench_document(text):
            bs = load_bench_scenario(path, overrides=overrides)
            if bs.circuit is not None:
                return bs.circuit.circuit, {}, str(path)
            c, init = _preset_circuit(bs.preset, bs.params, f"{path}: device.preset")
            return c, init, str(path)
        sc = load_scenario(path, overrides=overrides)
        cfg = device_config(sc)
    except ScenarioError as exc:
        raise InvalidInput(f"invalid scenario: {exc}") from None
    if cfg is None:
        raise InvalidInput(f"{path}: no [circuit] and no [device]: nothing to export as an "
                           "FMU; allowed: a scenario with a [circuit] description or a "
                           f"[device] preset ({', '.join(_circuit_presets())})")
    if cfg.circuit is not None:
        return cfg.circuit.circuit, {}, str(path)
    c, init = _preset_circuit(cfg.preset, cfg.params, f"{path}: device.preset")
    return c, init, str(path)


def _is_number(v: str) -> bool:
    try:
        float(v)
        return True
    except ValueError:
        return False


def export_fmu(scenario: str, out, overrides: Sequence[str] = (), timestep_s: float = 5e-4,
               step_size_s: float = 1e-3) -> dict:
    """Write the scenario's circuit as an FMU at ``out`` (see
    :func:`afo_mj.outputs.fmu_export.write_fmu`); returns its summary with ``origin``."""
    from afo_mj.circuits.components import CircuitError
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.outputs.fmu_export import FmuBuildError, FmuExportError, write_fmu
    circuit, init, origin = scenario_circuit(scenario, overrides)
    try:
        info = write_fmu(circuit, out, initial_state=init, timestep_s=timestep_s,
                         step_size_s=step_size_s,
                         description=f"afo_mj circuit {circuit.name!r} from {origin} "
                                     f"({circuit.controller.kind} controller), joint motion "
                                     "imposed")
    except FmuBuildError as exc:
        raise RunFailed(f"{exc}; nothing written") from None
    except (FmuExportError, CircuitError, ParameterError) as exc:
        raise InvalidInput(f"{exc}; nothing written") from None
    except OSError as exc:
        raise RunFailed(f"writing {out}: {exc}; nothing written") from None
    return {**info, "origin": origin}
