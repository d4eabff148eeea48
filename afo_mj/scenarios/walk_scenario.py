"""Walking scenarios: a TOML file validated into a frozen :class:`WalkScenario`.

Schema (every section and key optional except where said; unknown keys are errors)::

    name = "walk_healthy"            # [A-Za-z0-9_.-]+, default: the file name without .toml
    description = "..."
    [walker]                         # any WalkerParams field (afo_mj.human.walker), SI units
    body_preset = "child_8y"         # a named body size (afo_mj.human.body_presets: CDC 2000
                                     # medians child_4y..child_14y[_boy|_girl], adult_male,
                                     # adult_female): sets body_mass_kg and height_m; those
                                     # two, if also given here, override the preset
    body_mass_kg = 75.0
    height_m = 1.75
    timestep_s = 0.001               # default 1 ms, but 0.5 ms when the resulting height_m is
                                     # below 1.3 m (body_presets.default_timestep_s)
    model = "torque"                 # "torque" (PD tracking of the reference, the default) or
                                     # "muscle": 14 Hill-type muscles under a reflex controller
                                     # (afo_mj.gait.muscle_walk); the reference then only scores
                                     # the walk, [impairment] strength fractions scale the
                                     # muscles' maximum forces, [controller] does not apply;
                                     # [device], [circuit] and [assistance] are worn as on
                                     # the torque walker; or the name of a controller
                                     # registered with afo_mj.gait.controller.
                                     # register_controller ([controller] then fills its
                                     # Params)
    reflex_set = "1.25"              # muscle model: a shipped set (MUSCLE_REFLEX_SETS) or a
                                     # reflex_params.json path (afo-mj optimize-gait), relative
                                     # to the file
    [gait]
    reference = "winter"             # "winter" | "schwartz2008" (default "winter")
    condition = "normal"             # winter: normal; schwartz2008: VerySlow|Slow|Free (Fast and
                                     # VeryFast are refused: the walker falls, see UNWALKABLE);
                                     # schwartz2008 starts at its own speed (start_speed_m_s)
    reference_path = "my_gait.csv"   # instead of reference/condition: a user's cycle, CSV
                                     # (afo_mj.gait.reference.load_reference_csv) or OpenSim
                                     # .sto/.mot (load_opensim_storage); relative to the file
    reference_grf_path = "grf.mot"   # with an OpenSim reference_path: it is a trial (any
                                     # start, many cycles); the reference is the mean of its
                                     # complete cycles, events from these forces
                                     # (afo_mj.gait.measured_trial); with reference_id_path
                                     # its moments, and its forces per kg, come too
    cadence_steps_per_min = 105.3    # 30..200; default: the reference's own cadence
    strides = 10                     # right-leg cycles to simulate, 1..1000
    analyse_strides = [4, 10]        # first, last stride analysed (1-based, inclusive)
    [impairment]                     # WalkerParams impairment fields, validated by WalkerParams
    plantarflexor_strength_fraction = 1.0     # 0..1
    dorsiflexor_strength_fraction = 1.0       # 0..1
    ankle_passive_stiffness_nm_per_rad = 0.0  # 0..2000
    ankle_passive_damping_nm_s_per_rad = 0.0  # 0..100
    [controller]                     # overrides of afo_mj.gait.walk.ControllerParams fields
    [device]                         # an orthosis (afo_mj.scenarios.device_scenario)
    [assistance]                     # its assistance profile (afo_mj.scenarios.device_scenario)
    [circuit]                        # a circuit description worn instead of device.preset
                                     # (afo_mj.scenarios.circuit_scenario)
    [output]                         # what a run writes besides summary.json and figures
    record = false                   # true: a rerun recording, recording.rrd, in the results
                                     # directory (afo_mj.outputs.recording; `--rrd FILE` on
                                     # the command line writes one anywhere)
    signal_rate_hz = 500.0           # recording: scalar signals sample rate, 1..100000 Hz
    transform_rate_hz = 50.0         # recording: 3D body transforms sample rate, 1..10000 Hz
    opensim = false                  # true: opensim/<run>_ik.mot, _id.sto, _grf.mot,
                                     # _grf.xml (ExternalLoads) and <run>.osim (the model)
                                     # in the results directory
                                     # (afo_mj.outputs.opensim_export)

Any problem (TOML syntax, unknown key, wrong type, value out of range, missing reference
file) raises one :class:`ScenarioError` naming the file, the dotted key, the value and what
is allowed. ``afo-mj run`` maps it to exit code 2 and writes nothing.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

from afo_mj.hydraulics.params import ParameterError
from afo_mj.human.walker import WalkerParams
from afo_mj.scenarios.schema import Key, ScenarioError, Table, check_table, did_you_mean

__all__ = ["ScenarioError", "WalkScenario", "load_scenario", "parse_scenario",
           "REFERENCES", "TOP", "GAIT", "IMPAIRMENT", "OUTPUT", "did_you_mean", "strides_overrides"]

REFERENCES: dict[str, tuple[str, ...]] = {
    "winter": ("normal",),
    "schwartz2008": ("VerySlow", "Slow", "Free", "Fast", "VeryFast"),
}
"""Shipped normative references and their conditions."""
DEFAULT_CONDITION = {"winter": "normal", "schwartz2008": "Free"}

#: shipped reference conditions this walker cannot walk, refused at load with the reason and
#: what to set instead (tests/test_reference_walks.py walks every other one)
UNWALKABLE: dict[tuple[str, str], str] = {
    ("schwartz2008", cond): (
        f"the walker falls within about 2-5 s tracking the children's {cond} kinematics "
        f"(on the adult and on a child body, at any start speed and at cycle times up to "
        f"1.3x the reference's: its foot placement cannot hold the long, fast strides of "
        f"this speed group)")
    for cond in ("Fast", "VeryFast")}
_UNWALKABLE_INSTEAD = (
    'walk Winter\'s kinematics at this speed group\'s cadence and judge them against its bands: '
    'gait.reference = "winter", gait.cadence_steps_per_min = {cad:g}, gait.band_references = '
    '["schwartz2008:{cond}"] (as scenarios/walk_schwartz_fast.toml does), or '
    'gait.condition = "Free", "Slow" or "VerySlow"')

#: the default start speed (ControllerParams.initial_speed_m_s, 1.0 m/s) is Winter's start on
#: the 1.75 m walker: 1.11 x the no-slip speed of Winter's posture at Winter's cadence
#: (0.9036 m/s). A schwartz2008 condition without controller.initial_speed_m_s starts at the
#: same multiple of its own no-slip speed at the walker's cadence (VerySlow 0.62 m/s ...
#: Free 1.25 m/s on the adult): started at Winter's 1.0 m/s, VerySlow fell at 2.5 s.
START_SPEED_OVER_NO_SLIP = 1.0 / 0.9036

#: the top level of a walking scenario file
TOP = Table("", (
    Key("name", "string", doc="letters, digits, _ . -; default: the file name without .toml"),
    Key("description", "string", default=""),
    Key("walker", "table", doc="body size and model (WalkerParams fields, body_preset, model, "
        "reflex_set)"),
    Key("gait", "table", doc="the reference gait, cadence and strides"),
    Key("impairment", "table", doc="WalkerParams impairment fields"),
    Key("controller", "table", doc="overrides of the walker model's controller parameters"),
    Key("device", "table", doc="an orthosis (afo_mj.scenarios.device_scenario)"),
    Key("assistance", "table", doc="its assistance profile (device_scenario)"),
    Key("output", "table", doc="what a run writes besides summary.json and figures"),
    Key("circuit", "table", doc="a circuit description worn instead of device.preset")))
#: ``[gait]``
GAIT = Table("gait", (
    Key("reference", "string", default="winter", doc=" | ".join(REFERENCES)),
    Key("condition", "string", doc="a condition of the reference (DEFAULT_CONDITION)"),
    Key("reference_path", "string", doc="a user's cycle: .csv, .sto or .mot, relative to the "
        "file"),
    Key("cadence_steps_per_min", "number", (30.0, 200.0), unit="steps/min",
        doc="default: the reference's own cadence"),
    Key("strides", "integer", (1, 1000), default=10, doc="right-leg cycles to simulate"),
    Key("analyse_strides", "list", doc="[first, last] stride analysed (1-based, inclusive)"),
    Key("band_references", "list", default=(), doc="'source:condition' bands to judge "
        "against"),
    Key("reference_id_path", "string", doc="OpenSim inverse dynamics beside reference_path"),
    Key("reference_grf_path", "string", doc="OpenSim ground reaction forces: reference_path "
        "is a trial")))
#: ``[impairment]``: the WalkerParams fields of the same names (which validate them)
IMPAIRMENT = Table("impairment", (
    Key("plantarflexor_strength_fraction", "number", (0.0, 1.0)),
    Key("dorsiflexor_strength_fraction", "number", (0.0, 1.0)),
    Key("ankle_passive_stiffness_nm_per_rad", "number", (0.0, 2000.0), unit="N*m/rad"),
    Key("ankle_passive_damping_nm_s_per_rad", "number", (0.0, 100.0), unit="N*m*s/rad")))
#: ``[output]``
OUTPUT = Table("output", (
    Key("record", "bool", default=False, doc="a rerun recording in the results directory"),
    Key("signal_rate_hz", "number", (1.0, 1e5), 500.0, "Hz", "recording: scalar signals"),
    Key("transform_rate_hz", "number", (1.0, 1e4), 50.0, "Hz", "recording: 3D transforms"),
    Key("opensim", "bool", default=False, doc="OpenSim storage files of the run(s)")))
_NAME_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")
CADENCE_RANGE = GAIT["cadence_steps_per_min"].range
STRIDES_RANGE = GAIT["strides"].range
#: body mass index [kg/m^2] of the bodies the walker stands for: de Leva's (1996) adult
#: segment fractions scaled by mass and stature, shipped bodies from the CDC 2000 medians
#: (4-year-olds 15.4) to adults (21.8-22.6); outside it a scenario is noted, not refused
BMI_RANGE_KG_M2 = (13.0, 40.0)
#: ``--set`` keys that change the walker's body: a file's description stating its mass or
#: height is then marked as the file's, with the body that runs
_BODY_OVERRIDE_KEYS = ("walker", "walker.body_mass_kg", "walker.height_m", "walker.body_preset")


def strides_overrides(n: int) -> list[str]:
    """The ``--set`` overrides of ``--strides N`` (``run`` and ``compare``): N strides
    simulated, strides ``[max(2, N - 4), N]`` analysed (stride 1 for N = 1)."""
    first = max(2, n - 4) if n >= 2 else 1
    return [f"gait.strides={n}", f"gait.analyse_strides=[{first}, {n}]"]


def _rebuild_walk_scenario(state: dict) -> "WalkScenario":
    """Inverse of :meth:`WalkScenario.__reduce__`."""
    return WalkScenario(**{k: (MappingProxyType(v) if k in _MAPPING_FIELDS else v)
                           for k, v in state.items()})


_MAPPING_FIELDS = ("controller", "device", "assistance", "circuit")


@dataclasses.dataclass(frozen=True)
class WalkScenario:
    """A validated walking scenario (see the module docstring for the TOML schema).

    ``walker`` holds body size and impairment; ``reference``/``condition`` name a shipped
    normative gait, or ``reference == "file"`` with ``reference_path``; ``cadence_steps_per_min``
    None means the reference's own; ``controller`` maps ControllerParams field names to
    overriding values; ``text`` is the TOML source (copied into the run's outputs).
    """

    name: str
    description: str
    walker: WalkerParams
    reference: str
    condition: str | None
    reference_path: Path | None
    cadence_steps_per_min: float | None
    strides: int
    analyse_strides: tuple[int, int]
    controller: Mapping[str, float]
    band_references: tuple[tuple[str, str], ...] = ()
    reference_id_path: Path | None = None
    #: ``gait.reference_grf_path``: the trial's ground reaction forces; the reference is
    #: then the mean of the trial's complete cycles (afo_mj.gait.measured_trial)
    reference_grf_path: Path | None = None
    source_path: Path | None = None
    text: str = ""
    #: what the parser adjusted on the user's behalf (e.g. the analysed strides following a
    #: ``--set gait.strides``), one sentence each, for the command line to print
    notes: tuple[str, ...] = ()
    #: raw ``[device]`` and ``[assistance]`` tables (validated by
    #: :mod:`afo_mj.scenarios.device_scenario`); empty for a walk without an orthosis
    device: Mapping[str, Any] = dataclasses.field(default_factory=lambda: MappingProxyType({}))
    assistance: Mapping[str, Any] = dataclasses.field(
        default_factory=lambda: MappingProxyType({}))
    #: raw ``[circuit]`` table (a circuit description worn instead of a ``device.preset``,
    #: validated by :mod:`afo_mj.scenarios.circuit_scenario`); empty without one
    circuit: Mapping[str, Any] = dataclasses.field(default_factory=lambda: MappingProxyType({}))
    #: ``[output]``: write a rerun recording into the results directory, and its rates
    record: bool = False
    record_signal_rate_hz: float = 500.0
    record_transform_rate_hz: float = 50.0
    #: ``[output] opensim``: write the run(s) as OpenSim storage files and models
    opensim: bool = False
    #: ``walker.model``: "torque" or "muscle"; ``walker.reflex_set``: the muscle model's
    #: reflex parameter file (absolute path; None for the torque model)
    walker_model: str = "torque"
    reflex_set: Path | None = None

    def __reduce__(self):
        """Pickle support (batches and sweeps send scenarios to worker processes): the
        read-only mapping fields travel as dicts and come back read-only."""
        state = {f.name: (dict(getattr(self, f.name))
                          if isinstance(getattr(self, f.name), MappingProxyType)
                          else getattr(self, f.name)) for f in dataclasses.fields(self)}
        return _rebuild_walk_scenario, (state,)

    def load_reference(self):
        """The reference gait (:class:`afo_mj.gait.reference.ReferenceGait`)."""
        from afo_mj.gait import reference as ref
        if self.reference_path is None:
            return ref.load_normative(self.reference, self.condition)
        return _load_reference_file(self.reference_path, self.walker.body_mass_kg,
                                    self.reference_id_path, self.reference_grf_path)

    def cycle_time_s(self, reference=None) -> float:
        """Gait cycle time: 120 / cadence; without a cadence, the reference's cycle time
        carried to this walker's stature by dynamic similarity (equal Froude number, cycle
        time ∝ √stature; the reference adult is taken as 1.75 m)."""
        if self.cadence_steps_per_min is not None:
            return 120.0 / self.cadence_steps_per_min
        ref = reference if reference is not None else self.load_reference()
        if ref.cycle_time_s is None:
            raise ScenarioError(f"{self.source_path or self.name}: the reference has no cycle "
                                f"time; set gait.cadence_steps_per_min")
        from afo_mj.human.walker import DynamicScale
        return float(ref.cycle_time_s) * DynamicScale.of(
            self.walker.body_mass_kg, self.walker.height_m).time

    def controller_params(self):
        """:class:`afo_mj.gait.walk.ControllerParams` with this scenario's overrides; a
        schwartz2008 reference without ``controller.initial_speed_m_s`` gets its own start
        speed (:meth:`start_speed_m_s`). A registered controller's model: its ``Params``
        from ``[controller]`` (None when it takes none)."""
        if self.walker_model not in ("torque", "muscle"):
            from afo_mj.gait.controller import controller_class
            cls = controller_class(self.walker_model)
            return None if cls.Params is None else cls.Params(**self.controller)
        from afo_mj.gait.walk import ControllerParams
        kw = dict(self.controller)
        if self.reference == "schwartz2008" and "initial_speed_m_s" not in kw:
            kw["initial_speed_m_s"] = round(self.start_speed_m_s(), 4)
        return ControllerParams(**kw)

    def start_speed_m_s(self, reference=None) -> float:
        """Start speed derived from the reference, as ``controller.initial_speed_m_s`` (for
        the 1.75 m walker; :func:`~afo_mj.gait.walk.run_walk` scales it by √(stature/1.75 m)):
        :data:`START_SPEED_OVER_NO_SLIP` × the no-slip speed of the reference's posture at
        this scenario's cycle time on this walker's legs."""
        from afo_mj.gait.walk import ReferenceTable
        from afo_mj.human.anthropometry import scale_body
        from afo_mj.human.walker import DynamicScale
        ref = reference if reference is not None else self.load_reference()
        seg = scale_body(self.walker.body_mass_kg, self.walker.height_m)
        table = ReferenceTable(ref, seg.thigh.length_m, seg.shank.length_m, n=200)
        v = START_SPEED_OVER_NO_SLIP * table.geometric_stride_m / self.cycle_time_s(ref)
        return float(v / DynamicScale.of(self.walker.body_mass_kg, self.walker.height_m).speed)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready description (for the run summary)."""
        return {"name": self.name, "description": self.description,
                "file": None if self.source_path is None else str(self.source_path),
                "reference": self.reference, "condition": self.condition,
                "reference_path": None if self.reference_path is None else str(self.reference_path),
                "reference_id_path": (None if self.reference_id_path is None
                                      else str(self.reference_id_path)),
                "reference_grf_path": (None if self.reference_grf_path is None
                                       else str(self.reference_grf_path)),
                "cadence_steps_per_min": self.cadence_steps_per_min, "strides": self.strides,
                "analyse_strides": list(self.analyse_strides),
                "band_references": [f"{s}:{c}" for s, c in self.band_references],
                "walker": {f.name: getattr(self.walker, f.name)
                           for f in dataclasses.fields(self.walker)},
                "walker_model": self.walker_model,
                "reflex_set": None if self.reflex_set is None else str(self.reflex_set),
                "controller": dict(self.controller),
                # every gain the run used (defaults included), so a result can be reproduced
                "controller_effective": _effective(self.controller_params())}


