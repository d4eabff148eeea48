"""Property-based tests (hypothesis) of circuit descriptions drawn within their documented
ranges: every parameter of every component, the controller, the oil, the heat path and the
circuit options of the shipped descriptions (:data:`afo_mj.circuits.library.LIBRARY`), drawn
from the ranges the parameter dataclasses declare (:func:`afo_mj.hydraulics.params.param`'s
``lo``/``hi``/``lo_open``/``hi_open``, read here from the fields' metadata, so the tests follow
the documented ranges rather than numbers copied into them).

What must hold for every draw:

* the description builds (description and generated code), or it is refused with one
  :class:`~afo_mj.circuits.components.CircuitError` /
  :class:`~afo_mj.hydraulics.params.ParameterError` that names a drawn parameter and says
  what is allowed; never another exception;
* a built circuit driving a simulated joint load (:meth:`CircuitDevice.run_imposed` with a
  :class:`JointLoad`, 0.25 s) stays finite, and its energy ledger closes: input = mechanical
  output + losses + stored change, checked from the ledger's own terms (the sum, not the
  ledger's ``balance_error_rel``, is recomputed here).

The ledger did not close in three cases found by these draws; each was a bug, pinned by a
strict xfail test below with its smallest input (the property test does not assert closure on
a run that shows one still open, and counts them as hypothesis events):

* the battery asked for more than its matched-load power ``V_oc²/(4R)``: booked, the bus
  energy beyond it is the store ``battery_overload`` and the steps are flagged
  (``battery_overload_steps``, :class:`~afo_mj.circuits.components.Battery`); the test below
  now passes. The property test still counts capped runs as an event: asserting them changes
  the derandomized draws, which then reach a pump_accumulator with a 1 H motor inductance and
  0 Pa initial pressure (2 V amplitude) whose ledger closes to 1.5e-7 only, on the code before
  these fixes too (open: not the battery's);
* a pressure clipped at the vapour floor (``pressure_floor_steps``): fixed, the clip books the
  void it opens as the store ``cavitation`` (:mod:`afo_mj.circuits.stepper`), and the test
  below now passes;
* Newton iterations left unconverged (``newton_unconverged_steps``; reported as a flag and a
  console warning, the solver not fixed).

End-stop contact reporting is another change's (issue 38 item 3) and is not asserted here.

Every structure compiles once (numba, then cached on disk); parameter changes only change the
packed parameter row, so the draws do not recompile (checked below).
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from afo_mj.circuits.catalogue import COMPONENT_KINDS, CONTROLLER_KINDS
from afo_mj.circuits.circuit import Circuit, CircuitOptions, ThermalParams
from afo_mj.circuits.codegen import build
from afo_mj.circuits.components import CircuitError
from afo_mj.circuits.device import CircuitDevice, JointLoad
from afo_mj.hydraulics.fluid import ISO_VG32
from afo_mj.hydraulics.params import ParameterError, Parameters, replace_named
from afo_mj.scenarios.circuit_scenario import library_spec

#: one description per compiled structure (the ``*_gait`` variants share these structures)
STRUCTURES = ("lab_bench", "pump_accumulator", "spring_return")
#: relative to the energy throughput. Closing runs reach ~1e-10; what is left is the Newton
#: tolerance, which is on each pressure (Pa, in units of Y_TYP) rather than on the volume it
#: stands for, so a very compliant node closes its stored energy less tightly: a draw of
#: pump_accumulator with hose_b's wall at 1 MPa (the range's lower end) closes to 9.6e-7, and
#: to 4.7e-9 with the Newton tolerance divided by 100 (measured); a 1 ohm / 1 H motor at 0 Pa
#: to 1.5e-7. A ledger bug shows at 1e-3 and above.
LEDGER_TOL = 2e-6
N_STEPS = 250                 # 0.25 s at 1 ms
SETTINGS = dict(deadline=None, derandomize=True, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# ------------------------------------------------------------------------------ drawing


def numeric_fields(obj: Parameters, prefix: str = "") -> list[tuple[str, dict, float]]:
    """``(dotted name, range metadata, value)`` of every numeric parameter of ``obj``,
    nested sets included, from the ``param(...)`` metadata of its dataclass fields."""
    out = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, Parameters):
            out += numeric_fields(value, f"{prefix}{f.name}.")
        elif f.metadata.get("kind") == "number":
            out.append((f"{prefix}{f.name}", dict(f.metadata), float(value)))
    return out


def effect_fields(obj: Parameters, prefix: str = "") -> list[str]:
    """Dotted names of every effect switch (``effect(...)``) of ``obj``."""
    out = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, Parameters):
            out += effect_fields(value, f"{prefix}{f.name}.")
        elif f.metadata.get("kind") == "effect":
            out.append(f"{prefix}{f.name}")
    return out


def in_range(md: dict, default: float) -> st.SearchStrategy[float]:
    """A value allowed by ``md`` (``lo``, ``hi``, open ends): anywhere in the range (uniform,
    and log-uniform where it spans decades), at its closed ends, or within a factor 4 of
    ``default`` (the shipped design's neighbourhood, where most use is). An open end is
    approached to within 1e-9 of the range's width, not to the last float: a bore of 5e-324 m
    is allowed by ``lo = 0, lo_open`` but is no design (what it does is pinned by
    :func:`test_a_subnormal_seal_cross_section_is_refused_by_name`)."""
    lo, hi = md["lo"], md["hi"]
    lo_eff = lo + (hi - lo) * 1e-9 if md["lo_open"] else lo
    hi_eff = hi - (hi - lo) * 1e-9 if md["hi_open"] else hi

    def clip(x: float) -> float:
        return min(max(x, lo_eff), hi_eff)

    parts = [st.floats(lo_eff, hi_eff), st.sampled_from([lo_eff, hi_eff])]
    if lo_eff > 0 and hi_eff / lo_eff > 100.0:
        parts.append(st.floats(math.log(lo_eff), math.log(hi_eff))
                     .map(lambda u: clip(math.exp(u))))
    elif lo_eff == 0 and hi_eff > 0:
        parts.append(st.floats(math.log(hi_eff * 1e-9), math.log(hi_eff))
                     .map(lambda u: clip(math.exp(u))))
    if default > 0:
        parts.append(st.floats(-math.log(4.0), math.log(4.0))
                     .map(lambda u: clip(default * math.exp(u))))
    return st.one_of(parts)


def _component_params(kind: str, overrides: dict) -> Parameters:
    base = COMPONENT_KINDS[kind].params_type()
    return replace_named(base, overrides) if overrides else base


def parameter_table(name: str) -> list[tuple[tuple, str, dict | None, float | None]]:
    """Everything a description of structure ``name`` may set: ``(where, dotted name,
    metadata, shipped value)``, ``where`` is ``("components", c)``, ``("controller",)``,
    ``("fluid",)``, ``("thermal",)`` or ``("options",)``; effect switches have metadata None."""
    spec = library_spec(name)
    rows = []
    for cname, c in spec["components"].items():
        p = _component_params(c["kind"], c.get("params", {}))
        rows += [(("components", cname), n, md, v) for n, md, v in numeric_fields(p)]
        rows += [(("components", cname), n, None, None) for n in effect_fields(p)]
    ctrl = dict(spec.get("controller", {"kind": "open_loop"}))
    cp = CONTROLLER_KINDS[ctrl.get("kind", "open_loop")].params_type()
    cp = replace_named(cp, ctrl.get("params", {})) if ctrl.get("params") else cp
    rows += [(("controller",), n, md, v) for n, md, v in numeric_fields(cp)]
    fluid = ISO_VG32.replace(air_fraction=0.001)
    rows += [(("fluid",), n, md, v) for n, md, v in numeric_fields(fluid)]
    rows += [(("fluid",), n, None, None) for n in effect_fields(fluid)]
    rows += [(("thermal",), n, md, v) for n, md, v in numeric_fields(ThermalParams())]
    opts = replace_named(CircuitOptions(), spec.get("options", {})) \
        if spec.get("options") else CircuitOptions()
    rows += [(("options",), n, md, v) for n, md, v in numeric_fields(opts)]
    return rows


TABLES = {name: parameter_table(name) for name in STRUCTURES}


@st.composite
def drawn_description(draw, max_changes: int = 6):
    """``(structure, description, changes)``: a shipped description with 1 … ``max_changes``
    of its parameters (or effect switches) drawn within their documented ranges."""
    name = draw(st.sampled_from(STRUCTURES))
    table = TABLES[name]
    picks = draw(st.lists(st.integers(0, len(table) - 1), min_size=1, max_size=max_changes,
                          unique=True))
    spec = copy.deepcopy(library_spec(name))
    changes = {}
    for i in picks:
        where, key, md, default = table[i]
        value = draw(st.booleans() if md is None else in_range(md, default))
        if where[0] == "components":
            spec["components"][where[1]].setdefault("params", {})[key] = value
            changes[f"{where[1]}.{key}"] = value
        elif where[0] == "controller":
            spec.setdefault("controller", {"kind": "open_loop"}).setdefault(
                "params", {})[key] = value
            changes[f"controller.{key}"] = value
        else:
            section = spec.get(where[0])
            if not isinstance(section, dict):
                spec[where[0]] = section = {}
            section[key] = value
            changes[f"{where[0]}.{key}"] = value
    return name, spec, changes


def build_or_refusal(spec: dict, changes: dict):
    """The compiled circuit, or None when it is refused with an error that names a drawn
    parameter and what is allowed (anything else fails the test)."""
    try:
        return build(Circuit.from_dict(spec))
    except (CircuitError, ParameterError) as exc:
        msg = str(exc)
        leaves = {k.rsplit(".", 1)[-1] for k in changes}
        assert any(leaf in msg for leaf in leaves), (
            f"the refusal does not name a drawn parameter {sorted(changes)}: {msg}")
        assert "allowed" in msg or "must" in msg, f"the refusal says nothing allowed: {msg}"
        assert "\n" not in msg.strip() and "Traceback" not in msg, msg
        return None


def drive(cc, amplitude: float) -> tuple[CircuitDevice, dict]:
    """The circuit on a simulated joint load (0.02 kg m² on 80 N·m/rad and 0.5 N·m·s/rad),
    commanded by one 4 Hz cycle: a motor voltage (V) for ``open_loop``, a plantarflexion
    torque (N·m) for a torque controller."""
    dev = CircuitDevice(cc)
    t = np.arange(N_STEPS) * 1e-3
    if cc.circuit.controller.kind == "open_loop":
        cmd = amplitude * 0.5 * np.sin(2 * np.pi * 4.0 * t)
    else:
        cmd = -amplitude * np.sin(np.pi * 4.0 * t) ** 2
    zero = np.zeros(N_STEPS)
    log = dev.run_imposed(cmd, zero, zero, load=JointLoad(0.02, 80.0, 0.5))
    return dev, log


def battery_capped(dev: CircuitDevice, log: dict) -> bool:
    """Did the pack reach its matched-load current ``V_oc/(2R)`` (where
    :func:`~afo_mj.hydraulics.laws.battery_current_a` caps the power)? ``V_oc`` from the
    battery model at the run's state of charge."""
    comps = [c for c in dev.cc.circuit.components if c.kind == "battery"]
    if not comps:
        return False
    p = comps[0].params
    v_oc = float(np.min(p.battery.open_circuit_voltage_v(np.array([p.initial_soc]))))
    i_cap = v_oc / (2.0 * p.battery.internal_resistance_ohm)
    return bool(np.max(log["battery_current_a"]) >= 0.98 * i_cap)


def closing_error(led: dict) -> float:
    """``(input − output − Σ losses − Σ stored) / throughput`` from the ledger's terms."""
    resid = (led["input_j"] - led["mechanical_out_j"] - sum(led["losses_j"].values())
             - sum(led["stored_change_j"].values()))
    return resid / max(led["energy_throughput_j"], 1e-12)


def _assert_finite(tree, where: str = "") -> None:
    if isinstance(tree, dict):
        for k, v in tree.items():
            _assert_finite(v, f"{where}.{k}")
    elif isinstance(tree, (float, int, np.ndarray)) and not isinstance(tree, bool):
        assert np.all(np.isfinite(tree)), f"non-finite {where}"


# ------------------------------------------------------------------------------ properties


def test_the_drawn_ranges_are_the_documented_ones():
    """The tables the draws use are read from the dataclasses: a range changed in
    the code is a range changed here (spot checks against the declarations)."""
    rows = {(w, n): md for w, n, md, _ in TABLES["pump_accumulator"] if md is not None}
    hose = rows[(("components", "hose_a"), "bore_m")]
    assert (hose["lo"], hose["hi"], hose["lo_open"]) == (0.0, 0.1, True)
    bat = rows[(("components", "battery"), "battery.internal_resistance_ohm")]
    assert (bat["lo"], bat["hi"], bat["lo_open"]) == (0.0, 100.0, True)
    assert (("options",), "initial_pressure_pa") in rows
    assert any(w == ("controller",) for w, _ in rows)
    assert all(len(TABLES[n]) > 80 for n in STRUCTURES)


def test_parameter_changes_do_not_recompile():
    """A drawn parameter set reuses its structure's generated module (the draws below stay
    within the compiled structures)."""
    spec = copy.deepcopy(library_spec("spring_return"))
    spec["components"]["hose"]["params"]["length_m"] = 7.5
    spec["components"]["cylinder"].setdefault("params", {})["spring_rate_n_m"] = 1.0e5
    a, b = build(Circuit.from_dict(library_spec("spring_return"))), build(Circuit.from_dict(spec))
    assert a.source_path == b.source_path
    assert not np.array_equal(a.P, b.P)


@settings(max_examples=150, **SETTINGS)
@given(drawn_description())
def test_drawn_descriptions_build_or_are_refused_by_name(drawn):
    _name, spec, changes = drawn
    cc = build_or_refusal(spec, changes)
    event("refused" if cc is None else "built")


@settings(max_examples=45, **SETTINGS)
@given(drawn_description(max_changes=4), st.floats(2.0, 40.0))
def test_drawn_circuits_stay_finite_and_close_their_ledger(drawn, amplitude):
    _name, spec, changes = drawn
    cc = build_or_refusal(spec, changes)
    if cc is None:
        event("refused")
        return
    dev, log = drive(cc, amplitude)          # a non-finite state raises FloatingPointError
    for key, values in log.items():
        assert np.all(np.isfinite(values)), f"{key} not finite for {changes}"
    led = dev.ledger()
    _assert_finite(led)
    known = [name for name, hit in (
        ("battery at its matched-load power", battery_capped(dev, log)),
        ("newton unconverged", led["newton_unconverged_steps"] > 0)) if hit]
    if known:
        event("ledger not checked: " + ", ".join(known))       # the xfail tests below
        return
    event("ledger checked")
    err = closing_error(led)
    assert abs(err) < LEDGER_TOL, (changes, err)
    assert err == pytest.approx(led["balance_error_rel"], abs=1e-12)


# ------------------------------------------------------------------------------ found bugs
# Each test checks first that its input reaches the case it is about (a RuntimeError, which the
# xfail does not accept, if not), then asserts the property: only the property may fail.


def _ledger_of(name: str, changes: dict, amplitude: float = 15.0) -> tuple[dict, bool]:
    spec = copy.deepcopy(library_spec(name))
    for key, value in changes.items():
        comp, param = key.split(".", 1)
        spec["components"][comp].setdefault("params", {})[param] = value
    dev, log = drive(build(Circuit.from_dict(spec)), amplitude)
    return dev.ledger(), battery_capped(dev, log)


def _reaches(condition: bool, what: str) -> None:
    if not condition:
        raise RuntimeError(f"the input no longer reaches the case: {what}")


def test_ledger_closes_when_the_battery_reaches_its_matched_load_power():
    """A pack asked for more than ``V_oc²/(4R)`` is capped at ``V_oc/(2R)`` while the bus
    loads, which see the voltage held from the last step, draw what they asked for: the excess
    is booked as the (negative) store ``battery_overload`` and the steps are counted (before,
    spring_return with battery.internal_resistance_ohm = 45.9 ohm left balance_error_rel
    -0.60). Reference for the booked energy: the pack delivers at most ``V_oc²/(4R)``, so
    what it delivered (``∫(V_oc I − R I²) dt``: input less its internal loss) is at most
    that power over the run, and the booked excess makes up the rest of the bus energy."""
    led, capped = _ledger_of("spring_return", {"battery.battery.internal_resistance_ohm": 45.9})
    _reaches(capped and led["pressure_floor_steps"] == 0
             and led["newton_unconverged_steps"] == 0, "battery capped, nothing else")
    assert led["battery_overload_steps"] > 0
    over = led["stored_change_j"]["battery_overload"]
    assert over < 0.0
    comp = Circuit.from_dict(library_spec("spring_return")).components
    bat = next(c for c in comp if c.kind == "battery").params.battery
    v_oc = float(np.max(bat.open_circuit_voltage_v(np.array([0.0, 1.0]))))
    delivered = led["input_j"] - led["losses_j"]["battery.internal"]
    assert delivered <= v_oc ** 2 / (4 * 45.9) * N_STEPS * 1e-3 * (1 + 1e-9)
    assert abs(closing_error(led)) < LEDGER_TOL
    calm, capped = _ledger_of("spring_return", {}, amplitude=2.0)
    assert not capped and calm["battery_overload_steps"] == 0
    assert calm["stored_change_j"]["battery_overload"] == 0.0


@pytest.mark.parametrize("changes", [{"motor.motor.torque_constant_nm_a": 8.6},
                                     {"inlet.bore_m": 0.0012}])
def test_ledger_closes_when_a_pressure_reaches_the_vapour_floor(changes):
    """A pressure raised to the vapour floor (``clip_floor``) gains a volume no flow brought:
    the ledger books the energy of that void as the store ``cavitation`` and closes (before,
    spring_return with motor.torque_constant_nm_a = 8.6 N m/A left balance_error_rel +0.018
    over ~50 clipped steps, a 1.2 mm inlet bore +0.024 over ~150); the void's energy is
    positive (work done against the atmosphere the stores are referred to)."""
    led, capped = _ledger_of("spring_return", changes)
    _reaches(led["pressure_floor_steps"] > 0 and not capped
             and led["newton_unconverged_steps"] == 0, "floor clipped, nothing else")
    assert led["stored_change_j"]["cavitation"] > 0.0
    assert abs(closing_error(led)) < LEDGER_TOL
    # a run that never reaches the floor books nothing there
    calm, _ = _ledger_of("spring_return", {}, amplitude=2.0)
    assert calm["pressure_floor_steps"] == 0 and calm["stored_change_j"]["cavitation"] == 0.0


UNCONVERGED = {"tank.pressure_pa": 3.53e6, "inlet.bore_m": 0.0756}


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "open: spring_return with reservoir tank.pressure_pa = 3.53 MPa (allowed 0 ... 5 MPa) and "
    "inlet.bore_m = 75.6 mm (allowed (0, 0.1] m): from the first step the Newton iteration "
    "of the suction node (a few cm^3 of aerated oil filled from 3.5 MPa through the wide "
    "inlet) does not converge even at 1/1024 of the step, its iterates fall below the vapour "
    "floor and are clipped every sub-step (~1000 unconverged sub-steps and clips a step; "
    "131 kJ booked as inlet line loss in 0.25 s, balance_error_rel -228). The steps are "
    "reported (ledger newton_unconverged_steps, the newton_unconverged flag, WARNING SOLVER: "
    "test_unconverged_steps_are_flagged_and_said); the solver itself is not fixed"))
