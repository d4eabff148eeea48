"""The device registry: every shipped device by name, each a :class:`DeviceSpec` maker.

A tool that wears, benches, replays or calibrates a device asks this registry for its
:class:`~afo_mj.circuits.device_spec.DeviceSpec` by name (a scenario's ``device.preset``, a
record's ``source.preset``, a command-line option) and then reads the spec, never the name:

* the pump-controlled HAFO presets (:data:`afo_mj.devices.hafo.PRESETS`: ``hafo``, also
  known as ``hafo_prototype``, the published prototype; ``hafo_gait``, sized for walking),
  built by :func:`afo_mj.devices.hafo.hafo_spec` with dotted-name overrides;
* the valve circuits (:data:`afo_mj.devices.valve_afo.VALVE_PRESETS`: the servo circuit's
  supply variants, ``digital``, ``phafo``), built by :func:`afo_mj.devices.valve_afo.valve_spec`;
* the library circuits (:data:`afo_mj.circuits.library.LIBRARY`), descriptions with nested
  overrides in the description's own format, as a user's ``[circuit]`` is
  (:meth:`DeviceSpec.from_circuit`).

Adding a device is one maker plus one :func:`register_device` line.
"""

from __future__ import annotations

import dataclasses
import difflib
from typing import Callable, Mapping

from afo_mj.circuits import library
from afo_mj.circuits.device_spec import DeviceSpec
from afo_mj.devices import hafo, valve_afo
from afo_mj.hydraulics.params import ParameterError

__all__ = ["DeviceEntry", "register_device", "unregister_device", "device_names",
           "device_entry", "device_spec", "spec_of_params", "preset_names", "ALIASES"]


@dataclasses.dataclass(frozen=True)
class DeviceEntry:
    """A registered device: ``make(overrides)`` builds its spec with the overrides applied
    (dotted parameter names for a preset, a nested description table for a library
    circuit), validated; ``overrides_form`` says which, for error messages and docs."""

    name: str
    make: Callable[[Mapping | None], DeviceSpec]
    summary: str = ""
    #: a short family name for tables ("HAFO", "valve AFO", "circuit")
    label: str = "circuit"
    overrides_form: str = "dotted parameter names"
    #: the spec of a parameter set of this device's type (a design variant), or None for a
    #: description (its overrides are the description's)
    from_params: Callable[[object], DeviceSpec] | None = None
    #: the validated parameter set of ``overrides`` without building the spec (a scenario
    #: parses it; the device is built from it later), or None for a description
    params_of: Callable[[Mapping | None], object] | None = None


_REGISTRY: dict[str, DeviceEntry] = {}
#: other names of registered devices (alias → name)
ALIASES = {"hafo_prototype": "hafo"}


def register_device(entry: DeviceEntry) -> None:
    """Add ``entry`` (refused when its name, or an alias, is taken)."""
    if entry.name in _REGISTRY or entry.name in ALIASES:
        raise ParameterError(f"device {entry.name!r} is already registered")
    _REGISTRY[entry.name] = entry


def unregister_device(name: str) -> None:
    """Remove a registered device (a test's or a plug-in's)."""
    _REGISTRY.pop(name, None)


def device_names() -> tuple[str, ...]:
    """Registered device names, in registration order (aliases not included)."""
    return tuple(_REGISTRY)


def device_entry(name: str, key: str = "device.preset") -> DeviceEntry:
    """The entry of ``name`` (or its alias); ``key`` names where the name came from in the
    error."""
    entry = _REGISTRY.get(ALIASES.get(name, name))
    if entry is None:
        names = list(_REGISTRY) + list(ALIASES)
        near = difflib.get_close_matches(str(name), names, n=1, cutoff=0.6)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise ParameterError(f"{key} = {name!r} is not a registered device{hint}; allowed: "
                             f"{', '.join(names)}")
    return entry


def device_spec(name: str, overrides: Mapping | None = None,
                key: str = "device.preset") -> DeviceSpec:
    """The spec of registered device ``name`` with ``overrides`` applied (see
    :class:`DeviceEntry`)."""
    return device_entry(name, key).make(overrides)


def preset_names() -> tuple[str, ...]:
    """Registered devices built from a parameter set (the presets a scenario's
    ``device.preset`` names; the library circuits are worn as ``[circuit]`` descriptions)."""
    return tuple(n for n, e in _REGISTRY.items() if e.from_params is not None)


def _preset_maker(params_of, spec_of, preset: str):
    def make(overrides=None):
        return spec_of(params_of(dict(overrides or {}), preset), name=preset)
    return make


def _overrides_maker(params_of, preset: str):
    def params(overrides=None):
        return params_of(dict(overrides or {}), preset)
    return params


def _params_maker(spec_of, preset: str):
    def from_params(params):
        return spec_of(params, name=preset)
    return from_params


def spec_of_params(name: str, params, key: str = "device.preset") -> DeviceSpec:
    """The spec of registered device ``name`` built from ``params`` (a parameter set of its
    type, e.g. a design variant's); refused for a description (it takes overrides)."""
    entry = device_entry(name, key)
    if entry.from_params is None:
        raise ParameterError(f"{key} = {name!r} is a circuit description; allowed: its "
                             f"overrides ({entry.overrides_form}), not a parameter set")
    return entry.from_params(params)


def _library_maker(name: str):
    def make(overrides=None):
        return DeviceSpec.from_circuit(library.LIBRARY[name](dict(overrides or {}) or None),
                                       name=name)
    return make


for _name in hafo.PRESETS:
    register_device(DeviceEntry(_name, _preset_maker(hafo.hafo_params, hafo.hafo_spec, _name),
                                "pump-controlled hydraulic AFO", label="HAFO",
                                from_params=_params_maker(hafo.hafo_spec, _name),
                                params_of=_overrides_maker(hafo.hafo_params, _name)))
for _name, _p in valve_afo.VALVE_PRESETS.items():
    register_device(DeviceEntry(
        _name, _preset_maker(valve_afo.valve_params, valve_afo.valve_spec, _name),
        f"valve-controlled AFO ({_p.circuit} circuit, {_p.supply_mode} supply)",
        label="valve AFO",
        from_params=_params_maker(valve_afo.valve_spec, _name),
        params_of=_overrides_maker(valve_afo.valve_params, _name)))
for _name, _fn in library.LIBRARY.items():
    register_device(DeviceEntry(_name, _library_maker(_name),
                                " ".join((_fn.__doc__ or "").split(".")[0].split()),
                                "a nested [circuit] table (the description's own format)"))
