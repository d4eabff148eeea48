"""Issue 40: the devices' controller gains are the circuits' own parameter sets, declared once.

The HAFO presets' ``control`` is :class:`~afo_mj.circuits.controllers.PumpTorqueGains` and the
valve presets' ``valve_control`` is :class:`~afo_mj.circuits.valve_controllers.
ValveTorqueParams`, handed to the controller as they are (the valve's set points filled in from
the preset's own fields). The reference of each check is the packed parameter row of the
generated circuit (:func:`afo_mj.circuits.codegen.generate`): the value a key sets is the value
the compiled controller reads. That the presets' modules did not move is
``tests/test_preset_circuit_golden.py``.
"""

from __future__ import annotations

import pytest

from afo_mj.circuits.codegen import generate
from afo_mj.circuits.controllers import PumpTorqueGains
from afo_mj.circuits.valve_controllers import ValveTorqueParams
from afo_mj.devices.hafo import hafo_circuit, hafo_params
from afo_mj.devices.valve_afo import (CONTROL_SET_BY_PRESET, VALVE_CONTROL_ALIASES,
                                      VALVE_PRESETS, valve_circuit, valve_params)
from afo_mj.hydraulics.params import ParameterError


def _packed(circuit) -> dict:
    _, g, _ = generate(circuit)
    return dict(zip(g.P_labels, g.P))


def test_hafo_control_is_the_controllers_gains_and_reaches_it():
    """``control.*`` keys of a HAFO preset set the pump_torque controller's packed gains."""
    p = hafo_params({"control.pressure_gain_rad_s_per_pa": 2.5e-5,
                     "control.speed_gain_v_s_per_rad": 0.03}, "hafo_gait")
    assert type(p.control) is PumpTorqueGains
    P = _packed(hafo_circuit(p))
    assert P["controller.k_p"] == 2.5e-5
    assert P["controller.k_w"] == 0.03
    assert P["controller.k_i"] == 4e-4 / 3.0          # the preset's own, kept
    assert P["controller.spring_ff"] == 0.0


def test_hafo_refuses_a_spring_feedforward():
    """The gains' spring feedforward is for a spring-return cylinder: the HAFO's piston-cable
    pair has none, so a non-zero value is refused when the parameters are read, naming it."""
    with pytest.raises(ParameterError, match=r"control\.spring_feedforward = 0\.5: .*no "
                                             r"return spring; allowed: 0"):
        hafo_params({"control.spring_feedforward": 0.5})


@pytest.mark.parametrize("old", list(VALVE_CONTROL_ALIASES))
def test_valve_control_former_names_set_the_same_gain(old):
    """Every former flat name of a valve supply gain sets the parameter it stands for, and so
    the same packed gain of the compiled controller."""
    new = VALVE_CONTROL_ALIASES[old]
    base = valve_params(preset="valve_pressure_control")
    cur = base
    for part in new.split("."):
        cur = getattr(cur, part)
    changed = 0.37 * cur
    a = valve_params({old: changed}, "valve_pressure_control")
    b = valve_params({new: changed}, "valve_pressure_control")
    assert a == b != base
    assert type(a.valve_control) is ValveTorqueParams
    pa, pbase = _packed(valve_circuit(a)), _packed(valve_circuit(base))
    moved = [k for k in pa if pa[k] != pbase[k]]
    assert len(moved) == 1 and pa[moved[0]] == changed


def test_valve_control_refuses_both_names_of_one_gain():
    old, new = next(iter(VALVE_CONTROL_ALIASES.items()))
    with pytest.raises(ParameterError, match="name one parameter"):
        valve_params({old: 0.01, new: 0.02})


@pytest.mark.parametrize("name", list(CONTROL_SET_BY_PRESET))
def test_valve_control_set_points_have_one_name(name):
    """The controller's set points are the preset's own fields: setting one under
    ``valve_control`` is refused, naming the field that sets it."""
    default = ValveTorqueParams()
    for part in name.split("."):
        default = getattr(default, part)
    other = (not default) if isinstance(default, bool) else default * 0.9
    field = CONTROL_SET_BY_PRESET[name]
    with pytest.raises(ParameterError, match=rf"valve_control\.{name} = .*set by the preset's "
                                             rf"{field}"):
        valve_params({f"valve_control.{name}": other})


@pytest.mark.parametrize("preset", list(VALVE_PRESETS))
def test_valve_set_points_reach_the_controller(preset):
    """The preset's own set-point fields are what the compiled controller reads."""
    p = VALVE_PRESETS[preset]
    P = _packed(valve_circuit(p))
    assert P["controller.max_torque"] == p.max_torque_nm
    assert P["controller.ff_density"] == p.fluid.density_kg_m3
    assert P["controller.speed_set"] == p.motor_speed_rad_s
    assert P["controller.pressure_control_on"] == float(p.supply_mode == "pressure_control")
    if p.circuit == "servo":
        assert P["controller.follows_demand_on"] == float(p.supply_pressure_follows_demand)
        assert P["controller.pressure_set"] == p.supply_pressure_set_pa
        assert P["controller.pressure_min"] == p.supply_pressure_min_pa
        assert P["controller.k_pp"] == p.valve_control.supply.pressure_gain_rad_s_per_pa
    assert P["controller.k_v"] == p.valve_control.valve_gain_per_pa