def _effective(params) -> dict | None:
    """Every parameter a run used (defaults included), JSON-ready."""
    if params is None:
        return None
    return {k: (list(v) if isinstance(v, tuple) else v)
            for k, v in dataclasses.asdict(params).items()}


def _load_reference_file(path: Path, body_mass_kg: float, id_path: Path | None = None,
                         grf_path: Path | None = None):
    """A user's reference cycle: OpenSim ``.sto``/``.mot`` coordinates (with an optional
    inverse-dynamics ``.sto``) or CSV, with the loaders' documented default column mapping;
    with ``grf_path`` the coordinates are a trial and the reference is the mean of its
    complete cycles (:func:`afo_mj.gait.measured_trial.load_measured_trial`)."""
    from afo_mj.gait import reference as ref
    if grf_path is not None:
        from afo_mj.gait.measured_trial import load_measured_trial
        return load_measured_trial(path, grf_path, id_path=id_path,
                                   body_mass_kg=body_mass_kg).reference
    if path.suffix.lower() in (".sto", ".mot"):
        return ref.load_opensim_storage(path, body_mass_kg=body_mass_kg, id_path=id_path)
    return ref.load_reference_csv(path, body_mass_kg=body_mass_kg)


# ------------------------------------------------------------------------------------------
# validation helpers
# ------------------------------------------------------------------------------------------

