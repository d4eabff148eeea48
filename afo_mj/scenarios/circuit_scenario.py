"""The ``[circuit]`` table of a scenario: a circuit description (issue 18) instead of a
``[device] preset``, for walking and bench scenarios.

Either a whole description, the structure of :meth:`afo_mj.circuits.circuit.Circuit.from_dict`::

    [circuit]
    name = "my_circuit"
    [circuit.components.pump]
    kind = "pump"
    [circuit.components.hose_a]
    kind = "hose"
    params = { length_m = 0.5, bore_m = 3.2e-3 }
    ...
    [circuit.nodes]
    line_a = ["pump.a", "hose_a.a", ...]
    [circuit.controller]
    kind = "pump_torque"
    motor = "motor"
    pump = "pump"
    actuator = "cylinders"

or a shipped description (:data:`afo_mj.circuits.library.LIBRARY`) with overrides merged into
it key by key (a component's ``params`` are merged parameter by parameter)::

    [circuit]
    library = "pump_accumulator"
    [circuit.components.hose_a.params]
    length_m = 2.0
    [circuit.controller.params]
    pressure_gain_rad_s_per_pa = 1e-5

Dotted parameter names may be written nested or quoted (``"motor.resistance_ohm" = 0.5``);
``--set circuit.components.hose_a.params.length_m=2.0`` sets one from the command line.

The description is built and its code generated while the scenario is read, so every error
of the description (an unknown component kind or port, a port left unconnected, a node
without capacitance, a parameter no component uses, two drives on one joint, …) is one
:class:`~afo_mj.scenarios.walk_scenario.ScenarioError` naming it, and ``afo-mj run`` exits 2
before anything is written.
"""

from __future__ import annotations

import copy

from afo_mj.scenarios.schema import Key, ScenarioError, Table, check_table

#: ``[circuit]``: a description (afo_mj.circuits.circuit.Circuit.from_dict), or a library
#: circuit with overrides of it
CIRCUIT = Table("circuit", (
    Key("library", "string", doc="a shipped circuit (afo_mj.circuits.library.LIBRARY) the "
        "other keys override"),
    Key("name", "string"),
    Key("components", "table", doc="name -> {kind, params}"),
    Key("nodes", "table", doc="name -> the component ports it joins"),
    Key("controller", "table", doc="{kind, params}"),
    Key("fluid", "table"),
    Key("thermal", "table"),
    Key("options", "table")))


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _flatten_params(spec: dict) -> dict:
    """Dotted parameter names in every ``components.*.params`` and ``controller.params``
    (a nested TOML table and a quoted dotted key mean the same parameter)."""
    spec = copy.deepcopy(spec)
    comps = spec.get("components")
    if isinstance(comps, dict):
        for c in comps.values():
            if isinstance(c, dict) and isinstance(c.get("params"), dict):
                c["params"] = _flat(c["params"])
    ctrl = spec.get("controller")
    if isinstance(ctrl, dict) and isinstance(ctrl.get("params"), dict):
        ctrl["params"] = _flat(ctrl["params"])
    return spec


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = v
    return out


def circuit_spec(table, origin: str) -> dict:
    """The full description (a ``Circuit.from_dict`` table) of a scenario's ``[circuit]``:
    the table itself, or the library description with the table's overrides merged in."""
    from afo_mj.circuits.library import LIBRARY
    if not isinstance(table, dict) or not table:
        raise ScenarioError(f"{origin}: circuit = {table!r} is not allowed; allowed: a "
                            "[circuit] table (a description, or library = "
                            f"{' | '.join(repr(k) for k in LIBRARY)} with overrides)")
    check_table(table, CIRCUIT, origin)
    over = _flatten_params({k: v for k, v in table.items() if k != "library"})
    if "library" not in table:
        return over
    name = table["library"]
    if name not in LIBRARY:
        raise ScenarioError(f"{origin}: circuit.library = {name!r} is not allowed; allowed: "
                            + " | ".join(repr(k) for k in LIBRARY))
    return _merge(_flatten_params(library_spec(name)), over)


class _SpecOnly:
    """Stands in for ``Circuit`` while a library builder runs: ``from_dict`` hands back the
    description instead of building it."""

    @staticmethod
    def from_dict(spec, where="circuit"):
        return copy.deepcopy(spec)


def library_spec(name: str) -> dict:
    """The description (a ``Circuit.from_dict`` table) behind a shipped circuit of
    :data:`afo_mj.circuits.library.LIBRARY`."""
    from afo_mj.circuits import library
    real = library.Circuit
    library.Circuit = _SpecOnly
    try:
        return library.LIBRARY[name]()
    finally:
        library.Circuit = real


def load_circuit(table, origin: str):
    """``(spec, compiled circuit)`` of a ``[circuit]`` table, built and code-generated;
    raises :class:`ScenarioError` naming the description's problem."""
    from afo_mj.circuits.circuit import Circuit
    from afo_mj.circuits.codegen import build
    from afo_mj.circuits.components import CircuitError
    from afo_mj.hydraulics.params import ParameterError
    spec = circuit_spec(table, origin)
    try:
        cc = build(Circuit.from_dict(spec))
    except (CircuitError, ParameterError) as exc:
        raise ScenarioError(f"{origin}: [circuit]: {exc}") from None
    return spec, cc


def with_controller(circuit, controller):
    """The same components and nodes under another controller (e.g. ``OpenLoop()`` for the
    motor-voltage bench tests)."""
    from afo_mj.circuits.circuit import Circuit
    return Circuit(circuit.name, circuit.components, circuit.nodes, controller,
                   fluid=circuit.fluid, thermal=circuit.thermal, options=circuit.options)
