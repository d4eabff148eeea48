"""Generate a circuit's compiled kernel from its description.

:func:`build` walks the components of a :class:`~afo_mj.circuits.circuit.Circuit`; each writes
its equations through an :class:`Emitter`. The emitter numbers the states (a pressure per
hydraulic node that is not held by a reservoir, a speed per shaft, then the components' own
states), the packed parameters and the named losses, stores and probes, and assembles
straight-line Python for ``rhs`` (node continuity ``C(p) ṗ = ΣQ`` with
``C = ΣV/B(p) + ΣV_w/K_w + ΣC_acc``, shaft ``J ω̇ = ΣT``; ``rhs_step`` is the same with the
mean of ``1/B`` over the stepper's step in place of ``1/B(p)``), the controller, and the begin/close
hooks (oil viscosity and density, battery, heat). The source of the one stepper
(:mod:`afo_mj.circuits.stepper`) is appended, and the module is written to the cache directory
under the hash of its text and imported; numba caches its machine code beside it, so a new
process with the same topology does not recompile. Parameter values live in the packed row,
never in the code: a parameter sweep reuses one compiled module.

Cache directory: ``$AFO_MJ_CACHE_DIR`` or ``~/.cache/afo_mj``, subfolder ``circuits``.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import inspect
import os
import sys
import threading
from collections import defaultdict
from pathlib import Path

import numpy as np

from afo_mj.circuits import stepper
from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.jacobian_columns import column_function
from afo_mj.circuits.components import BUS, HYDRAULIC, JOINT, SHAFT, CircuitError, gated
from afo_mj.hydraulics import laws
from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA, Fluid

#: entries of the held input vector ``U``: actuated command, bus voltage, viscosity, density,
#: temperature, and ``1/h`` of the (sub-)step being solved (set by the stepper before each
#: solve: a component's difference quotient over the step, e.g. the cable stretch of
#: :class:`~afo_mj.circuits.components.PulleyCylinders`). The named actuated inputs follow,
#: then the held values (:meth:`Emitter.held`).
U_NAMES = ("CMD", "VBUS", "MU", "RHO", "TEMP", "INV_H")
#: header of the work vector ``W`` (per side); the arrays that follow are sized per circuit
W_HEADER = ("CMD", "THETA", "THETA_DOT", "TAU0", "G", "TAU", "TAU_END", "TAU_MEAS", "P_MECH",
            "COUPLE_SQ", "NEWTON_ITERS", "NEWTON_FAIL", "SUBSTEPPED", "SUBSTEPS",
            "CLIP_STEPS", "E_MECH", "E_IN", "E_IN_DRAWN", "E_ABS_FLOW", "HEAT_TO_OIL",
            "TEMP_K", "SOC", "I_BAT", "P_MAX", "E_FLOOR", "E_OVERLOAD", "OVERLOAD_STEPS")
F_HEADER = ("TAU", "PBUS", "HEAT")
TYP = {"pressure": 1e5, "speed": 10.0, "current": 1.0}


@functools.lru_cache(maxsize=1)
def _dependency_digest() -> str:
    """Hash of the compiled modules a generated circuit calls into (the laws, the phase
    estimator and profile lookup, the impedance law, the buffer views). numba's on-disk cache of a
    module does not notice a change in a function it calls from another file, so the generated text
    carries this hash: a changed law gives a new module text, a new cache entry, a fresh
    compile."""
    from afo_mj.circuits import buffer_views
    from afo_mj.control import assistance, impedance
    h = hashlib.sha256()
    for mod in (laws, assistance, impedance, buffer_views):
        h.update(Path(mod.__file__).read_bytes())
    return h.hexdigest()[:20]


#: How every function of a generated module is compiled: cached on disk, and with numpy's
#: floating-point error model (a division by zero gives inf/nan, which the stepper's
#: finiteness checks report, instead of a zero test before every division: 0.8 µs of the
#: HAFO's ~8 µs per coupled gait step, measured by replaying a recorded gait).
JIT_DECORATOR = '@numba.njit(cache=True, error_model="numpy")'
#: the decorator of every generated function that allocates nothing and returns no array: the
#: same, compiled without numba's reference counting (``_nrt=False``). Their arrays are views
#: of buffers their caller holds, so the counts guard nothing, and each view made or passed
#: cost an out-of-line atomic increment and decrement: measured on the HAFO's coupled gait
#: step (replayed from numba, 2 cores), 3.9 µs/step with counting, 2.4 µs without.
HOT_DECORATOR = JIT_DECORATOR[:-1] + ", _nrt=False)"


def cache_dir() -> Path:
    base = os.environ.get("AFO_MJ_CACHE_DIR") or os.path.join(Path.home(), ".cache", "afo_mj")
    return Path(base) / "circuits"


class _Recorder:
    """A read-recording view of a parameter dataclass: every leaf field read through it is
    added to ``used`` by its dotted path."""

    def __init__(self, obj, used: set, prefix: str = ""):
        object.__setattr__(self, "_obj", obj)
        object.__setattr__(self, "_used", used)
        object.__setattr__(self, "_prefix", prefix)

    def __getattr__(self, name):
        prop = inspect.getattr_static(type(self._obj), name, None)
        if isinstance(prop, property):
            # a derived figure (CylinderParams.area_a_m2, ...): evaluated on this view, so
            # the fields it reads are recorded as used
            return prop.fget(self)
        value = getattr(self._obj, name)
        path = self._prefix + name
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            return _Recorder(value, self._used, path + ".")
        if name in {f.name for f in dataclasses.fields(self._obj)}:
            self._used.add(path)
        return value


def _unwrap(v):
    return object.__getattribute__(v, "_obj") if isinstance(v, _Recorder) else v


def leaf_fields(obj, prefix: str = "") -> list:
    """Dotted names of every leaf field of a parameter dataclass (nested sets expanded)."""
    out = []
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            out += leaf_fields(v, prefix + f.name + ".")
        else:
            out.append(prefix + f.name)
    return out


class Emitter:
    """Collects one circuit's equations (see the module docstring); components call it."""

    def __init__(self, circuit: Circuit):
        self.c = circuit
        self.P: list = []
        self.P_labels: list = []
        self.p_index: dict = {}
        self.states: list = []          # dicts: label, typ, kind, store
        self.derivs: dict = {}
        self.lines: list = []
        self.flows = defaultdict(list)
        self.vols = defaultdict(list)
        self.walls = defaultdict(list)
        self.caps = defaultdict(list)
        self.couplings: list = []       # (node a, node b, differential capacitance expr)
        self.torques = defaultdict(list)
        self.inertias = defaultdict(list)
        self.joint_terms: list = []
        self.bus_terms = defaultdict(list)
        self.losses: list = []          # (label, expr or None, oil)
        self.srates: list = []          # (label, expr)
        self.probes: list = []
        self.monitors: list = []        # (label, expr, in_close)
        self.begin_lines: list = []
        self.close_lines: list = []
        self.ctrl_lines: list = []
        self.ctrl_slots: list = []
        self.work_init: dict = {}
        self.inputs: list = []          # named actuated inputs after U_NAMES (controller-set)
        self.inputs_driven: set = set()
        self.held_values: list = []     # (label, expr): values held from the last step's end
        self.fixed: dict = {}
        self.sources: dict = {}
        self._current = None
        # node states first: every hydraulic node not held by a reservoir, every shaft
        fixed_nodes = {circuit.port_node[(c.name, "port")] for c in circuit.components
                       if c.kind == "reservoir"}
        self.node_ref = {}
        for node, dom in circuit.node_domain.items():
            if dom == HYDRAULIC and node not in fixed_nodes:
                self.node_ref[node] = self._new_state(node, "pressure", TYP["pressure"])
            elif dom == HYDRAULIC:
                self.node_ref[node] = f"fix_{node}"
            elif dom == SHAFT:
                self.node_ref[node] = self._new_state(node, "speed", TYP["speed"])

    # -- numbering ---------------------------------------------------------------------------
    def _new_state(self, label, kind, typ, store=None):
        self.states.append({"label": label, "kind": kind, "typ": typ, "store": store})
        return f"y[{len(self.states) - 1}]"

    def param(self, comp, key: str, value) -> str:
        value = float(_unwrap(value))
        label = f"{comp.name}.{key}"
        if label in self.p_index:
            raise CircuitError(f"parameter {label} packed twice")
        self.p_index[label] = len(self.P)
        self.P.append(value)
        self.P_labels.append(label)
        return f"P[{len(self.P) - 1}]"

    def optional(self, value) -> bool:
        """Whether an optional term whose parameter is ``value`` is built: when the value is
        not 0, or when the circuit builds every optional term
        (:attr:`~afo_mj.circuits.circuit.Circuit.optional_terms`). A term not built leaves
        the generated code as it is without it."""
        return float(_unwrap(value)) != 0.0 or bool(getattr(self.c, "optional_terms", False))

    def param_ref(self, comp, key: str) -> str:
        label = f"{comp.name}.{key}"
        if label not in self.p_index:
            raise CircuitError(f"{label} is not a packed parameter (emit order)")
        return f"P[{self.p_index[label]}]"

    def param_table(self, comp, key: str, values) -> str:
        vals = [float(v) for v in _unwrap(values)]
        start = len(self.P)
        for k, v in enumerate(vals):
            self.P.append(v)
            self.P_labels.append(f"{comp.name}.{key}[{k}]")
        self.p_index[f"{comp.name}.{key}"] = start
        return f"P[{start}:{start + len(vals)}]"

    def state(self, comp, key, typ, store=None) -> str:
        return self._new_state(f"{comp.name}.{key}", "own", typ, store)

    def local(self, comp, key) -> str:
        return f"{comp.name}_{key}"

    # -- topology ---------------------------------------------------------------------------
    def _node(self, comp, port, domain):
        if comp.ports.get(port) != domain:
            raise CircuitError(f"{comp.name}.{port} is not a {domain} port")
        return self.c.port_node[(comp.name, port)]

    def p(self, comp, port) -> str:
        return self.node_ref[self._node(comp, port, HYDRAULIC)]

    def speed(self, comp, port) -> str:
        return self.node_ref[self._node(comp, port, SHAFT)]

    def fix_pressure(self, comp, port, pref):
        node = self._node(comp, port, HYDRAULIC)
        if node in self.fixed:
            raise CircuitError(f"node {node!r} is held by two reservoirs")
        self.fixed[node] = pref

    def flow(self, comp, port, expr):
        self.flows[self._node(comp, port, HYDRAULIC)].append(expr)

    def volume(self, comp, port, expr, wall_volume=None, wall_inv=None):
        node = self._node(comp, port, HYDRAULIC)
        self.vols[node].append(expr)
        if wall_volume is not None:
            self.walls[node].append((wall_volume, wall_inv))

    def capacitance(self, comp, port, expr):
        self.caps[self._node(comp, port, HYDRAULIC)].append(expr)

    def couple(self, comp, port_a, port_b, expr):
        """Join the nodes at ``port_a`` and ``port_b`` by the differential capacitance
        ``expr`` (m³/Pa; a series spring between two chambers): their continuity equations
        are solved together (:func:`~afo_mj.hydraulics.laws.coupled_node_rate_pa_s`)."""
        na = self._node(comp, port_a, HYDRAULIC)
        nb = self._node(comp, port_b, HYDRAULIC)
        for node in (na, nb):
            if not self.node_ref[node].startswith("y[") or any(
                    node in pair[:2] for pair in self.couplings):
                raise CircuitError(f"{comp.name}: node {node!r} cannot be coupled (allowed: a "
                                   "pressure-state node in at most one coupled pair)")
        self.couplings.append((na, nb, expr))

    def torque(self, comp, port, expr):
        self.torques[self._node(comp, port, SHAFT)].append(expr)

    def inertia(self, comp, port, expr):
        self.inertias[self._node(comp, port, SHAFT)].append(expr)

    def joint_torque(self, comp, expr):
        self._node(comp, "joint", JOINT)
        self.joint_terms.append(expr)

    def bus_power(self, comp, port, expr):
        self.bus_terms[self._node(comp, port, BUS)].append(expr)

    def source_bus(self, comp, port):
        self.sources[self._node(comp, port, BUS)] = comp.name

    def line(self, code):
        self.lines.append(code)

    def deriv(self, yref, expr):
        self.derivs[int(yref[2:-1])] = expr

    def loss(self, comp, key, expr, oil=True):
        self.losses.append((f"{comp.name}.{key}", expr, oil))

    def loss_slot(self, comp, key) -> str:
        self.losses.append((f"{comp.name}.{key}", None, False))
        return f"W[W_E_LOSS + {len(self.losses) - 1}]"

    def store_rate(self, comp, key, expr):
        self.srates.append((f"{comp.name}.{key}", expr))

    def probe(self, comp, key, expr):
        self.probes.append((f"{comp.name}.{key}", expr))

    def monitor(self, comp, key, expr, close=False):
        self.monitors.append((f"{comp.name}.{key}", expr, close))

    def begin_line(self, code):
        self.begin_lines.append(code)

    def close_line(self, code):
        self.close_lines.append(code)

    def ctrl_line(self, code):
        self.ctrl_lines.append(code)

    def ctrl_slot(self, key) -> str:
        self.ctrl_slots.append(key)
        return f"W[W_CTRL + {len(self.ctrl_slots) - 1}]"

    def initial_work(self, key, value):
        self.work_init[key] = float(value)

    # -- named actuated inputs (valve commands, coil switching rates) -----------------------
    def input(self, comp, key) -> str:
        """Declare the actuated input ``comp.key`` (held over each step, written by the
        controller through :meth:`input_slot`); returns its reference in ``rhs``."""
        label = f"{comp.name}.{key}"
        if label not in self.inputs:
            self.inputs.append(label)
        return f"U[{len(U_NAMES) + self.inputs.index(label)}]"

    def held(self, comp, key, expr) -> str:
        """A value held from the end of the last accepted (sub-)step: ``expr`` is evaluated
        with the right-hand side and stored when a step is accepted (``close_extra``); the
        next step reads it as the returned reference (an entry of ``U`` after the actuated
        inputs, 0 at the start). With ``U[U_INV_H]`` it makes a backward-Euler difference
        quotient ``(expr(y) − expr_n)/h`` of a quantity that depends on the joint motion as
        well as on the states."""
        label = f"{comp.name}.{key}"
        if any(lab == label for lab, _ in self.held_values):
            raise CircuitError(f"held value {label} declared twice")
        self.held_values.append((label, expr))
        return f"U[U_HELD_{len(self.held_values) - 1}]"

    def input_slot(self, comp, key) -> str:
        """The work-vector entry through which the controller sets input ``comp.key``."""
        label = f"{comp.name}.{key}"
        if label not in self.inputs:
            raise CircuitError(f"controller drives {label!r}, which no component reads; "
                               f"allowed: {', '.join(self.inputs) or 'none'}")
        self.inputs_driven.add(label)
        return f"W[W_U + {len(U_NAMES) + self.inputs.index(label)}]"