class _Ctx:
    def __init__(self, origin: str):
        self.origin = origin

    def fail(self, key: str, value: Any, problem: str, allowed: str) -> ScenarioError:
        return ScenarioError(f"{self.origin}: {key} = {value!r} {problem}; allowed: {allowed}")

    def table(self, doc: Mapping, key: str) -> dict:
        v = doc.get(key, {})
        if not isinstance(v, dict):
            raise self.fail(key, v, "is not a table", f"a [{key}] section")
        return v

    def unknown(self, schema: Table, table: Mapping) -> None:
        check_table(table, schema, self.origin)

    def string(self, key: str, v: Any, allowed: str = "a string") -> str:
        if not isinstance(v, str):
            raise self.fail(key, v, f"has the wrong type ({type(v).__name__})", allowed)
        return v

    def number(self, key: str, v: Any, lo: float, hi: float, unit: str) -> float:
        allowed = f"a number {lo:g} <= {key.rsplit('.', 1)[-1]} <= {hi:g} [{unit}]"
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(key, v, f"has the wrong type ({type(v).__name__})", allowed)
        if not (math.isfinite(v) and lo <= v <= hi):
            raise self.fail(key, v, "is out of range", allowed)
        return float(v)

    def integer(self, key: str, v: Any, lo: int, hi: int) -> int:
        allowed = f"an integer {lo} <= {key.rsplit('.', 1)[-1]} <= {hi}"
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(key, v, f"has the wrong type ({type(v).__name__})", allowed)
        if not lo <= v <= hi:
            raise self.fail(key, v, "is out of range", allowed)
        return v