def test_ledger_closes_when_newton_does_not_converge():
    led, _ = _ledger_of("spring_return", UNCONVERGED)
    _reaches(led["newton_unconverged_steps"] > 0, "unconverged steps")
    assert abs(closing_error(led)) < LEDGER_TOL


def test_unconverged_steps_are_flagged_and_said():
    """Steps accepted unconverged are not silent: the ledger counts them (two steps of the
    case above), the device summary's flags carry them (a study constrains on
    ``device.newton_unconverged``, a sweep counts it) and the console warns."""
    from afo_mj.metrics.device_flags import device_flags
    from afo_mj.outputs.console import device_warnings, sweep_outcome_counts

    spec = copy.deepcopy(library_spec("spring_return"))
    for key, value in UNCONVERGED.items():
        comp, param = key.split(".", 1)
        spec["components"][comp].setdefault("params", {})[param] = value
    dev = CircuitDevice(build(Circuit.from_dict(spec)))
    dev.run_imposed(np.zeros(2), np.zeros(2), np.zeros(2), load=JointLoad(0.02, 80.0, 0.5))
    n = dev.ledger()["newton_unconverged_steps"]
    assert n > 0
    flags = device_flags(None, "actuator", False, n)
    assert flags["newton_unconverged"] is True and flags["flags"] == ["newton_unconverged"]
    assert device_flags(None, "actuator", False, 0)["flags"] == []
    (line,) = device_warnings({**flags, "newton_unconverged_steps": n})
    assert line.startswith("WARNING SOLVER") and f" {n} " in line
    assert device_warnings({"newton_unconverged_steps": 0}) == []
    rows = [{"run_id": "r1", "status": "ok", "device.newton_unconverged": True},
            {"run_id": "r2", "status": "ok", "device.newton_unconverged": False}]
    assert sweep_outcome_counts(rows) == {"unconverged solver steps": ["r1"]}


