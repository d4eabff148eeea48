"""``afo-mj schematic``: the circuit of a scenario, a device preset or a library circuit, drawn
as an ISO 1219-1-style schematic (:mod:`afo_mj.outputs.schematic`).

A source is a scenario TOML file (its ``[circuit]`` table, or its ``[device]`` preset with
``params`` overrides), a device preset name (:data:`afo_mj.devices.hafo.PRESETS`,
:data:`afo_mj.devices.valve_afo.VALVE_PRESETS`) or a library circuit name
(:data:`afo_mj.circuits.library.LIBRARY`). :func:`shipped_circuits` lists every circuit the
package ships (``tools/circuit_schematics.py`` draws them into ``docs/schematics``).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from afo_mj.app.errors import InvalidInput

__all__ = ["circuit_of", "shipped_circuits", "write_circuit_schematic", "SCENARIO_CIRCUITS"]

#: scenario files whose own ``[circuit]`` description (not a library name) is shipped
SCENARIO_CIRCUITS = ("scenarios/calibration/lab_rig.toml",)


def _preset_circuit(name: str):
    from afo_mj.devices.hafo import PRESETS, hafo_circuit
    from afo_mj.devices.valve_afo import VALVE_PRESETS, valve_circuit
    if name in PRESETS:
        return hafo_circuit(PRESETS[name], name=name)
    return valve_circuit(VALVE_PRESETS[name])


def _names() -> dict:
    from afo_mj.circuits.library import LIBRARY
    from afo_mj.devices.hafo import PRESETS
    from afo_mj.devices.valve_afo import VALVE_PRESETS
    return {"preset": list(PRESETS) + list(VALVE_PRESETS), "library": list(LIBRARY)}


def circuit_of(source: str):
    """``(circuit, title)`` of ``source`` (see the module docstring); :class:`InvalidInput`
    naming the problem otherwise."""
    from afo_mj.circuits.components import CircuitError
    from afo_mj.circuits.library import LIBRARY
    from afo_mj.hydraulics.params import ParameterError
    from afo_mj.scenarios.walk_scenario import ScenarioError
    names = _names()
    src = str(source)
    path = Path(src)
    if src in LIBRARY and not path.is_file():
        return LIBRARY[src](), src
    if src in names["preset"] and not path.is_file():
        return _preset_circuit(src), src
    if path.suffix.lower() != ".toml" or not path.is_file():
        raise InvalidInput(f"{src!r} is not a scenario file, a device preset or a "
                           "library circuit; allowed: a .toml scenario with [circuit] or "
                           f"[device], a preset ({', '.join(names['preset'])}) or a library "
                           f"circuit ({', '.join(names['library'])})")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise InvalidInput(f"{src}: cannot read the scenario ({exc})") from None
    try:
        if doc.get("circuit"):
            from afo_mj.circuits.circuit import Circuit
            from afo_mj.scenarios.circuit_scenario import circuit_spec
            spec = circuit_spec(doc["circuit"], src)
            try:
                return Circuit.from_dict(spec), f"{path.stem} ({spec.get('name', 'circuit')})"
            except (CircuitError, ParameterError) as exc:
                raise InvalidInput(f"{src}: [circuit]: {exc}") from None
        dev = doc.get("device")
        if isinstance(dev, dict):
            from afo_mj.devices.hafo import PRESETS, hafo_circuit
            from afo_mj.devices.valve_afo import VALVE_PRESETS, valve_circuit
            from afo_mj.scenarios.device_scenario import device_params
            preset, params, _ = device_params(dev, src)
            if preset in PRESETS:
                circuit = hafo_circuit(params, name=preset)
            elif preset in VALVE_PRESETS:
                circuit = valve_circuit(params)
            else:
                raise InvalidInput(f"{src}: device.preset = {preset!r} has no "
                                   "hydraulic circuit (it delivers its command ideally); "
                                   f"allowed: {', '.join(names['preset'])}, or a [circuit]")
            return circuit, f"{path.stem} ({preset})"
    except (ScenarioError, CircuitError, ParameterError) as exc:
        raise InvalidInput(f"{exc}") from None
    raise InvalidInput(f"{src}: the scenario has neither a [circuit] table nor a "
                       "[device] table; allowed: a scenario that wears a circuit")


def shipped_circuits(root: Path | None = None) -> dict:
    """Every circuit the package ships, by name: the device presets, the library circuits
    and the scenarios' own descriptions (:data:`SCENARIO_CIRCUITS`, read from ``root``, the
    source tree)."""
    from afo_mj.circuits.library import LIBRARY
    out = {name: _preset_circuit(name) for name in _names()["preset"]}
    out.update({name: fn() for name, fn in LIBRARY.items()})
    root = Path(root) if root is not None else Path(__file__).resolve().parents[2]
    for rel in SCENARIO_CIRCUITS:
        circuit, _ = circuit_of(str(root / rel))
        out[f"scenario_{Path(rel).stem}"] = circuit
    return out


def write_circuit_schematic(source: str, out) -> dict:
    """Draw ``source``'s circuit into ``out`` (``.svg``, or ``.png`` where cairosvg can
    render it); returns ``{"path", "circuit", "components", "nodes"}``."""
    from afo_mj.outputs.schematic import SchematicError, write_schematic
    circuit, title = circuit_of(source)
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
