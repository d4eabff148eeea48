"""``afo-mj export-fmu``: a scenario's circuit as an FMI 2.0 co-simulation FMU
(:mod:`afo_mj.outputs.fmu_export`).

The scenario is a walking or bench scenario file with a ``[circuit]`` description or a
``[device]`` preset that is a circuit, or the name of a registered device
(:func:`afo_mj.scenarios.device_source.device_source`). The device is exported as its spec
describes it (:class:`afo_mj.circuits.device_spec.DeviceSpec`), as the bench replay builds it:
the circuit as worn (the HAFO with its torque controller) from its initial state (a valve
circuit's charged rail).
"""

from __future__ import annotations

from typing import Sequence

from afo_mj.app.errors import InvalidInput, RunFailed

__all__ = ["export_fmu", "scenario_circuit"]


def scenario_circuit(scenario: str, overrides: Sequence[str] = ()):
    """``(circuit, initial state, origin)`` of a scenario file or a registered device's name
    (:func:`afo_mj.scenarios.device_source.device_source`); :class:`InvalidInput` naming what
    is wrong."""
    from afo_mj.circuits.components import CircuitError
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.scenarios.device_source import device_source
    from afo_mj.scenarios.walk_scenario import ScenarioError
    try:
        spec, origin = device_source(scenario, overrides)
    except (ScenarioError, CircuitError, ParameterError) as exc:
        raise InvalidInput(f"invalid scenario: {exc}") from None
    if origin == spec.name:
        origin = f"device {spec.name}"
    return spec.circuit, dict(spec.initial_state), origin


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
