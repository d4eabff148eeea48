"""A device specification: a circuit description plus what the tools need to know about it.

A circuit description (:class:`afo_mj.circuits.circuit.Circuit`) says what is connected to
what and with which parameters; that is enough to step it. The tools around it (the coupled
walk, the test stand, the bench replay, the calibration, the energy ledger, the worn-mass
budget) also need to know what the parts *are* for: which input is the open-loop command and
which record channel carries it, how a measured command takes over from the controller, the
state the device starts from, which output channels a replay offers, how the component losses
and stores are grouped into the device's named ledger entries, and what is worn where.
:class:`DeviceSpec` carries those answers, so a tool asks the spec instead of switching on
which preset family it holds.

Every shipped device (the HAFO presets, the valve circuits, the library circuits) is a spec in
:mod:`afo_mj.devices.registry`; a user's ``[circuit]`` description becomes one with
:meth:`DeviceSpec.from_circuit` (generic roles: no mass budget, the ledger by component).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.components import CircuitError

__all__ = ["DeviceSpec", "LedgerGroups", "MassItem", "regroup", "circuit_roles",
           "OPEN_LOOP_CHANNELS", "TORQUE_CHANNEL"]

#: the record channel of a torque reference (the device's own torque controller runs on it)
TORQUE_CHANNEL = "commanded_torque_nm"
#: record channels an open-loop command may arrive on: a motor voltage (the circuit's
#: ``command`` input, the motor driver's) or a valve command (a valve circuit's controller
#: passes it to its metering valve)
OPEN_LOOP_CHANNELS = ("motor_voltage_v", "valve_command")


@dataclasses.dataclass(frozen=True)
class MassItem:
    """One part of a device's mass budget (one worn side): its mass and the walker site stem
    it is worn at (``waist``, ``shank_cuff``, ``foot_plate``, ``ankle_axis``; ``off_body``: a
    tethered supply, not worn)."""

    name: str
    mass_kg: float
    site: str
    note: str = ""


@dataclasses.dataclass(frozen=True)
class LedgerGroups:
    """How a device names its energy ledger: each named loss (store) is the sum of these
    component-instance losses (stores) of the generic circuit ledger
    (:meth:`afo_mj.circuits.device.CircuitDevice.ledger`), and the entries upstream of the
    pump's ports, whose losses and store changes separate the hydraulic energy the pump
    delivered from the electrical input (an energy balance of that part of the circuit)."""

    losses: Mapping[str, tuple[str, ...]]
    stores: Mapping[str, tuple[str, ...]]
    upstream_losses: tuple[str, ...] = ()
    upstream_stores: tuple[str, ...] = ()


def regroup(values: Mapping[str, float], table: Mapping[str, tuple[str, ...]],
            what: str) -> dict:
    """Sum the generic per-component entries ``values`` (component-instance names) into the
    named groups of ``table`` (group → tuple of generic names, in the order of the result).
    Every generic name must belong to exactly one group, so a component added to a circuit
    without a place in its device's ledger is an error rather than a silent omission."""
    out, used = {}, set()
    for group, names in table.items():
        out[group] = 0.0
        for n in names:
            if n in values:
                out[group] += values[n]
                used.add(n)
    missing = sorted(set(values) - used)
    if missing:
        raise CircuitError(f"{what}: {missing} belong to no ledger entry; allowed: "
                           + ", ".join(f"{g} ← {list(ns)}" for g, ns in table.items()))
    return out


#: component kinds that play the presets' roles (label prefixes of the calibration's
#: parameters and effects)
_ROLE_KINDS = {"cylinders": ("pulley_cylinders",), "pump": ("pump", "variable_pump"),
               "motor": ("motor",), "hose_a": ("hose",), "hose_b": ("hose",),
               "charge": ("reservoir",), "check_a": ("check_valve",),
               "check_b": ("check_valve",), "servo": ("servo_valve",),
               "drain_a": ("drain",), "drain_b": ("drain",)}


def circuit_roles(circuit: Circuit) -> dict[str, str]:
    """Role → component name of a described circuit: the first ``pulley_cylinders`` plays
    ``cylinders``, the first and second hoses ``hose_a`` and ``hose_b``, and so on (a
    component whose name already is the role's keeps it). The presets' part names are the
    roles (a calibration's parameter and effect labels name them: ``cylinders.seal_fc``,
    ``hose_a.wall_inv``), so a described circuit answers to them through this map."""
    names = {c.name: c.kind for c in circuit.components}
    used: set = set()
    roles: dict[str, str] = {}
    for role, kinds in _ROLE_KINDS.items():
        if names.get(role) in kinds:
            roles[role] = role
            used.add(role)
    for role, kinds in _ROLE_KINDS.items():
        if role in roles:
            continue
        for c in circuit.components:
            if c.kind in kinds and c.name not in used:
                roles[role] = c.name
                used.add(c.name)
                break
    return roles



