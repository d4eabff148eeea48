"""``afo-mj schematic``: the circuit of a scenario, a device preset or a library circuit, drawn
as an ISO 1219-1-style schematic (:mod:`afo_mj.outputs.schematic`).

A source is a scenario TOML file (its ``[circuit]`` table, or its ``[device]`` preset with
``params`` overrides) or the name of a registered device (a preset or a library circuit:
:mod:`afo_mj.devices.registry`), resolved by
:func:`afo_mj.scenarios.device_source.device_source`. :func:`shipped_circuits` lists every
circuit the package ships (``tools/circuit_schematics.py`` draws them into ``docs/schematics``).
"""

from __future__ import annotations

from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["circuit_of", "shipped_circuits", "write_circuit_schematic", "SCENARIO_CIRCUITS"]

#: scenario files whose own ``[circuit]`` description (not a library name) is shipped
SCENARIO_CIRCUITS = ("scenarios/calibration/lab_rig.toml",)


def circuit_of(source: str, overrides=()):
    """``(circuit, title)`` of ``source``: a registered device's name or a scenario file
    (:func:`afo_mj.scenarios.device_source.device_source`); :class:`InvalidInput` naming the
    problem otherwise."""
    from afo_mj.circuits.components import CircuitError
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.scenarios.device_source import device_source
    from afo_mj.scenarios.walk_scenario import ScenarioError
    try:
        spec, origin = device_source(source, overrides)
    except (ScenarioError, CircuitError, ParameterError) as exc:
        raise InvalidInput(str(exc)) from None
    path = Path(origin)
    title = origin if origin == spec.name else f"{path.stem} ({spec.name})"
    return spec.circuit, title


def shipped_circuits(root: Path | None = None) -> dict:
    """Every circuit the package ships, by name: every registered device
    (:func:`afo_mj.devices.registry.device_names`: the presets and the library circuits) and
    the scenarios' own descriptions (:data:`SCENARIO_CIRCUITS`, read from ``root``, the
    source tree)."""
    from afo_mj.devices.registry import device_names, device_spec
    out = {name: device_spec(name).circuit for name in device_names()}
    root = Path(root) if root is not None else Path(__file__).resolve().parents[2]
    for rel in SCENARIO_CIRCUITS:
        circuit, _ = circuit_of(str(root / rel))
        out[f"scenario_{Path(rel).stem}"] = circuit
    return out


def write_circuit_schematic(source: str, out, overrides=()) -> dict:
    """Draw ``source``'s circuit, with ``overrides`` (``--set`` items, as
    :func:`afo_mj.scenarios.device_source.device_source` takes them), into ``out`` (``.svg``,
    or ``.png`` where cairosvg can render it); returns ``{"path", "circuit", "components",
    "nodes"}``."""
    from afo_mj.outputs.schematic import SchematicError, write_schematic
    circuit, title = circuit_of(source, overrides or ())
    out_path = Path(out)
    if out_path.parent and not out_path.parent.exists():
        raise InvalidInput(f"--out = {str(out)!r}: the folder "
                           f"{str(out_path.parent)!r} does not exist")
    try:
        path = write_schematic(circuit, out_path, title=title)
    except SchematicError as exc:
        raise InvalidInput(f"{exc}") from None
    return {"path": path, "circuit": circuit.name, "components": len(circuit.components),
            "nodes": len(circuit.nodes)}
