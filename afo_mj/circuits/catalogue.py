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
    _c.Battery, _c.MotorDriver, _c.Pump, _c.Hose, _c.ReliefValve, _c.CheckValve, _c.Reservoir,
    _c.Volume, _c.GasAccumulator, _c.PulleyCylinders, _c.SpringReturnCylinder) + _v.COMPONENTS}

#: controller kind → class
CONTROLLER_KINDS = {c.kind: c for c in (_k.OpenLoop, _k.PumpTorque) + _vk.CONTROLLERS}