@dataclasses.dataclass(frozen=True)
class DeviceSpec:
    """A device: its circuit description and the roles of its parts (module docstring).

    ``circuit`` is the description as worn (its controller tracks a torque reference when it
    is a torque controller). An open-loop command (``open_loop_channel``, one of
    :data:`OPEN_LOOP_CHANNELS`) reaches the actuator in one of three ways:
    ``open_loop_switch`` names a packed parameter that, set to 1, hands the actuator to the
    command (a valve circuit's ``controller.valve_command_on``); else ``open_loop_circuit`` is
    the same device with an open-loop controller (the HAFO's motor-voltage variant), stepped
    when a tool drives it open loop; else, in a replay, the command is imposed on the circuit's
    ``command`` input (the motor voltage) over whatever the controller sets.
    """

    #: registry name (a preset's) or the description's name
    name: str
    #: the circuit description as worn
    circuit: Circuit
    #: the parameter set the circuit was built from (a preset's frozen dataclass), or None
    #: for a description given directly
    params: Any = None
    #: one line for listings
    summary: str = ""
    #: the same device with an open-loop controller (see the class docstring), or None
    open_loop_circuit: Circuit | None = None
    #: the record channel of the open-loop command, or None (no open-loop command)
    open_loop_channel: str | None = None
    #: a packed parameter that hands the actuator to the open-loop command when set to 1
    open_loop_switch: str | None = None
    #: whether a torque reference (:data:`TORQUE_CHANNEL`) drives it through its controller
    torque_controlled: bool = True
    #: state label → value at t = 0 for the states that do not start where the circuit's
    #: options put them (a charged rail, a pump at its set speed)
    initial_state: Mapping[str, float] = dataclasses.field(default_factory=dict)
    #: a replay's output channels, in order, or None: every channel whose signal the circuit
    #: has (:mod:`afo_mj.experiments.bench_replay`)
    outputs: tuple[str, ...] | None = None
    #: log column renames (generic name → the name consumers read)
    log_names: Mapping[str, str] = dataclasses.field(default_factory=dict)
    #: the named ledger, or None: the ledger by component instance
    ledger: LedgerGroups | None = None
    #: extra ledger figures: key → (section of the generic ledger, entry), e.g.
    #: ``peak_supply_pressure_pa → ("state_peaks", "rail")``
    ledger_extras: Mapping[str, tuple[str, str]] = dataclasses.field(default_factory=dict)
    #: the driver's current limit (A) whose over-limit monitor gives the ledger's
    #: ``peak_current_a``, or None
    current_limit_a: float | None = None
    #: the mass budget of one worn side (None: masses not modelled)
    masses: tuple[MassItem, ...] | None = None
    #: prefix of the worn-mass labels on the walker (``<prefix>_<side>_<part>``)
    mass_label: str = "device"
    #: role → component name where they differ (:func:`circuit_roles`); empty: the part
    #: names are the roles
    roles: Mapping[str, str] = dataclasses.field(default_factory=dict)
    #: published measurements of the real device its bench figures are compared with
    #: (figure name → SI value, e.g. ``stall_torque_nm``), empty where none are published
    published: Mapping[str, float] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.circuit, Circuit):
            raise CircuitError(f"device {self.name!r}: circuit = {type(self.circuit).__name__};"
                               " allowed: a Circuit description")
        if self.open_loop_channel not in (None,) + OPEN_LOOP_CHANNELS:
            raise CircuitError(f"device {self.name!r}: open_loop_channel = "
                               f"{self.open_loop_channel!r}; allowed: "
                               + ", ".join(OPEN_LOOP_CHANNELS) + " or None")
        if self.open_loop_switch is not None and self.open_loop_circuit is not None:
            raise CircuitError(f"device {self.name!r}: both open_loop_switch and "
                               "open_loop_circuit given; allowed: one")

    @classmethod
    def from_circuit(cls, circuit: Circuit, name: str | None = None) -> "DeviceSpec":
        """A description given directly (a user's ``[circuit]``, a library circuit): an
        open-loop controller takes the motor voltage, a torque controller a torque
        reference; the replay's outputs are the channels whose signals it has; the ledger
        by component; masses not modelled."""
        open_loop = circuit.controller.kind == "open_loop"
        return cls(name=name or circuit.name, circuit=circuit,
                   summary=f"described circuit {circuit.name!r}",
                   open_loop_channel="motor_voltage_v" if open_loop else None,
                   torque_controlled=not open_loop, roles=circuit_roles(circuit))

    @property
    def commands(self) -> tuple[str, ...]:
        """The command channels it accepts, in order of preference: the open-loop command,
        then the torque reference."""
        out = (self.open_loop_channel,) if self.open_loop_channel else ()
        return out + ((TORQUE_CHANNEL,) if self.torque_controlled else ())

    def circuit_for(self, open_loop: bool = False) -> Circuit:
        """The description a tool steps: the worn one, or with ``open_loop`` its open-loop
        variant (:attr:`open_loop_circuit`, else the worn one: a switch or a circuit whose
        controller is open loop already). Refused for a device without an open-loop
        command."""
        if not open_loop:
            return self.circuit
        if self.open_loop_channel is None:
            raise CircuitError(f"device {self.name!r} takes no open-loop command; allowed: "
                               f"a torque reference ({TORQUE_CHANNEL})")
        return self.open_loop_circuit or self.circuit