@dataclasses.dataclass
class CompiledCircuit:
    """A circuit's generated kernel: the compiled ``module``, the packed parameter row ``P``
    and the names of everything numbered (states, losses, stores, probes, monitors), with the
    work-vector layout and the initial state."""

    circuit: Circuit
    module: object
    source_path: Path
    P: np.ndarray
    param_labels: tuple
    state_names: tuple
    state_kinds: tuple
    loss_names: tuple
    store_names: tuple
    srate_names: tuple
    probe_names: tuple
    monitor_names: tuple
    y0: np.ndarray
    w_init: dict
    n_w: int
    n_scratch: int
    s_width: int
    #: named actuated inputs after ``U_NAMES`` (``W[W_U + len(U_NAMES) + k]``)
    input_names: tuple = ()
    #: the controller's own slots (``W[W_CTRL + k]``: integrators, clocks, logged values)
    ctrl_names: tuple = ()
    #: whether each state keeps energy (a capacitance, inductance or inertia)
    state_stores: tuple = ()

    def index(self, state_label: str) -> int:
        return self.state_names.index(state_label)


def _expr_sum(terms, empty="0.0"):
    return " + ".join(f"({t})" for t in terms) if terms else empty


def _emit_fluid_thermal(g: "Emitter", circuit: Circuit) -> tuple:
    """Pack the oil's and the thermal node's parameters (every fluid field must reach one);
    returns their references ``(B_l, air, n, p_atm, floor, walther_b, walther_c, rho0, beta,
    T_ref, heat capacity, thermal resistance, ambient)``."""
    fl = Fluid(circuit.fluid)
    fu = circuit.fluid
    used_fluid: set = set()
    rf = _Recorder(fu, used_fluid)
    own = type("FluidOwner", (), {"name": "fluid"})()
    b_l = g.param(own, "liquid_bulk_modulus", rf.liquid_bulk_modulus_pa)
    # gated: both fields are read, so switching the air off is not an unused parameter
    air = g.param(own, "air_fraction", gated(rf.entrained_air_enabled, rf.air_fraction))
    npoly = g.param(own, "polytropic_index", rf.polytropic_index)
    p_atm = g.param(own, "atmospheric_pressure", ATMOSPHERIC_PRESSURE_PA)
    floor = g.param(own, "pressure_floor", rf.pressure_floor_pa)
    g.param(own, "cavitation_band", rf.cavitation_band_pa)
    wb = g.param(own, "walther_b", fl.walther_b)
    wc = g.param(own, "walther_c", fl.walther_c)
    # Walther's constants come from the two datasheet viscosity points
    for f in ("viscosity_low_m2_s", "viscosity_low_temperature_k", "viscosity_high_m2_s",
              "viscosity_high_temperature_k"):
        getattr(rf, f)
    rho0 = g.param(own, "density", rf.density_kg_m3)
    beta = g.param(own, "expansion", rf.thermal_expansion_per_k)
    tref = g.param(own, "reference_temperature", rf.reference_temperature_k)
    unused_fluid = [f for f in leaf_fields(fu) if f not in used_fluid
                    and f not in ("name", "specific_heat_j_kg_k")]
    if unused_fluid:
        raise CircuitError(f"fluid.{unused_fluid[0]} reaches no equation of the circuit")
    th = circuit.thermal
    towner = type("ThermalOwner", (), {"name": "thermal"})()
    tc = g.param(towner, "heat_capacity", th.heat_capacity_j_k)
    tr = g.param(towner, "resistance", th.thermal_resistance_k_w)
    ta = g.param(towner, "ambient", th.ambient_temperature_k)
    return b_l, air, npoly, p_atm, floor, wb, wc, rho0, beta, tref, tc, tr, ta