def _controller_fields() -> dict[str, Any] | None:
    """ControllerParams fields by name, or None while the controller module is absent."""
    try:
        from afo_mj.gait.walk import ControllerParams
    except ImportError:
        return None
    return {f.name: f for f in dataclasses.fields(ControllerParams)}


def _walker(ctx: _Ctx, walker_tbl: dict, imp_tbl: dict) -> WalkerParams:
    """WalkerParams from ``[walker]`` and ``[impairment]``.

    ``walker.body_preset`` names a body size of :mod:`afo_mj.human.body_presets` and supplies
    ``body_mass_kg`` and ``height_m``; either of them given explicitly in ``[walker]`` overrides
    the preset's value. Without ``walker.timestep_s``, a walker whose resulting ``height_m`` is
    below 1.3 m gets 0.5 ms (:func:`afo_mj.human.body_presets.default_timestep_s`; faster
    dynamics of a small body, see ``scenarios/walk_child_healthy.toml``), others the 1 ms
    default.
    """
    from afo_mj.human.body_presets import (SMALL_BODY_HEIGHT_M, body_preset,
                                           default_timestep_s, preset_names)
    fields = [f.name for f in dataclasses.fields(WalkerParams)]
    ctx.unknown(Table.of_names("walker", ["body_preset"] + fields), walker_tbl)
    ctx.unknown(IMPAIRMENT, imp_tbl)
    walker_tbl = dict(walker_tbl)
    preset = None
    if "body_preset" in walker_tbl:
        raw = walker_tbl.pop("body_preset")
        allowed = "one of " + ", ".join(preset_names())
        name = ctx.string("walker.body_preset", raw, allowed)
        try:
            preset = body_preset(name)
        except ParameterError:
            raise ctx.fail("walker.body_preset", name, "is not a known body preset",
                           allowed) from None
    kw: dict[str, Any] = {}
    dotted: dict[str, str] = {}
    if preset is not None:
        for k in ("body_mass_kg", "height_m"):
            if k not in walker_tbl:
                kw[k], dotted[k] = getattr(preset, k), f"walker.body_preset ({preset.name}).{k}"
    for section, tbl in (("walker", walker_tbl), ("impairment", imp_tbl)):
        for k, v in tbl.items():
            if k in kw:
                raise ScenarioError(f"{ctx.origin}: {section}.{k} = {v!r} is also set as "
                                    f"{dotted[k]} = {kw[k]!r}; allowed: set it once")
            kw[k], dotted[k] = v, f"{section}.{k}"
    height = kw.get("height_m", WalkerParams().height_m)
    if ("timestep_s" not in kw and isinstance(height, (int, float))
            and not isinstance(height, bool) and height < SMALL_BODY_HEIGHT_M):
        kw["timestep_s"] = default_timestep_s(float(height))
        dotted["timestep_s"] = f"walker.timestep_s (default for height_m = {height!r})"
    for k, v in kw.items():          # one field at a time, so the error names its key
        try:
            WalkerParams(**{k: v})
        except ParameterError as exc:
            raise ScenarioError(f"{ctx.origin}: {dotted[k]} = {v!r} rejected: {exc}") from None
    try:
        return WalkerParams(**kw)
    except ParameterError as exc:
        raise ScenarioError(f"{ctx.origin}: [walker]/[impairment] "
                            f"{', '.join(dotted.values())} rejected together: {exc}") from None


