"""The catalogue: every component and controller kind a circuit description may name.

Component modules define kinds (:mod:`afo_mj.circuits.components`: electrical, pump,
lines, plain valves, volumes, cylinders; :mod:`afo_mj.circuits.valves`: metering, switching
and supply valves, the variable pump; :mod:`afo_mj.circuits.valve_controllers`: the valve
circuits' controllers); this module only lists them, so a description's
``kind = "..."`` resolves in one place and :func:`afo_mj.circuits.circuit.Circuit` stays
independent of which modules hold them.
"""

from __future__ import annotations

from afo_mj.circuits import components as _c
from afo_mj.circuits import controllers as _k
from afo_mj.circuits import valve_controllers as _vk
from afo_mj.circuits import valves as _v

#: component kind → class
COMPONENT_KINDS = {c.kind: c for c in (
    _c.Battery, _c.MotorDriver, _c.Pump, _c.Hose, _c.ReliefValve, _c.CheckValve,
    _c.Drain, _c.FlushingValve, _c.Reservoir, _c.Volume, _c.GasAccumulator, _c.PulleyCylinders,
    _c.SpringReturnCylinder) + _v.COMPONENTS}

#: controller kind → class
CONTROLLER_KINDS = {c.kind: c for c in (_k.OpenLoop, _k.PumpTorque) + _vk.CONTROLLERS}


def _param_rows(ptype, prefix: str = "") -> list:
    """``(dotted name, default, unit, range, doc)`` of every leaf field of ``ptype``."""
    import dataclasses
    rows = []
    default = ptype()
    for f in dataclasses.fields(ptype):
        value = getattr(default, f.name)
        if dataclasses.is_dataclass(value):
            rows += _param_rows(type(value), prefix + f.name + ".")
            continue
        md = f.metadata
        rng = ""
        if md.get("kind") == "number":
            lo = "(" if md.get("lo_open") else "["
            hi = ")" if md.get("hi_open") else "]"
            rng = f"{lo}{md['lo']:g}, {md['hi']:g}{hi}"
        val = f"{value:g}" if isinstance(value, float) else repr(value)
        if len(val) > 40:
            val = val[:37] + "..."
        rows.append((prefix + f.name, val, md.get("unit", ""), rng,
                     " ".join(str(md.get("doc", "")).split())))
    return rows


def catalogue_markdown() -> str:
    """The component and controller catalogue as Markdown (``docs/circuits.md`` embeds it
    between its catalogue markers; a test keeps the two equal)."""
    import inspect
    out = []
    for kind, cls in COMPONENT_KINDS.items():
        out.append(f"### `{kind}`: {cls.summary}\n")
        out.append(inspect.cleandoc(cls.__doc__ or "") + "\n")
        ports = ", ".join(f"`{p}` ({d})" for p, d in cls.ports.items())
        out.append(f"Ports: {ports}.\n")
        rows = _param_rows(cls.params_type)
        meta = set(cls.metadata_fields)
        out.append("| parameter | default | unit | allowed | meaning |")
        out.append("|---|---|---|---|---|")
        for name, val, unit, rng, doc in rows:
            note = " (mass budget / label only)" if name in meta else ""
            out.append(f"| `{name}` | {val} | {unit} | {rng} | {doc}{note} |")
        out.append("")
    for kind, cls in CONTROLLER_KINDS.items():
        out.append(f"### controller `{kind}`: {cls.summary}\n")
        out.append(inspect.cleandoc(cls.__doc__ or "") + "\n")
        rows = _param_rows(cls.params_type)
        if rows:
            out.append("| parameter | default | unit | allowed | meaning |")
            out.append("|---|---|---|---|---|")
            for name, val, unit, rng, doc in rows:
                out.append(f"| `{name}` | {val} | {unit} | {rng} | {doc} |")
            out.append("")
    return "\n".join(out).rstrip() + "\n"