def packed_values(circuit: Circuit, parts) -> dict[str, float]:
    """The packed parameter values (label → value) that the ``parts`` of ``circuit`` write:
    component names, ``"fluid"`` and ``"thermal"`` (the oil's and the thermal node's rows).
    Each part is emitted exactly as :func:`generate` emits it, but alone, and no code is
    assembled: what a fit that moves a described value (a bore, a seal's friction scale)
    needs to know of the row without generating or compiling the circuit again."""
    parts = set(parts)
    known = {c.name for c in circuit.components} | {"fluid", "thermal"}
    unknown = parts - known
    if unknown:
        raise CircuitError(f"packed_values: parts {sorted(unknown)}; allowed: "
                           f"{', '.join(sorted(known))}")
    g = Emitter(circuit)
    out: dict[str, float] = {}
    if parts & {"fluid", "thermal"}:
        _emit_fluid_thermal(g, circuit)
        out.update({lab: v for lab, v in zip(g.P_labels, g.P)
                    if lab.split(".", 1)[0] in parts})
    for comp in circuit.components:
        if comp.name in parts:
            g1 = Emitter(circuit)
            comp.emit(g1, _Recorder(comp.params, set()))
            out.update(zip(g1.P_labels, g1.P))
    return out


def generate(circuit: Circuit):
    """Emit every component and assemble the module text. Returns ``(source, emitter)``."""
    g = Emitter(circuit)
    b_l, air, npoly, p_atm, floor, wb, wc, rho0, beta, tref, tc, tr, ta = \
        _emit_fluid_thermal(g, circuit)
    g.initial_work("TEMP_K", circuit.thermal.ambient_temperature_k)

    for comp in circuit.components:
        used: set = set()
        comp.emit(g, _Recorder(comp.params, used))
        missing = [f for f in leaf_fields(comp.params)
                   if f not in used and f not in comp.metadata_fields]
        if missing:
            raise CircuitError(f"parameter {comp.name}.{missing[0]} ({comp.kind}) reaches no "
                               "equation of the circuit; allowed: parameters the kernel "
                               "simulates")
    used_c: set = set()
    circuit.controller.emit(g, _Recorder(circuit.controller.params, used_c), circuit)
    missing = [f for f in leaf_fields(circuit.controller.params) if f not in used_c]
    if missing:
        raise CircuitError(f"controller.{missing[0]} reaches no equation")
    undriven = [k for k in g.inputs if k not in g.inputs_driven]
    if undriven:
        raise CircuitError(f"input {undriven[0]!r} is driven by no controller; controller "
                           f"{circuit.controller.kind!r} drives "
                           f"{', '.join(sorted(g.inputs_driven)) or 'none'}")

    n_y = len(g.states)
    if n_y == 0:
        raise CircuitError(f"circuit {circuit.name!r} has no states")
    body = []
    for node, pref in g.fixed.items():
        body.append(f"fix_{node} = {pref}")
    body.append(f"P_ATM = {p_atm}")
    body += g.lines
    # node continuity and shafts
    cap_expr = {}
    for node, ref in g.node_ref.items():
        if not ref.startswith("y["):
            continue
        k = int(ref[2:-1])
        dom = circuit.node_domain[node]
        if dom == HYDRAULIC:
            if not g.vols[node] and not g.caps[node] and not g.walls[node]:
                raise CircuitError(f"node {node!r} has no capacitance: no component adds oil "
                                   "volume or compliance to it (add a volume, hose or "
                                   "accumulator)")
            # oil compliance: the mean of 1/B over the step y_old → y (``yo``), so that a
            # backward-Euler step conserves the node's oil (the tangent 1/B(y) when yo = y)
            b = f"K_{node}"
            body.append(f"{b} = oil_mean_compliance_per_pa(yo[{k}] + P_ATM, {ref} + P_ATM, "
                        f"{b_l}, {air}, {npoly}, P_ATM, {floor})")
            wall = " + ".join(f"({v}) * ({i})" for v, i in g.walls[node]) or "0.0"
            cexpr = f"({_expr_sum(g.vols[node])}) * {b} + {wall}"
            if g.caps[node]:
                cexpr += " + " + _expr_sum(g.caps[node])
            body.append(f"C_{node} = {cexpr}")
            body.append(f"QN_{node} = {_expr_sum(g.flows[node])}")
            if not any(node in pair[:2] for pair in g.couplings):
                body.append(f"dy[{k}] = QN_{node} / C_{node}")
            cap_expr[k] = f"C_{node}"
        else:
            if not g.inertias[node]:
                raise CircuitError(f"shaft node {node!r} has no inertia")
            body.append(f"J_{node} = {_expr_sum(g.inertias[node])}")
            body.append(f"dy[{k}] = ({_expr_sum(g.torques[node])}) / J_{node}")
            cap_expr[k] = f"J_{node}"
    for na, nb, cs in g.couplings:
        for me, other in ((na, nb), (nb, na)):
            body.append(f"d{g.node_ref[me]} = coupled_node_rate_pa_s(QN_{me}, QN_{other}, "
                        f"C_{me}, C_{other}, {cs})")
    for k, st in enumerate(g.states):
        if st["kind"] == "own":
            if k not in g.derivs:
                raise CircuitError(f"state {st['label']} has no derivative")
            body.append(f"dy[{k}] = {g.derivs[k]}")
            cap_expr[k] = st["store"] if st["store"] is not None else "0.0"
    n_loss, n_srate = len(g.losses), len(g.srates) + len(g.fixed)
    f_loss = len(F_HEADER)
    f_srate = f_loss + n_loss
    f_cap = f_srate + n_srate
    f_probe = f_cap + n_y
    f_mon = f_probe + len(g.probes)
    f_held = f_mon + len(g.monitors)
    n_f = f_held + len(g.held_values)
    body.append(f"F[F_TAU] = {_expr_sum(g.joint_terms)}")
    bus_all = [t for terms in g.bus_terms.values() for t in terms]
    body.append(f"F[F_PBUS] = {_expr_sum(bus_all)}")
    oil = []
    for i, (label, expr, is_oil) in enumerate(g.losses):
        body.append(f"F[{f_loss + i}] = {expr if expr is not None else '0.0'}")
        if is_oil and expr is not None:
            oil.append(f"F[{f_loss + i}]")
    body.append(f"F[F_HEAT] = {_expr_sum(oil)}")
    srate_names = []
    for j, (label, expr) in enumerate(g.srates):
        body.append(f"F[{f_srate + j}] = {expr}")
        srate_names.append(label)
    for j, node in enumerate(g.fixed):
        body.append(f"F[{f_srate + len(g.srates) + j}] = fix_{node} * "
                    f"({_expr_sum(g.flows[node])})")
        srate_names.append(f"reservoir.{node}")
    for k in range(n_y):
        body.append(f"F[{f_cap + k}] = {cap_expr[k]}")
    for i, (label, expr) in enumerate(g.probes):
        body.append(f"F[{f_probe + i}] = {expr}")
    for i, (label, expr, in_close) in enumerate(g.monitors):
        body.append(f"F[{f_mon + i}] = {expr if not in_close else '0.0'}")
    for i, (label, expr) in enumerate(g.held_values):
        body.append(f"F[{f_held + i}] = {expr}")

    # work vector layout
    w_names = list(W_HEADER)
    w_names += [f"U + {k}" for k in range(0)]
    consts = {f"W_{n}": i for i, n in enumerate(W_HEADER)}
    off = len(W_HEADER)
    consts["W_U"] = off
    off += len(U_NAMES) + len(g.inputs) + len(g.held_values)
    consts["W_CTRL"] = off
    off += max(len(g.ctrl_slots), 1)
    consts["W_A"] = off
    off += n_y
    consts["W_B"] = off
    off += n_y
    consts["W_E_LOSS"] = off
    off += max(n_loss, 1)
    consts["W_E_SRATE"] = off
    off += max(n_srate, 1)
    consts["W_E_STORE"] = off
    off += n_y
    consts["W_MON"] = off
    off += max(len(g.monitors), 1)
    consts["W_Y_MAX"] = off          # peak of every state over the run
    off += n_y
    consts["W_PROBE_INT"] = off      # time integral of every probe (right-point rule)
    off += max(len(g.probes), 1)
    n_w = off
    n_u = len(U_NAMES) + len(g.inputs) + len(g.held_values)
    s_width = max(n_y + 1, n_f, n_u, 2)
    n_scratch = stepper.scratch_rows(n_y)

    # begin / close / controller / floor
    begin = [f"W[W_U + U_MU] = dynamic_viscosity_pa_s(W[W_TEMP_K], {wb}, {wc}, {rho0}, "
             f"{beta}, {tref})",
             f"W[W_U + U_RHO] = oil_density_kg_m3(W[W_TEMP_K], {rho0}, {beta}, {tref})",
             "W[W_U + U_TEMP] = W[W_TEMP_K]"]
    bus_nodes = circuit.nodes_of_domain(BUS)
    close = []
    supply = None
    if bus_nodes and not g.sources:
        supply = g.param(type("O", (), {"name": "circuit"})(), "supply_voltage",
                         circuit.options.supply_voltage_v)
        begin.append(f"W[W_U + U_VBUS] = {supply}")
        close += ["W[W_E_IN] += h * F[F_PBUS]",
                  "if F[F_PBUS] > 0.0:\n    W[W_E_IN_DRAWN] += h * F[F_PBUS]",
                  "W[W_E_ABS_FLOW] += h * abs(F[F_PBUS])"]
    begin += g.begin_lines
    close += g.close_lines
    close.append(f"W[W_TEMP_K] += h * lumped_temperature_rate_k_s(W[W_TEMP_K], F[F_HEAT], "
                 f"{ta}, {tr}, {tc})")
    pressure_states = [k for k, s in enumerate(g.states) if s["kind"] == "pressure"]
    for k in pressure_states:
        close.append(f"if y[{k}] > W[W_P_MAX]:\n    W[W_P_MAX] = y[{k}]")
    for i, (label, expr, in_close) in enumerate(g.monitors):
        val = expr if in_close else f"F[{f_mon + i}]"
        close.append(f"W[W_MON + {i}] = max(W[W_MON + {i}], {val})")
    for k in range(n_y):
        close.append(f"if y[{k}] > W[W_Y_MAX + {k}]:\n    W[W_Y_MAX + {k}] = y[{k}]")
    for i in range(len(g.probes)):
        close.append(f"W[W_PROBE_INT + {i}] += h * F[{f_probe + i}]")
    for i in range(len(g.held_values)):
        close.append(f"W[W_U + U_HELD_{i}] = F[{f_held + i}]")
    floor_lines = [f"fl = {floor} - {p_atm}", "clipped = False"]
    for k in pressure_states:
        floor_lines.append(f"if y[{k}] < fl:\n    y[{k}] = fl\n    clipped = True")
    floor_lines.append("return clipped")

    def fn(name, args, lines):
        out = [HOT_DECORATOR, f"def {name}({args}):"]
        for ln in lines or ["pass"]:
            out += ["    " + s for s in ln.split("\n")]
        return "\n".join(out)

    law_names = sorted(laws.LAWS) + ["table_interp"]
    src = [f'"""Generated by afo_mj.circuits.codegen from circuit {circuit.name!r}: do not '
           'edit."""',
           f"# compiled against laws/assistance/impedance/buffer_views {_dependency_digest()}",
           "import math", "import numba", "import numpy as np",
           "from afo_mj.circuits.buffer_views import view2, view3",
           f"from afo_mj.hydraulics.laws import ({', '.join(law_names)})",
           "from afo_mj.control.assistance import N_PH, PH_PHASE, phase_update, table_lookup",
           "from afo_mj.control.impedance import impedance_torque",
           ""]
    src.append(f"N_Y = {n_y}")
    src.append(f"N_F = {n_f}")
    src.append(f"N_U = {n_u}")
    src.append(f"N_LOSS = {n_loss}")
    src.append(f"N_SRATE = {n_srate}")
    src.append(f"N_W = {n_w}")
    src.append(f"N_P = {len(g.P)}")
    src.append(f"N_SCRATCH = {n_scratch}")
    src.append(f"S_WIDTH = {s_width}")
    src.append(f"N_PROBE = {len(g.probes)}")
    src.append(f"N_INPUT = {len(g.inputs)}")
    src.append(f"N_U_HEAD = {len(U_NAMES)}")
    src.append(f"N_CTRL = {len(g.ctrl_slots)}")
    src.append(f"N_HELD = {len(g.held_values)}")
    for name in stepper.LAYOUT_CONSTANTS:
        src.append(f"{name} = {getattr(stepper, name)!r}")
    for i, n in enumerate(U_NAMES):
        src.append(f"U_{n} = {i}")
    for i in range(len(g.held_values)):
        src.append(f"U_HELD_{i} = {len(U_NAMES) + len(g.inputs) + i}")
    for i, n in enumerate(F_HEADER):
        src.append(f"F_{n} = {i}")
    src += [f"F_LOSS = {f_loss}", f"F_SRATE = {f_srate}", f"F_CAP = {f_cap}",
            f"F_PROBE = {f_probe}", f"F_MON = {f_mon}"]
    for k, v in consts.items():
        src.append(f"{k} = {v}")
    src.append(f"NEWTON_TOL = {stepper.NEWTON_TOL!r}")
    src.append(f"NEWTON_TOL_STEP_S = {stepper.NEWTON_TOL_STEP_S!r}")
    src.append(f"MIN_SUBSTEP_FRACTION = {stepper.MIN_SUBSTEP_FRACTION!r}")
    for name in ("JAC_MAX_AGE", "JAC_INPUT_REL", "JAC_COUPLE_REL", "NEWTON_CONTRACT",
                 "BROYDEN_MAX"):
        src.append(f"{name} = {getattr(stepper, name)!r}")
    src.append("Y_TYP = np.array([" + ", ".join(repr(float(s["typ"])) for s in g.states)
               + "])")
    src.append("")
    src.append(fn("rhs_step", "y, yo, th, thd, U, P, dy, F", body))
    src.append("")
    src.append(fn("rhs", "y, th, thd, U, P, dy, F", ["rhs_step(y, y, th, thd, U, P, dy, F)"]))
    src.append("")
    src.append(column_function(body, n_y, HOT_DECORATOR))
    src.append("")
    src.append(fn("controller", "y, th, thd, cmd, h, P, W",
                  ["U = W[W_U:W_U + N_U]"]
                  + [f"fix_{node} = {pref}" for node, pref in g.fixed.items()]
                  + g.ctrl_lines))
    src.append("")
    src.append(fn("begin_extra", "y, P, W", begin))
    src.append("")
    src.append(fn("close_extra", "y, h, thd, P, W, F", close))
    src.append("")
    src.append(fn("clip_floor", "y, P", floor_lines))
    for f in stepper.TEMPLATE:
        deco = (JIT_DECORATOR[:-1] + ', inline="always")' if f in stepper.INLINE
                else HOT_DECORATOR)
        src += ["", "", deco, inspect.getsource(f).rstrip()]
    text = "\n".join(src) + "\n"
    layout = dict(n_w=n_w, n_scratch=n_scratch, s_width=s_width, srate_names=srate_names,
                  f_probe=f_probe)
    return text, g, layout