def walker_model_names() -> tuple[str, ...]:
    """The walker models a scenario may name (``walker.model``): the built-in ``"torque"`` and
    ``"muscle"`` and every controller registered with
    :func:`afo_mj.gait.controller.register_controller`."""
    from afo_mj.gait.controller import controller_names
    return controller_names()


def muscle_reflex_sets() -> dict[str, Path]:
    """The shipped reflex parameter sets of the muscle walker by name: ``"1.25"`` is
    ``afo_mj/data/reflex_params_1.25.json``; the wearers re-optimised with a device worn
    (``tools/muscle_adapted.py``, docs/muscle_walker.md) are ``"adapted/<condition>"`` (e.g.
    ``"adapted/hafo"``, ``"adapted/zhang_seed2"``) and ``"adapted_weak/<condition>"`` for the
    wearer with weak plantarflexors."""
    from importlib.resources import files
    data = Path(str(files("afo_mj") / "data"))
    sets = {p.stem.removeprefix("reflex_params_"): p
            for p in sorted(data.glob("reflex_params_*.json"))}
    for folder in ("adapted", "adapted_weak"):
        sets.update({f"{folder}/{p.stem}": p for p in sorted((data / folder).glob("*.json"))})
    return sets


def _muscle_model(ctx: _Ctx, doc: dict, model, raw_set, base_dir: Path | None) -> Path | None:
    """``walker.model`` and ``walker.reflex_set``: the reflex file of a muscle walker (None
    for the torque model); the muscle model refuses the torque walker's ``[controller]`` and
    nothing else: an orthosis (``[device]``, ``[circuit]``, ``[assistance]``) is worn by
    either walker."""
    names = walker_model_names()
    model = ctx.string("walker.model", model, " | ".join(repr(m) for m in names))
    if model not in names:
        raise ctx.fail("walker.model", model, "is not a walker model (built in, or a "
                       "controller registered with afo_mj.gait.controller.register_controller)",
                       " | ".join(repr(m) for m in names))
    if model != "muscle":
        if raw_set is not None:
            raise ctx.fail("walker.reflex_set", raw_set, f"is given for the {model} model",
                           "walker.reflex_set with walker.model = 'muscle'")
        return None
    if ctx.table(doc, "controller"):
        raise ctx.fail("controller", dict(ctx.table(doc, "controller")),
                       "does not apply to walker.model = 'muscle' (it sets the torque "
                       "walker's tracking controller; the muscle walker's reflexes are "
                       "walker.reflex_set)", "no [controller] table")
    shipped = muscle_reflex_sets()
    if (isinstance(raw_set, (int, float)) and not isinstance(raw_set, bool)
            and repr(float(raw_set)) in shipped):
        # --set walker.reflex_set=1.25 reads the name as a number: the shipped set it names
        raw_set = repr(float(raw_set))
    raw = ctx.string("walker.reflex_set", "1.25" if raw_set is None else raw_set,
                     "a shipped set (" + ", ".join(shipped) + ") or a reflex_params.json path")
    if raw in shipped:
        return shipped[raw]
    p = Path(raw)
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    if p.suffix.lower() != ".json" or not p.is_file():
        raise ctx.fail("walker.reflex_set", raw, f"is neither a shipped set nor a file (looked "
                       f"at {p})", "a shipped set (" + ", ".join(shipped) + ") or an existing "
                       "reflex_params.json (afo-mj optimize-gait)")
    return p


