"""A circuit description: components, the nodes that connect their ports, the controller,
the oil, the heat path and the joint it drives (Python or a ``[circuit]`` TOML table).

Example (the lab ankle bench: one double-acting piston-cable cylinder driven by a pump)::

    circuit = Circuit.from_dict({
        "name": "lab_bench",
        "components": {
            "battery": {"kind": "battery"},
            "motor": {"kind": "motor", "params": {"motor.resistance_ohm": 0.6}},
            "pump": {"kind": "pump"},
            ...
        },
        "nodes": {"bus": ["battery.bus", "motor.bus"], "shaft": ["motor.shaft", "pump.shaft"],
                  ...},
        "controller": {"kind": "open_loop"},
    })

Building checks the description and fails with one :class:`CircuitError` naming the problem:
an unknown component kind or port, a port left unconnected or connected twice, a node that
mixes domains, a parameter no component has, no joint or two joints, a joint driven by two
actuated paths. (A node without capacitance is found when the code is generated.)
"""

from __future__ import annotations

import dataclasses

from afo_mj.circuits.catalogue import COMPONENT_KINDS, CONTROLLER_KINDS
from afo_mj.circuits.components import BUS, HYDRAULIC, JOINT, SHAFT, CircuitError, Component
from afo_mj.circuits.controllers import Controller
from afo_mj.hydraulics.fluid import FLUID_PRESETS, ISO_VG32, FluidParams
from afo_mj.hydraulics.params import ParameterError, Parameters, param, replace_named


@dataclasses.dataclass(frozen=True)
class ThermalParams(Parameters):
    """One lumped thermal mass (oil, pump, manifold) cooled to ambient."""

    heat_capacity_j_k: float = param(240.0, unit="J/K", lo=1.0, hi=1e6,
                                     doc="oil plus the metal it wets")
    thermal_resistance_k_w: float = param(3.0, unit="K/W", lo=0.01, hi=1e3,
                                          doc="to ambient through pack and hoses")
    ambient_temperature_k: float = param(298.15, unit="K", lo=230.0, hi=330.0)


@dataclasses.dataclass(frozen=True)
class CircuitOptions(Parameters):
    """Circuit-wide settings."""

    initial_pressure_pa: float = param(0.0, unit="Pa", lo=0.0, hi=5e7,
                                       doc="gauge pressure of every pressure node at t = 0 "
                                           "(a node on a reservoir starts at its pressure)")
    supply_voltage_v: float = param(24.0, unit="V", lo=0.0, hi=1000.0, lo_open=True,
                                    doc="bus voltage of an ideal bench supply (a bus without "
                                        "a battery)")


class _ControllerOwner:
    """Names the controller's parameters in the packed row (``controller.k_p``)."""

    name = "controller"