#: a generated circuit's first compilation (numba, all its functions; loaded machine: 2 cores)
FIRST_COMPILE_S = "~15 s"


def _announce(name: str, d: Path, digest: str) -> None:
    """Say (:mod:`afo_mj.progress`) whether circuit ``name`` will be compiled for the first
    time (no numba cache beside its module; the compilation itself happens at the kernel's
    first call, e.g. in the first simulated step) or loaded from the cache. Once per process
    and module."""
    from afo_mj import progress
    rep = progress.reporter()
    if not rep.active:
        return
    cache = Path(os.environ["NUMBA_CACHE_DIR"]) if os.environ.get("NUMBA_CACHE_DIR") else None
    if cache is None:
        cached = any((d / "__pycache__").glob(f"circuit_{digest}.*.nbi"))
    else:
        cached = any(cache.rglob(f"circuit_{digest}.*.nbi"))
    if cached:
        rep.stage(f"circuit {name!r}: compiled kernel loaded from the cache ({d})")
    else:
        rep.stage(f"circuit {name!r}: compiling its kernel (first run only, {FIRST_COMPILE_S}, "
                  f"at its first step; cached in {d})…")


def write_once(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` unless it exists, safely against concurrent writers.

    Several processes may build the same circuit at once (test workers, sweep workers): each
    writes its own temporary file, and the first one to link it in place wins. A hard link
    never replaces, so the module keeps the first writer's mtime, which numba's on-disk cache
    records as the source's stamp (a replaced file would make a kernel just cached by another
    process stale, to be compiled again). On a file system without hard links the file is
    moved into place if it is still missing."""
    if path.exists():
        return
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_text(text)
    try:
        os.link(tmp, path)
    except FileExistsError:
        pass
    except OSError:                    # a file system without hard links
        if not path.exists():
            os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def build(circuit: Circuit) -> CompiledCircuit:
    """Generate, write (once, atomically) and import the circuit's kernel."""
    text, g, layout = generate(circuit)
    digest = hashlib.sha256(text.encode()).hexdigest()[:20]
    d = cache_dir()
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"circuit_{digest}.py"
    write_once(path, text)
    modname = f"afo_mj_circuit_{digest}"
    module = sys.modules.get(modname)
    if module is None:
        _announce(circuit.name, d, digest)
        spec = importlib.util.spec_from_file_location(modname, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[modname] = module
        spec.loader.exec_module(module)
    y0 = np.zeros(len(g.states))
    for k, st in enumerate(g.states):
        if st["kind"] == "pressure":
            y0[k] = circuit.options.initial_pressure_pa
    losses = tuple(label for label, _, _ in g.losses)
    stores = tuple(s["label"] for s in g.states)
    return CompiledCircuit(
        circuit=circuit, module=module, source_path=path, P=np.array(g.P),
        param_labels=tuple(g.P_labels), state_names=tuple(s["label"] for s in g.states),
        state_kinds=tuple(s["kind"] for s in g.states), loss_names=losses,
        store_names=stores, srate_names=tuple(layout["srate_names"]),
        probe_names=tuple(p for p, _ in g.probes),
        monitor_names=tuple(m for m, _, _ in g.monitors), y0=y0, w_init=dict(g.work_init),
        n_w=layout["n_w"], n_scratch=layout["n_scratch"], s_width=layout["s_width"],
        input_names=tuple(g.inputs), ctrl_names=tuple(g.ctrl_slots),
        state_stores=tuple(s["kind"] != "own" or s["store"] is not None for s in g.states))


__all__ = ["build", "generate", "packed_values", "write_once", "CompiledCircuit", "Emitter",
           "cache_dir", "leaf_fields"]