def _registered_controller(ctx: _Ctx, model: str, tbl: dict) -> dict[str, Any]:
    """``[controller]`` of a registered controller: its ``Params`` dataclass's fields, checked
    by constructing it (its own range checks name the key, the value and what is allowed)."""
    from afo_mj.gait.controller import controller_class
    cls = controller_class(model)
    if cls.Params is None:
        if tbl:
            raise ctx.fail("controller", dict(tbl), f"is given, but the {model!r} controller "
                           "takes no parameters", "no [controller] table")
        return {}
    ctx.unknown(Table.of_names("controller", [f.name for f in dataclasses.fields(cls.Params)]),
                tbl)
    try:
        cls.Params(**tbl)
    except (ValueError, TypeError) as exc:
        raise ScenarioError(f"{ctx.origin}: [controller] of walker.model = {model!r} "
                            f"rejected: {exc}") from None
    return dict(tbl)


def _controller(ctx: _Ctx, tbl: dict, model: str = "torque") -> dict[str, float]:
    if model not in ("torque", "muscle"):
        return _registered_controller(ctx, model, tbl)
    fields = _controller_fields()
    out: dict[str, float] = {}
    if fields is None:                # controller module absent: keep plain numbers
        for k, v in tbl.items():
            out[k] = ctx.number(f"controller.{k}", v, -math.inf, math.inf, "SI")
        return out
    ctx.unknown(Table.of_names("controller", fields), tbl)
    from afo_mj.gait.walk import ControllerParams
    for k, v in tbl.items():
        md = fields[k].metadata
        if md.get("kind") == "number":
            out[k] = ctx.number(f"controller.{k}", v, md.get("lo", -math.inf),
                                md.get("hi", math.inf), md.get("unit", ""))
        else:
            out[k] = v
        try:
            ControllerParams(**{k: out[k]})
        except ParameterError as exc:
            raise ScenarioError(f"{ctx.origin}: controller.{k} = {v!r} rejected: {exc}") from None
    try:
        ControllerParams(**out)
    except ParameterError as exc:
        raise ScenarioError(f"{ctx.origin}: [controller] values rejected together: {exc}") from None
    return out


def apply_overrides(doc: dict, overrides, origin: str = "<scenario>") -> dict:
    """Set dotted keys in a parsed TOML document: ``["gait.strides=4",
    "device.params.hose.length_m=2.2"]``. Values are read as TOML values (numbers, booleans,
    strings in quotes, arrays); anything that is not valid TOML is taken as a bare string.
    The first two levels are tables of the scenario schema; below ``device.params``,
    ``circuit.components.<name>.params`` and ``circuit.controller.params`` the rest of the key
    is a dotted parameter name and is kept whole."""
    for item in overrides or ():
        key, sep, raw = str(item).partition("=")
        key = key.strip()
        if not sep or not key:
            raise ScenarioError(f"{origin}: --set {item!r}: expected key=value, e.g. "
                                "gait.strides=4")
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        parts = key.split(".")
        if parts[:2] == ["device", "params"] and len(parts) > 2:
            parts = parts[:2] + [".".join(parts[2:])]
        elif (parts[:2] == ["circuit", "components"] and len(parts) > 4
              and parts[3] == "params"):
            parts = parts[:4] + [".".join(parts[4:])]
        elif parts[:3] == ["circuit", "controller", "params"] and len(parts) > 3:
            parts = parts[:3] + [".".join(parts[3:])]
        node = doc
        for part in parts[:-1]:
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                raise ScenarioError(f"{origin}: --set {key}: {part!r} is not a table")
            node = nxt
        node[parts[-1]] = value
    return doc


def _override_keys(overrides) -> list[str]:
    """The dotted keys of ``key=value`` override strings."""
    return [str(item).partition("=")[0].strip() for item in overrides or ()]


def _follow_window(window, old_strides, strides: int) -> list[int] | None:
    """The file's analysed window carried to ``strides`` set on the command line: its start
    kept, its end clipped to ``strides`` (or moved with it when it ended at the file's last
    stride); a start past the new end becomes ``max(2, strides - 4)`` (1 for one stride).
    None when ``window`` is not a well-formed ``[first, last]`` (the validation reports it)."""
    if (not isinstance(window, list) or len(window) != 2
            or any(isinstance(x, bool) or not isinstance(x, int) for x in window)):
        return None
    first, last = window
    last = strides if last == old_strides else min(last, strides)
    if not 1 <= first <= last:
        first = max(2, last - 4) if last >= 2 else 1
    return [first, last]