def test_battery_overload_steps_are_flagged_and_said():
    """Steps whose bus drew more than the battery's matched-load power are not silent: the
    ledger counts them, the device summary's flags carry them (a study constrains on
    ``device.battery_overload``, a sweep counts it), the console warns, and a comparison row
    carries the count and gets a line under the tables."""
    from afo_mj.experiments.device_comparison import HEAD_COLUMNS
    from afo_mj.metrics.device_flags import device_flags
    from afo_mj.outputs.comparison_report import caveats
    from afo_mj.outputs.console import device_warnings, sweep_outcome_counts

    led, _ = _ledger_of("spring_return", {"battery.battery.internal_resistance_ohm": 45.9})
    n = led["battery_overload_steps"]
    assert n > 0
    flags = device_flags(None, "actuator", False, 0, n)
    assert flags["battery_overload"] is True and flags["flags"] == ["battery_overload"]
    assert device_flags(None, "actuator", False, 0, 0)["flags"] == []
    (line,) = device_warnings({**flags, "battery_overload_steps": n})
    assert line.startswith("WARNING BATTERY") and f" {n} " in line
    assert device_warnings({"battery_overload_steps": 0}) == []
    rows = [{"run_id": "r1", "status": "ok", "device.battery_overload": True},
            {"run_id": "r2", "status": "ok", "device.battery_overload": False}]
    assert sweep_outcome_counts(rows) == {"battery past its matched-load power": ["r1"]}
    assert {"battery_overload", "battery_overload_steps"} <= set(HEAD_COLUMNS)
    (cav,) = caveats([{"label": "weak pack", "battery_overload_steps": n},
                      {"label": "good pack", "battery_overload_steps": 0}])
    assert cav.startswith(f"WARNING BATTERY: weak pack: {n} ")


def test_a_subnormal_seal_cross_section_is_refused_by_name():
    """An open lower bound at 0 admitted subnormal values: a seal cross-section of 5e-324 m
    passed the range check and the O-ring law divided by its underflowed contact half-width
    (ZeroDivisionError). A subnormal is refused by name in any range (a negative one too)."""
    spec = copy.deepcopy(library_spec("lab_bench"))
    spec["components"]["cylinder"]["params"]["cylinder.rod_seal.cross_section_m"] = 5e-324
    with pytest.raises((CircuitError, ParameterError),
                       match=r"cross_section_m = 5e-324 .*allowed: 0 < cross_section_m"):
        build(Circuit.from_dict(spec))
    from afo_mj.hydraulics.fluid import FluidParams
    with pytest.raises(ParameterError, match="air_fraction = 1e-310 .*allowed"):
        FluidParams(air_fraction=1e-310)
    assert FluidParams(air_fraction=0.0).air_fraction == 0.0       # zero itself is normal
