"""A described rig's declared set: every numeric value of its description, with tolerances.

A rig described as a circuit (``[circuit]`` in a calibration scenario) declares a value for
every numeric field of every component's parameters (the frozen dataclasses of
:mod:`afo_mj.hydraulics` and :mod:`afo_mj.circuits.components`, each field declared with its
unit and allowed range by :func:`afo_mj.hydraulics.params.param`), of the oil
(:class:`afo_mj.hydraulics.fluid.FluidParams`) and of a simulated load. All of them are
**declared parameters** of the calibration: :func:`described_parameters` walks the
description and makes one :class:`~afo_mj.calibration.effect_library.DeclaredParameter` per
field, named by its place in the description (``cylinder.series_compliance_rad_per_nm``,
``motor.motor.resistance_ohm``, ``fluid.liquid_bulk_modulus_pa``, ``load.stiffness_nm_rad``).
Which of them the record can estimate is decided by the identifiability screen
(:mod:`afo_mj.calibration.identifiability`), not here.

**Tolerances by kind** (:data:`KINDS`, one table). Each field is classed by its name and unit
(:func:`kind_of`); the class gives the datasheet tolerance (how far a real part may sit from
its datasheet value, relative: a fitted value beyond it is reported) and the range the fit may
move it in (factors of the described value, clipped to the field's allowed range):

* geometry (bores, diameters, radii, lengths, strokes): ±2 %, machined and drawn parts;
* passage volumes (dead volumes, ports, manifolds): ±20 %, estimated from drawings;
* clearances and roughness: ±50 %, a few µm (a gap sets a cube law);
* electrical: winding resistance ±20 % (copper's +0.39 %/K over a 50 K rise), inductance
  ±30 %, torque constant ±10 % (catalogue spread, magnet temperature), switch resistance ±50 %;
* inertia and mass: ±20 % (catalogue rotor values, estimated foot/load parts);
* friction (Coulomb, viscous, drag, seal scales, squeeze, elastomer modulus): ±50 %, the
  loosest datasheet figures, varying with run-in, temperature and lubrication;
* leakage (slip coefficients, conductances): ±100 %, wear and clearance dominated;
* compliance (bulk moduli, cable compliance, wall moduli): ±30 %; entrained air ±100 %;
* pressure settings (charge, cracking, relief): ±10 %, a regulator's or spring's setting;
* oil properties: density ±2 %, viscosity ±10 % (the ISO VG class width), expansion ±10 %;
* thermal: capacities and resistances ±50 %, the ambient ±1 % (±3 K);
* the simulated load: stiffness ±10 %, inertia ±20 %, damping ±50 %.

Fields that are not datasheet values are **not fitted by default** (their kind has no
tolerance; listed as excluded with the reason): numerical smoothing widths and bands, the
end stops' penalty stiffness and damping (a contact model, not a part's figure), ratings
the kernel only monitors, reference points of a datasheet (the temperatures a viscosity is
given at), counts and physical constants. A user may state a tolerance for any field in the
scenario's ``[calibration.tolerances]`` (``"cylinder.series_compliance_rad_per_nm" = 0.1``),
which also brings an excluded field into the set, and fix any field with ``[calibration]
fixed = [...]``; an unknown name is refused with the allowed ones.

A field whose change moves no entry of the circuit's packed parameter row (its effect is
switched off in the description: the pump's Coulomb coefficient with its friction off, a
metadata field such as a mass) reaches nothing the replay runs: excluded, with that reason.
How a field's value reaches the row is the component's own emitter
(:func:`afo_mj.circuits.codegen.packed_values`), so a bore moves the piston area, the seal
friction and the drag-out weight together, exactly as building the circuit would.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
from typing import Mapping, Sequence

from afo_mj.calibration.effect_library import DeclaredParameter
from afo_mj.circuits.codegen import packed_values
from afo_mj.hydraulics.params import ParameterError

__all__ = ["Kind", "KINDS", "kind_of", "DescribedSet", "described_parameters"]


@dataclasses.dataclass(frozen=True)
class Kind:
    """A class of quantity: its default datasheet tolerance (relative; ``None``: not a
    datasheet value, not fitted unless the user states a tolerance), the range of factors the
    fit may move it in and the reasoning."""

    tolerance: float | None
    lo_factor: float
    hi_factor: float
    why: str


#: the default tolerances and fit ranges by kind of quantity (module docstring)
KINDS: dict[str, Kind] = {
    "geometry": Kind(0.02, 0.9, 1.1, "machined/drawn dimension"),
    "volume": Kind(0.2, 0.5, 2.0, "passage volume estimated from drawings"),
    "clearance": Kind(0.5, 0.3, 3.0, "a micrometre-scale gap or surface roughness"),
    "resistance": Kind(0.2, 0.5, 2.0, "winding resistance rises 0.39 %/K with temperature"),
    "inductance": Kind(0.3, 0.3, 3.0, "catalogue inductance, saturating"),
    "torque_constant": Kind(0.1, 0.7, 1.4, "catalogue spread and magnet temperature"),
    "switch_resistance": Kind(0.5, 0.0, 5.0, "driver on-resistance"),
    "inertia": Kind(0.2, 0.5, 2.0, "catalogue rotor or estimated load inertia"),
    "friction": Kind(0.5, 0.0, 5.0, "run-in, temperature and lubrication change friction"),
    "leakage": Kind(1.0, 0.1, 10.0, "leakage follows wear and clearance"),
    "compliance": Kind(0.3, 0.1, 10.0, "moduli and compliances of oil, hoses, cables"),
    "air": Kind(1.0, 0.0, 10.0, "free air content varies with de-aeration"),
    "pressure_setting": Kind(0.1, 0.5, 2.0, "a regulator's or spring's setting"),
    "density": Kind(0.02, 0.9, 1.1, "oil density at its reference temperature"),
    "viscosity": Kind(0.1, 0.5, 2.0, "the ISO VG class is +-10 %"),
    "oil_property": Kind(0.1, 0.5, 2.0, "oil datasheet property"),
    "thermal": Kind(0.5, 0.2, 5.0, "lumped thermal capacity/resistance estimate"),
    "ambient": Kind(0.01, 0.95, 1.05, "ambient temperature, +-3 K"),
    "load_stiffness": Kind(0.1, 0.5, 2.0, "calibrated bench spring"),
    "load_damping": Kind(0.5, 0.0, 5.0, "bench damper estimate"),
    "setting": Kind(0.1, 0.5, 2.0, "a driver or supply setting"),
    # not datasheet values: fixed unless the user states a tolerance
    "numerical": Kind(None, 0.2, 5.0, "a smoothing width or band of the model, not a "
                                      "datasheet value"),
    "rating": Kind(None, 0.5, 2.0, "a rating the kernel only monitors"),
    "reference": Kind(None, 0.9, 1.1, "a datasheet's reference point (a definition)"),
    "count": Kind(None, 1.0, 1.0, "a count"),
    "constant": Kind(None, 0.7, 1.4, "a physical constant"),
}

#: (pattern on the field's last name, unit or None, kind): the first that matches classes it
_RULES: tuple[tuple[str, str | None, str], ...] = (
    (r"smoothing|band|transition|floor|opening_smoothing|^v_c|end_stop", None, "numerical"),
    (r"^max_speed|^max_pressure|^max_current|rating", None, "rating"),
    (r"reference_temperature|viscosity_(low|high)_temperature", None, "reference"),
    (r"^count$|cells_series", None, "count"),
    (r"polytropic|atmospheric", None, "constant"),
    (r"^load\.stiffness", None, "load_stiffness"),
    (r"^load\.damping", None, "load_damping"),
    (r"air_fraction", None, "air"),
    (r"bulk_modulus|compliance|stiffness", None, "compliance"),
    (r"elastic_modulus|squeeze|friction_coefficient|coulomb|viscous|drag|breakaway|"
     r"stribeck|pressure_coefficient", None, "friction"),
    (r"slip|leak|conductance", None, "leakage"),
    (r"clearance|roughness", None, "clearance"),
    (r"on_resistance", None, "switch_resistance"),
    (r"resistance_ohm", None, "resistance"),
    (r"inductance", None, "inductance"),
    (r"torque_constant", None, "torque_constant"),
    (r"inertia|mass", None, "inertia"),
    (r"volume", None, "volume"),
    (r"cracking|pressure_pa|setting|precharge", None, "pressure_setting"),
    (r"^density", None, "density"),
    (r"viscosity", None, "viscosity"),
    (r"expansion|specific_heat", None, "oil_property"),
    (r"heat_capacity|thermal_resistance", None, "thermal"),
    (r"ambient_temperature", None, "ambient"),
    (r"current_limit|duty|quiescent|voltage", None, "setting"),
    (r"bore|diameter|radius|length|stroke|cross_section|width|area|displacement|"
     r"moment_arm|lap|_m$", None, "geometry"),
)


#: packed row entries (by key, after the component's name) that are a model's regularisation,
#: not a part's figure, with what they are: a value that reaches only these (and entries
#: switched off by :data:`_ACTS_WITH`) is numerics, not fitted by default
_NUMERICAL_ENTRIES: dict[str, str] = {
    "seal_v_c": "the seal's Coulomb smoothing velocity v_C = v_brk/10 (F_C tanh(v/v_C) for "
                "F_C sign(v), a regularisation of the friction law)",
}
#: packed row entries that act only while another entry of the same component is non-zero:
#: key → (that entry, what it is). The Stribeck velocity v_St = √2 v_brk only shapes the
#: Stribeck term, whose gain is 0 with the peak switched off
_ACTS_WITH: dict[str, tuple[str, str]] = {
    "seal_v_st": ("seal_stribeck", "the seal's Stribeck peak"),
}


def kind_of(path: str, unit: str = "") -> str:
    """The kind of quantity of field ``path`` (its dotted name in the description) by the
    first matching rule of :data:`_RULES` on its last name (``load.`` fields on the whole
    path); ``"numerical"`` when none matches (not a datasheet value the table knows: fixed
    unless the user states a tolerance)."""
    last = path.rsplit(".", 1)[-1]
    for pattern, u, kind in _RULES:
        target = path if "load" in pattern else last
        if re.search(pattern, target) and (u is None or u == unit):
            return kind
    return "numerical"


@dataclasses.dataclass(frozen=True)
class _Field:
    name: str           # place in the description: part.field.path
    part: str           # component name, "fluid", "thermal" or "load"
    field: str          # dotted field path inside the part's parameters
    value: float
    unit: str
    lo: float
    hi: float
    lo_open: bool
    hi_open: bool
    doc: str


def _fields_of(obj, part: str, prefix: str = "") -> list[_Field]:
    out = []
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            out += _fields_of(v, part, prefix + f.name + ".")
        elif f.metadata.get("kind") == "number":
            md = f.metadata
            out.append(_Field(f"{part}.{prefix}{f.name}", part, prefix + f.name, float(v),
                              md.get("unit", ""), md.get("lo", -math.inf),
                              md.get("hi", math.inf), bool(md.get("lo_open")),
                              bool(md.get("hi_open")), md.get("doc", "")))
    return out


def _replace_path(obj, path: str, value: float):
    head, _, rest = path.partition(".")
    if rest:
        return dataclasses.replace(obj, **{head: _replace_path(getattr(obj, head), rest,
                                                               value)})
    return dataclasses.replace(obj, **{head: value})


class DescribedSet:
    """The declared set of a described rig (module docstring) and the packed row entries of
    any values of it.

    ``replay``: the :class:`~afo_mj.experiments.bench_replay.BenchReplay` of the description;
    ``tolerances``: name → relative tolerance stated by the user; ``fixed``: names the user
    holds at the described value. :attr:`parameters`: the fittable ones, in the order of the
    description; :attr:`excluded`: name → why it is not fitted; :attr:`table`: every field
    with its kind, tolerance and where the tolerance came from."""

    def __init__(self, replay, tolerances: Mapping[str, float] | None = None,
                 fixed: Sequence[str] = ()):
        self.replay = replay
        circuit = replay.circuit
        self.circuit = circuit
        fields: list[_Field] = _fields_of(circuit.fluid, "fluid")
        for comp in circuit.components:
            fields += _fields_of(comp.params, comp.name)
        fields += _fields_of(circuit.thermal, "thermal")
        if replay.load is not None:
            for key in ("inertia_kg_m2", "stiffness_nm_rad", "damping_nm_s_rad"):
                lo_open = key == "inertia_kg_m2"
                fields.append(_Field(f"load.{key}", "load", key,
                                     float(getattr(replay.load, key)), "", 0.0, math.inf,
                                     lo_open, False, f"simulated load {key}"))
        self._fields = {f.name: f for f in fields}
        tolerances = dict(tolerances or {})
        names = list(self._fields)
        for key, tol in list(tolerances.items()) + [(k, None) for k in fixed]:
            if key not in self._fields:
                where = ("calibration.tolerances" if tol is not None
                         else "calibration.fixed")
                raise ParameterError(f"{where}: {key!r} is not a numeric value of the "
                                     f"description; allowed: {', '.join(names)}")
        both = sorted(set(tolerances) & set(fixed))
        if both:
            raise ParameterError(f"calibration.tolerances and calibration.fixed both name "
                                 f"{both}; allowed: a value is either fitted with a tolerance "
                                 "or fixed")
        base = {lab: v for lab, v in zip(replay.cc.param_labels, replay.base_row)}
        self._base = base
        self._row_cache: dict = {}
        self.table: list[dict] = []
        self.excluded: dict[str, str] = {}
        params: list[DeclaredParameter] = []
        for f in fields:
            kind = kind_of(f.name, f.unit)
            k = KINDS[kind]
            tol = tolerances.get(f.name, k.tolerance)
            source = ("[calibration.tolerances]" if f.name in tolerances
                      else f"default for {kind}")
            row = {"name": f.name, "value": f.value, "unit": f.unit, "kind": kind,
                   "tolerance": tol, "tolerance_source": source}
            self.table.append(row)
            reason = None
            labels: tuple[str, ...] = ()
            if f.name in fixed:
                reason = "fixed by the user ([calibration] fixed)"
            elif tol is None:
                reason = f"not a datasheet value ({k.why}); state a tolerance to fit it"
            else:
                labels = self._moved_labels(f)
                numerics = self._numerics_only(labels)
                if not labels:
                    reason = ("reaches no equation the replay runs (its effect is switched "
                              "off in the description, or it is metadata)")
                elif numerics and f.name not in tolerances:
                    reason = f"not a datasheet value here: {numerics}; state a tolerance " \
                             "to fit it"
                    row.update(kind="numerical", tolerance=None,
                               tolerance_source=f"default for numerical (was {kind})")
            if reason is not None:
                self.excluded[f.name] = reason
                row["decision"] = reason
                continue
            lo_f, hi_f = self._factor_range(f, k)
            if not lo_f < hi_f:
                self.excluded[f.name] = "its allowed range leaves the fit no room"
                row["decision"] = self.excluded[f.name]
                continue
            row["decision"] = "screened"
            params.append(DeclaredParameter(
                f.name, f.unit, labels, lo_f, hi_f, f.doc or f.field, float(tol),
                path=f.name, value=f.value, kind=kind))
        #: the declared parameters the identifiability screen considers
        self.parameters: tuple[DeclaredParameter, ...] = tuple(params)

    def _numerics_only(self, labels: Sequence[str]) -> str | None:
        """Why the packed entries ``labels`` are numerics, when every one that acts is a
        regularisation of the model (:data:`_NUMERICAL_ENTRIES`; an entry of
        :data:`_ACTS_WITH` whose gate is 0 in the description does not act), else None."""
        acting, off = [], []
        for lab in labels:
            comp, _, key = lab.partition(".")
            gate = _ACTS_WITH.get(key)
            if gate is not None and self._base.get(f"{comp}.{gate[0]}", 1.0) == 0.0:
                off.append(gate[1])
                continue
            acting.append(key)
        if not acting or not all(k in _NUMERICAL_ENTRIES for k in acting):
            return None
        what = "; ".join(_NUMERICAL_ENTRIES[k] for k in dict.fromkeys(acting))
        return (f"with {', '.join(dict.fromkeys(off))} switched off in the description it "
                f"only sets {what}" if off else f"it only sets {what}")

    # ---------------------------------------------------------------- rows
    @staticmethod
    def _factor_range(f: _Field, k: Kind) -> tuple[float, float]:
        """The kind's factor range, clipped strictly inside the field's allowed range."""
        if f.value == 0.0:
            return k.lo_factor, k.hi_factor   # held as "described value is 0" by the screen
        a, b = sorted((f.lo / f.value, f.hi / f.value))
        lo, hi = k.lo_factor, k.hi_factor
        if math.isfinite(a):
            lo = max(lo, a + 1e-6 * max(abs(a), 1e-3))
        if math.isfinite(b):
            hi = min(hi, b - 1e-6 * max(abs(b), 1e-3))
        return float(lo), float(hi)

    def _moved_labels(self, f: _Field) -> tuple[str, ...]:
        """The packed labels a 10 % change of ``f`` moves (its value 0: a unit change)."""
        if f.part == "load":
            return (f.name,)
        trial = f.value * 1.1 if f.value != 0.0 else (1.0 if f.hi >= 1.0 else 0.5 * f.hi)
        if trial > f.hi or (f.hi_open and trial >= f.hi):
            trial = f.value * 0.9
        try:
            row = self._part_row(f.part, {f.field: trial})
        except ParameterError:
            return ()
        return tuple(lab for lab, v in row.items() if v != self._base.get(lab, v))

    def _part_row(self, part: str, changes: Mapping[str, float]) -> dict[str, float]:
        c = copy.copy(self.circuit)
        if part == "fluid":
            obj = c.fluid
            for path, v in changes.items():
                obj = _replace_path(obj, path, v)
            c.fluid = obj
        elif part == "thermal":
            obj = c.thermal
            for path, v in changes.items():
                obj = _replace_path(obj, path, v)
            c.thermal = obj
        else:
            comps = []
            for comp in c.components:
                if comp.name == part:
                    comp = copy.copy(comp)
                    obj = comp.params
                    for path, v in changes.items():
                        obj = _replace_path(obj, path, v)
                    comp.params = obj
                comps.append(comp)
            c.components = comps
        return packed_values(c, [part])

    def row(self, values: Mapping[str, float]) -> dict[str, float]:
        """The packed row entries (label → value) that differ from the description's when
        the named declared values take ``values`` (name → value in SI); each part is emitted
        with all its changed fields together. Raises :class:`ParameterError` for a value
        outside its field's allowed range."""
        key = tuple(sorted(values.items()))
        hit = self._row_cache.get(key)
        if hit is not None:
            return hit
        by_part: dict[str, dict[str, float]] = {}
        out: dict[str, float] = {}
        for name, v in values.items():
            f = self._fields[name]
            if f.part == "load":
                out[name] = float(v)
            elif float(v) != f.value:
                by_part.setdefault(f.part, {})[f.field] = float(v)
        for part, changes in by_part.items():
            for lab, v in self._part_row(part, changes).items():
                if v != self._base.get(lab, v):
                    out[lab] = float(v)
        if len(self._row_cache) > 512:
            self._row_cache.clear()
        self._row_cache[key] = out
        return out


def described_parameters(replay, tolerances: Mapping[str, float] | None = None,
                         fixed: Sequence[str] = ()) -> DescribedSet:
    """The declared set of the described rig ``replay`` (:class:`DescribedSet`)."""
    return DescribedSet(replay, tolerances, fixed)