def parse_scenario(text: str, origin: str = "<scenario>", base_dir: Path | None = None,
                   default_name: str = "scenario", source_path: Path | None = None,
                   overrides=()) -> WalkScenario:
    """Validate TOML ``text`` into a :class:`WalkScenario` (``origin`` names it in errors;
    ``base_dir`` resolves a relative ``gait.reference_path``; ``overrides`` are ``key=value``
    strings applied first, see :func:`apply_overrides`)."""
    ctx = _Ctx(origin)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{origin}: not valid TOML: {exc}") from None
    ov_keys = _override_keys(overrides)
    if not any(isinstance(doc.get(t), dict) and doc.get(t) for t in ("device", "circuit")):
        for key in ov_keys:
            if key == "device" or key.startswith("device."):
                raise ScenarioError(
                    f"{origin}: --set {key}: this scenario has no device (no [device] or "
                    f"[circuit] table), so device keys do not apply; allowed: device.* keys on "
                    f"a scenario with a [device] table, e.g. scenarios/gait_assist_hafo.toml")
    file_gait = doc.get("gait") if isinstance(doc.get("gait"), dict) else {}
    file_strides = file_gait.get("strides", GAIT.default("strides"))
    file_window = file_gait.get("analyse_strides")
    apply_overrides(doc, overrides, origin)
    ctx.unknown(TOP, doc)
    name = ctx.string("name", doc.get("name", default_name), "a name of letters, digits, _ . -")
    if not _NAME_RE.match(name):
        raise ctx.fail("name", name, "is not a valid name", "letters, digits, _ . - (non-empty)")
    description = ctx.string("description", doc.get("description", TOP.default("description")))

    walker_tbl = dict(ctx.table(doc, "walker"))
    model = walker_tbl.pop("model", "torque")
    raw_set = walker_tbl.pop("reflex_set", None)
    walker = _walker(ctx, walker_tbl, ctx.table(doc, "impairment"))
    reflex_set = _muscle_model(ctx, doc, model, raw_set, base_dir)
    body_set = [k for k in ov_keys if k in _BODY_OVERRIDE_KEYS]
    if description and body_set:
        # the file's prose was written for the file's body; say which body actually runs
        description = (f"{description} [the file's description; --set {', '.join(body_set)} "
                       f"made the walker {walker.body_mass_kg:g} kg, {walker.height_m:g} m]")

    gait = ctx.table(doc, "gait")
    ctx.unknown(GAIT, gait)
    reference_path = None
    if "reference_path" in gait:
        raw = ctx.string("gait.reference_path", gait["reference_path"],
                         "a path to a .csv, .sto or .mot file")
        for k in ("reference", "condition"):
            if k in gait:
                raise ctx.fail(f"gait.{k}", gait[k], "is given together with gait.reference_path",
                               "either gait.reference (+ condition) or gait.reference_path")
        p = Path(raw)
        if not p.is_absolute() and base_dir is not None:
            p = base_dir / p
        if p.suffix.lower() not in (".csv", ".sto", ".mot"):
            raise ctx.fail("gait.reference_path", raw, "has an unknown file type",
                           "a .csv, .sto or .mot file")
        if not p.is_file():
            raise ctx.fail("gait.reference_path", raw, f"does not exist (looked at {p})",
                           "an existing .csv, .sto or .mot file")
        id_path = None
        if "reference_id_path" in gait:
            raw_id = ctx.string("gait.reference_id_path", gait["reference_id_path"],
                                "a path to an OpenSim inverse-dynamics .sto file")
            id_path = Path(raw_id)
            if not id_path.is_absolute() and base_dir is not None:
                id_path = base_dir / id_path
            if p.suffix.lower() not in (".sto", ".mot") or not id_path.is_file():
                raise ctx.fail("gait.reference_id_path", raw_id,
                               "needs an OpenSim gait.reference_path and an existing file",
                               "an existing .sto beside an OpenSim .sto/.mot reference_path")
        grf_path = None
        if "reference_grf_path" in gait:
            raw_grf = ctx.string("gait.reference_grf_path", gait["reference_grf_path"],
                                 "a path to an OpenSim ground-reaction .mot file")
            grf_path = Path(raw_grf)
            if not grf_path.is_absolute() and base_dir is not None:
                grf_path = base_dir / grf_path
            if p.suffix.lower() not in (".sto", ".mot") or not grf_path.is_file():
                raise ctx.fail("gait.reference_grf_path", raw_grf,
                               "needs an OpenSim gait.reference_path and an existing file",
                               "an existing .mot beside an OpenSim .sto/.mot trial")
        from afo_mj.gait.reference import ReferenceGaitError
        try:
            _load_reference_file(p, walker.body_mass_kg, id_path, grf_path)
        except ReferenceGaitError as exc:
            raise ScenarioError(f"{origin}: gait.reference_path = {raw!r} cannot be used: "
                                f"{exc}") from None
        reference_path, reference, condition = p, "file", None
        reference_id_path = id_path
    else:
        reference_id_path = grf_path = None
        if "reference_grf_path" in gait:
            raise ctx.fail("gait.reference_grf_path", gait["reference_grf_path"],
                           "is given without gait.reference_path",
                           "a ground-reaction .mot beside an OpenSim gait.reference_path trial")
        if "reference_id_path" in gait:
            raise ctx.fail("gait.reference_id_path", gait["reference_id_path"],
                           "is given without gait.reference_path",
                           "an OpenSim ID file beside an OpenSim gait.reference_path")
        reference = ctx.string("gait.reference", gait.get("reference", GAIT.default("reference")),
                               " | ".join(repr(r) for r in REFERENCES))
        if reference not in REFERENCES:
            raise ctx.fail("gait.reference", reference, "is not a known reference",
                           " | ".join(repr(r) for r in REFERENCES))
        condition = ctx.string("gait.condition",
                               gait.get("condition", DEFAULT_CONDITION[reference]))
        if condition not in REFERENCES[reference]:
            raise ctx.fail("gait.condition", condition, f"is not a {reference} condition",
                           " | ".join(repr(c) for c in REFERENCES[reference]))
        if (reference, condition) in UNWALKABLE:
            from afo_mj.gait.reference import load_normative
            own = load_normative(reference, condition).cycle_time_s
            raise ScenarioError(
                f"{origin}: gait.reference = {reference!r}, gait.condition = {condition!r} "
                f"cannot be walked: {UNWALKABLE[(reference, condition)]}; allowed instead: "
                + _UNWALKABLE_INSTEAD.format(cad=round(120.0 / own, 1), cond=condition))
    cadence = None
    if "cadence_steps_per_min" in gait:
        cadence = ctx.number("gait.cadence_steps_per_min", gait["cadence_steps_per_min"],
                             *CADENCE_RANGE, "steps/min")
    strides = ctx.integer("gait.strides", gait.get("strides", GAIT.default("strides")),
                          *STRIDES_RANGE)
    raw_an = gait.get("analyse_strides", [min(4, strides), strides])
    notes = []
    bmi = walker.body_mass_kg / walker.height_m ** 2
    if not BMI_RANGE_KG_M2[0] <= bmi <= BMI_RANGE_KG_M2[1]:
        notes.append(f"walker: {walker.body_mass_kg:g} kg at {walker.height_m:g} m is a body mass "
                     f"index of {bmi:.1f} kg/m^2, outside the {BMI_RANGE_KG_M2[0]:g}-"
                     f"{BMI_RANGE_KG_M2[1]:g} kg/m^2 of the human bodies the segment model "
                     f"scales (de Leva's proportions by mass and stature): the walk runs, but "
                     f"its results are not a human's")
    if "gait.strides" in ov_keys and "gait.analyse_strides" not in ov_keys:
        followed = _follow_window(file_window, file_strides, strides)
        if followed is not None and followed != raw_an:
            notes.append(f"gait.analyse_strides = {raw_an} -> {followed} to follow "
                         f"--set gait.strides={strides} (set gait.analyse_strides to choose "
                         f"another window)")
            raw_an = followed
    allowed_an = f"[first, last] integers with 1 <= first <= last <= gait.strides ({strides})"
    if (not isinstance(raw_an, list) or len(raw_an) != 2
            or any(isinstance(x, bool) or not isinstance(x, int) for x in raw_an)):
        raise ctx.fail("gait.analyse_strides", raw_an, "has the wrong type or length", allowed_an)
    first, last = raw_an
    if not 1 <= first <= last <= strides:
        raise ctx.fail("gait.analyse_strides", raw_an, "is out of range", allowed_an)
    if first == 1:
        notes.append(f"gait.analyse_strides = {[first, last]} includes stride 1, the start-up "
                     "stride (the walker is launched from its start posture at "
                     "controller.initial_speed_m_s and settles over the first strides), so "
                     "the gait metrics mix in the start-up; for steady walking simulate "
                     "gait.strides >= 2 and analyse from stride 2 on (--strides N analyses "
                     "strides max(2, N-4)..N)")

    bands = []
    allowed_bands = "a list of 'source:condition' strings, e.g. ['schwartz2008:Free']"
    raw_bands = gait.get("band_references", list(GAIT.default("band_references")))
    if not isinstance(raw_bands, list):
        raise ctx.fail("gait.band_references", raw_bands, "has the wrong type", allowed_bands)
    for item in raw_bands:
        src, _, cond = str(item).partition(":")
        if not isinstance(item, str) or src not in REFERENCES or cond not in REFERENCES[src]:
            raise ctx.fail("gait.band_references", item, "is not a known reference condition",
                           allowed_bands)
        bands.append((src, cond))

    controller = _controller(ctx, ctx.table(doc, "controller"), model)
    out_tbl = ctx.table(doc, "output")
    ctx.unknown(OUTPUT, out_tbl)
    record = out_tbl.get("record", OUTPUT.default("record"))
    if not isinstance(record, bool):
        raise ctx.fail("output.record", record, "has the wrong type", "true | false")
    sig_hz, tf_hz = (ctx.number(f"output.{k}", out_tbl.get(k, OUTPUT.default(k)),
                                *OUTPUT[k].range, OUTPUT[k].unit)
                     for k in ("signal_rate_hz", "transform_rate_hz"))
    opensim = out_tbl.get("opensim", OUTPUT.default("opensim"))
    if not isinstance(opensim, bool):
        raise ctx.fail("output.opensim", opensim, "has the wrong type", "true | false")
    return WalkScenario(record=record, record_signal_rate_hz=sig_hz, opensim=opensim,
                        record_transform_rate_hz=tf_hz, band_references=tuple(bands),
                        reference_id_path=reference_id_path, reference_grf_path=grf_path,
                        name=name, description=description,
                        walker=walker,
                        reference=reference, condition=condition,
                        reference_path=reference_path, cadence_steps_per_min=cadence,
                        strides=strides, analyse_strides=(first, last),
                        controller=MappingProxyType(controller), source_path=source_path,
                        text=text, notes=tuple(notes),
                        walker_model=model, reflex_set=reflex_set,
                        device=MappingProxyType(ctx.table(doc, "device")),
                        assistance=MappingProxyType(ctx.table(doc, "assistance")),
                        circuit=MappingProxyType(ctx.table(doc, "circuit")))


def load_scenario(path, overrides=()) -> WalkScenario:
    """Read and validate a scenario TOML file; raises :class:`ScenarioError`."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{p}: cannot read the scenario file ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{p}: not UTF-8 text ({exc})") from None
    try:
        empty = not tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        empty = False                 # parse_scenario reports the syntax error
    if empty:
        raise ScenarioError(f"{p}: empty scenario (no keys); allowed: a scenario with at least "
                            f"a name or a [walker]/[gait] table, e.g. scenarios/walk_healthy.toml")
    return parse_scenario(text, origin=str(p), base_dir=p.parent, default_name=p.stem,
                          source_path=p, overrides=overrides)