class Circuit:
    """A described circuit (see the module docstring). ``nodes`` maps a node name to the
    ``component.port`` references it joins."""

    def __init__(self, name: str, components, nodes: dict, controller: Controller,
                 fluid: FluidParams = ISO_VG32.replace(air_fraction=0.001),
                 thermal: ThermalParams = ThermalParams(),
                 options: CircuitOptions = CircuitOptions()):
        if not isinstance(name, str) or not name:
            raise CircuitError(f"circuit.name = {name!r}; allowed: a non-empty string")
        self.name = name
        self.components = list(components)
        self.fluid = fluid
        self.thermal = thermal
        self.options = options
        self.controller = controller
        self.controller_owner = _ControllerOwner()
        #: build every optional term of its components (a play in a cable transmission, a
        #: check valve's seat leakage) even where the description leaves it at 0, so that a
        #: calibration can switch it on by its packed label without recompiling
        #: (:meth:`with_optional_terms`); off, a term at 0 is not built and the generated
        #: code is that of a circuit without it
        self.optional_terms = False
        by_name: dict = {}
        for c in self.components:
            if not isinstance(c, Component):
                raise CircuitError(f"circuit {name!r}: {c!r} is not a component")
            if c.name in by_name or c.name in ("controller", "fluid", "thermal", "circuit"):
                raise CircuitError(f"component name {c.name!r} is used twice or reserved "
                                   "(controller, fluid, thermal, circuit)")
            by_name[c.name] = c
        self._by_name = by_name
        self.nodes = {}
        self.port_node: dict = {}
        self.node_domain: dict = {}
        for node, refs in dict(nodes).items():
            if not isinstance(node, str) or not node.isidentifier():
                raise CircuitError(f"node name {node!r}: allowed: a Python identifier")
            if isinstance(refs, str) or not refs:
                raise CircuitError(f"nodes.{node} = {refs!r}; allowed: a non-empty list of "
                                   "'component.port'")
            domains = set()
            for ref in refs:
                comp, port = self._parse_ref(ref, f"nodes.{node}")
                if (comp.name, port) in self.port_node:
                    raise CircuitError(f"port {ref!r} is connected twice: nodes "
                                       f"{self.port_node[(comp.name, port)]!r} and {node!r}")
                self.port_node[(comp.name, port)] = node
                domains.add(comp.ports[port])
            if len(domains) > 1:
                raise CircuitError(f"node {node!r} joins ports of different domains "
                                   f"({', '.join(sorted(domains))}): {list(refs)}")
            self.nodes[node] = list(refs)
            self.node_domain[node] = domains.pop()
        for c in self.components:
            for port in c.ports:
                if (c.name, port) not in self.port_node:
                    raise CircuitError(f"port '{c.name}.{port}' ({c.ports[port]}) is not "
                                       "connected to any node")
        joints = [n for n, d in self.node_domain.items() if d == JOINT]
        if len(joints) != 1:
            raise CircuitError(f"circuit {name!r} has {len(joints)} joint nodes "
                               f"({joints}); allowed: exactly one (the joint it drives)")
        self.joint = joints[0]
        actuated = [c.name for c in self.components if getattr(c, "actuated", False)]
        if len(actuated) > 1:
            raise CircuitError(f"two drives on joint {self.joint!r}: {actuated} both take the "
                               "controller's command; allowed: one actuated component")
        for node, dom in self.node_domain.items():
            if dom == BUS:
                sources = [r for r in self.nodes[node] if r.endswith(".bus")
                           and self._by_name[r.split(".")[0]].kind == "battery"]
                if len(sources) > 1:
                    raise CircuitError(f"bus node {node!r} has two batteries: {sources}")
        if not isinstance(controller, Controller):
            raise CircuitError(f"circuit {name!r}: controller must be a Controller")

    def _parse_ref(self, ref, where):
        if not isinstance(ref, str) or ref.count(".") != 1:
            raise CircuitError(f"{where}: {ref!r}; allowed: 'component.port'")
        cname, port = ref.split(".")
        comp = self.component(cname, where)
        if port not in comp.ports:
            raise CircuitError(f"{where}: component {cname!r} ({comp.kind}) has no port "
                               f"{port!r}; allowed: {', '.join(comp.ports)}")
        return comp, port

    def component(self, name: str, where: str = "circuit") -> Component:
        if name not in self._by_name:
            raise CircuitError(f"{where}: unknown component {name!r}; the circuit has "
                               f"{', '.join(self._by_name)}")
        return self._by_name[name]

    def nodes_of_domain(self, domain: str) -> list:
        return [n for n, d in self.node_domain.items() if d == domain]

    def with_optional_terms(self) -> "Circuit":
        """This description with its optional terms built at their described values (0 where
        it has none; :attr:`optional_terms`) and, where a pump feeds a charge circuit (a
        check valve on one of its port nodes) and has no drain there yet, a ``drain``
        component at 0 on each of its port nodes (``<pump>_drain_a``, ``<pump>_drain_b``):
        a calibration's candidate terms, every one of them off. Simulated as it is, this
        circuit gives what the description gives (each added term is an exact 0), but for
        one thing: a pulley drive's backlash term, built, moves its pistons as a mass of
        their own on the cable spring (:class:`~afo_mj.circuits.components.PulleyCylinders`,
        the described ``cylinder.piston_mass_kg``), so at no play the pistons' inertia
        remains (the same statics; a mode of the piston on its cable, far above a bench's
        band)."""
        from afo_mj.circuits.catalogue import COMPONENT_KINDS
        comps = list(self.components)
        nodes = {n: list(refs) for n, refs in self.nodes.items()}
        drain_t = COMPONENT_KINDS["drain"]
        names = {c.name for c in comps}
        for pump in [c for c in comps if c.kind == "pump"]:
            for port in ("a", "b"):
                node = self.port_node[(pump.name, port)]
                kinds = {self._by_name[r.split(".")[0]].kind for r in nodes[node]}
                if "check_valve" not in kinds or "drain" in kinds:
                    continue
                name = f"{pump.name}_drain_{port}"
                while name in names:
                    name += "_"
                names.add(name)
                comps.append(drain_t(name, drain_t.params_type(conductance_m3=0.0)))
                nodes[node].append(f"{name}.port")
        out = Circuit(self.name, comps, nodes, self.controller, fluid=self.fluid,
                      thermal=self.thermal, options=self.options)
        out.optional_terms = True
        return out

    # -- description as data ---------------------------------------------------------------
    @classmethod
    def from_dict(cls, spec: dict, where: str = "circuit") -> "Circuit":
        """Build from a ``[circuit]`` table: ``name``, ``components`` (name → ``{kind, params}``
        with ``params`` dotted overrides of the kind's parameter set, or ``preset`` for the
        fluid), ``nodes``, ``controller`` (``{kind, params, ...refs}``), ``fluid`` (a preset
        name or overrides), ``thermal``, ``options``."""
        if not isinstance(spec, dict):
            raise CircuitError(f"{where} must be a table")
        allowed = {"name", "components", "nodes", "controller", "fluid", "thermal", "options"}
        extra = sorted(set(spec) - allowed)
        if extra:
            raise CircuitError(f"{where}.{extra[0]}: unknown key; allowed: "
                               f"{', '.join(sorted(allowed))}")
        comps = []
        for cname, cspec in dict(spec.get("components", {})).items():
            if not isinstance(cspec, dict) or "kind" not in cspec:
                raise CircuitError(f"{where}.components.{cname} needs a kind; allowed kinds: "
                                   f"{', '.join(COMPONENT_KINDS)}")
            kind = cspec["kind"]
            if kind not in COMPONENT_KINDS:
                raise CircuitError(f"{where}.components.{cname}.kind = {kind!r}; allowed: "
                                   f"{', '.join(COMPONENT_KINDS)}")
            bad = sorted(set(cspec) - {"kind", "params"})
            if bad:
                raise CircuitError(f"{where}.components.{cname}.{bad[0]}: unknown key; "
                                   "allowed: kind, params")
            ctype = COMPONENT_KINDS[kind]
            params = _params_from(ctype.params_type(), cspec.get("params", {}),
                                  f"{where}.components.{cname}.params")
            comps.append(ctype(cname, params))
        cspec = dict(spec.get("controller", {"kind": "open_loop"}))
        kind = cspec.pop("kind", "open_loop")
        if kind not in CONTROLLER_KINDS:
            raise CircuitError(f"{where}.controller.kind = {kind!r}; allowed: "
                               f"{', '.join(CONTROLLER_KINDS)}")
        ctype = CONTROLLER_KINDS[kind]
        cparams = _params_from(ctype.params_type(), cspec.pop("params", {}),
                               f"{where}.controller.params")
        controller = ctype(cparams, **cspec)
        fluid = spec.get("fluid", ISO_VG32.replace(air_fraction=0.001))
        if isinstance(fluid, str):
            if fluid not in FLUID_PRESETS:
                raise CircuitError(f"{where}.fluid = {fluid!r}; allowed: "
                                   f"{', '.join(FLUID_PRESETS)} or a table of overrides")
            fluid = FLUID_PRESETS[fluid]
        elif isinstance(fluid, dict):
            fluid = _params_from(ISO_VG32.replace(air_fraction=0.001), fluid, f"{where}.fluid")
        thermal = _params_from(ThermalParams(), spec.get("thermal", {}), f"{where}.thermal")
        options = _params_from(CircuitOptions(), spec.get("options", {}), f"{where}.options")
        return cls(spec.get("name", "circuit"), comps, spec.get("nodes", {}), controller,
                   fluid=fluid, thermal=thermal, options=options)


def _params_from(base, overrides, where):
    """``base`` with dotted ``overrides``; an unknown name or a bad value is a CircuitError
    naming ``where``."""
    if not isinstance(overrides, dict):
        raise CircuitError(f"{where} must be a table of parameter values")
    flat = _flatten(overrides)
    if not flat:
        return base
    try:
        return replace_named(base, flat)
    except (ParameterError, TypeError, ValueError) as exc:
        raise CircuitError(f"{where}: {exc}") from None


def _flatten(d, prefix=""):
    out = {}
    for k, v in d.items():
        if isinstance(v, dict) and not (k == "fluid" and False):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


__all__ = ["Circuit", "CircuitError", "ThermalParams", "CircuitOptions", "HYDRAULIC", "SHAFT",
           "BUS", "JOINT"]
