"""Export a circuit as an FMI 2.0 co-simulation FMU (``afo-mj export-fmu``).

The FMU is the circuit's own compiled step behind the FMI 2.0 C interface: a shim
(``fmu_shim.c``, compiled here with the machine's C compiler) forwards every FMI call to
:mod:`afo_mj.outputs.fmu_runtime` in the host's Python, which replays the circuit with
:meth:`~afo_mj.circuits.device.CircuitDevice.run_imposed` one communication step at a time.
So the importing host needs, besides an FMI 2.0 co-simulation master on Linux x86-64: the
Python the FMU was exported with (a Python host such as FMPy runs it in its own interpreter;
any other host loads the recorded ``libpython``, which must be a shared build), and the same
afo_mj version importable there (the resources record the exporter's ``sys.path``, tried when
``import afo_mj`` fails). The circuit is compiled with numba on the host's first use (cached).

Variables (all Real):

* inputs: ``command`` (the circuit controller's command: a torque demand, N·m, or for an
  ``open_loop`` controller the motor voltage, V), ``joint_angle`` (rad) and
  ``joint_angular_velocity`` (rad/s), held over each communication step, or ramped with
  the first derivatives a host gives (``canInterpolateInputs``);
* outputs: ``joint_torque`` (N·m, on the joint, +dorsiflexion), ``pressure.<node>`` (gauge
  pressure of every hydraulic node, Pa), ``speed.<node>`` (every shaft, rad/s),
  ``<component>.current`` (every motor current, A), with a battery ``battery_current`` (A)
  and ``battery_power`` (bus voltage times battery current, W: what the battery delivers),
  with a bus ``bus_voltage`` (V), and ``oil_temperature`` (K);
* parameters (``variability="fixed"``: set before initialisation): every numeric parameter
  of the description that reaches the kernel, named ``<component>.<dotted name>``,
  ``controller.*``, ``fluid.*``, ``thermal.*``, ``options.*``, with its unit, start value,
  bounds and meaning. A changed parameter rebuilds the circuit description (and its packed
  row) at ``fmi2ExitInitializationMode``; effect switches and structure are fixed at export.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import pickle
import platform
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import uuid
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from afo_mj.circuits.circuit import BUS, Circuit
from afo_mj.circuits.codegen import build
from afo_mj.hydraulics.params import Parameters

__all__ = ["FmuExportError", "FmuBuildError", "write_fmu", "fmu_variables", "unit_definition",
           "SHIM_SOURCE"]

SHIM_SOURCE = Path(__file__).with_name("fmu_shim.c")
#: the resources' bootstrap: imports the runtime, adding the exporter's sys.path when the
#: host's Python cannot import afo_mj
BOOTSTRAP = '''"""Finds afo_mj for an FMU written by afo-mj export-fmu (see afo_mj_fmu.json)."""
import json
import os
import sys

_HERE = os.path.dirname(os.path.abspath(__file__))


def runtime():
    try:
        import afo_mj.outputs.fmu_runtime as rt
        return rt
    except ImportError:
        pass
    with open(os.path.join(_HERE, "afo_mj_fmu.json")) as f:
        cfg = json.load(f)
    for p in cfg["host"]["sys_path"]:
        if p not in sys.path:
            sys.path.append(p)
    try:
        import afo_mj.outputs.fmu_runtime as rt
    except ImportError as exc:
        raise ImportError(f"this FMU needs afo_mj {cfg['afo_mj_version']} importable in "
                          f"the host's Python (exported with Python {cfg['host']['python']}, "
                          f"sys.path tried: {cfg['host']['sys_path']}): {exc}") from None
    return rt
'''


class FmuExportError(ValueError):
    """The circuit or an option cannot give an FMU (the message says which and why)."""


class FmuBuildError(FmuExportError):
    """This machine cannot build the FMU's library (no C compiler, a failed compile)."""


# ---- units ------------------------------------------------------------------------------
_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
#: symbol → (factor to SI, base-unit exponents)
_SYMBOLS = {
    "kg": (1.0, {"kg": 1}), "m": (1.0, {"m": 1}), "s": (1.0, {"s": 1}), "A": (1.0, {"A": 1}),
    "K": (1.0, {"K": 1}), "mol": (1.0, {"mol": 1}), "cd": (1.0, {"cd": 1}),
    "rad": (1.0, {"rad": 1}), "N": (1.0, {"kg": 1, "m": 1, "s": -2}),
    "Pa": (1.0, {"kg": 1, "m": -1, "s": -2}), "J": (1.0, {"kg": 1, "m": 2, "s": -2}),
    "W": (1.0, {"kg": 1, "m": 2, "s": -3}), "V": (1.0, {"kg": 1, "m": 2, "s": -3, "A": -1}),
    "ohm": (1.0, {"kg": 1, "m": 2, "s": -3, "A": -2}),
    "H": (1.0, {"kg": 1, "m": 2, "s": -2, "A": -2}), "Hz": (1.0, {"s": -1}),
    "h": (3600.0, {"s": 1}), "min": (60.0, {"s": 1}), "rev": (2.0 * math.pi, {"rad": 1}),
    "deg": (math.pi / 180.0, {"rad": 1}), "l": (1e-3, {"m": 3}),
}
_TOKEN = re.compile(r"\s*(?:(?P<sym>[A-Za-z]+)(?:\^(?P<exp>-?\d+))?|(?P<one>1)|(?P<op>[*/·.()])"
                    r"|(?P<space>\s))")


def unit_definition(unit: str):
    """``(factor, exponents)`` of a unit written as in the parameter sets (``N*m/rad``,
    ``m^3/(s Pa)``, ``V s/rad``: products by space, ``*``, ``·`` or ``.``, ``/`` dividing by
    the next factor or parenthesised group, integer powers ``^n``), or None when it is not a
    product of integer powers of known symbols (``sqrt(W)``, ``l_opt/s``): FMI base units
    take integer exponents only. ``-`` and ``1`` are dimensionless."""
    text = unit.strip()
    if text in ("-", "1", ""):
        return 1.0, {}
    pos = 0
    tokens = []
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            return None
        pos = m.end()
        if m.group("sym"):
            if m.group("sym") not in _SYMBOLS:
                return None
            tokens.append(("sym", m.group("sym"), int(m.group("exp") or 1)))
        elif m.group("one"):
            tokens.append(("sym", None, 1))
        elif m.group("op") in ("(", ")", "/"):
            tokens.append(("op", m.group("op"), 0))
    try:
        (factor, exps), rest = _product(tokens)
    except (IndexError, ValueError):
        return None
    if rest:
        return None
    return factor, {k: v for k, v in exps.items() if v}


def _factor(tokens):
    kind, val, exp = tokens[0]
    if kind == "sym":
        f, e = _SYMBOLS[val] if val else (1.0, {})
        return (f ** exp, {k: v * exp for k, v in e.items()}), tokens[1:]
    if val == "(":
        inner, rest = _product(tokens[1:])
        if not rest or rest[0][1] != ")":
            raise ValueError("unbalanced")
        return inner, rest[1:]
    raise ValueError(val)


def _product(tokens):
    (f, e), rest = _factor(tokens)
    e = dict(e)
    while rest and rest[0][1] != ")":
        div = rest[0][1] == "/"
        if div:
            rest = rest[1:]
        (g, d), rest = _factor(rest)
        s = -1 if div else 1
        f *= g ** s
        for k, v in d.items():
            e[k] = e.get(k, 0) + s * v
    return (f, e), rest


# ---- variables ----------------------------------------------------------------------------
def _leaves(obj: Parameters, prefix: str = ""):
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, Parameters):
            yield from _leaves(v, f"{prefix}{f.name}.")
        elif f.metadata.get("kind") == "number":
            yield f"{prefix}{f.name}", f.metadata, float(v)


def _parameters(circuit: Circuit, cc) -> list[dict]:
    """The FMU's parameters: every numeric field of the description that reaches the kernel
    (the code generator refuses a component or controller field it does not read, unless it
    is the component's metadata: a name, a mass)."""
    sets = [(c.name, c.params, set(c.metadata_fields)) for c in circuit.components]
    sets.append(("controller", circuit.controller.params, set()))
    # the fluid's specific heat and name reach no equation (codegen.generate)
    sets.append(("fluid", circuit.fluid, {"specific_heat_j_kg_k"}))
    sets.append(("thermal", circuit.thermal, set()))
    opts = {"supply_voltage_v"} if "circuit.supply_voltage" not in cc.param_labels else set()
    sets.append(("options", circuit.options, opts))
    out = []
    for owner, params, skip in sets:
        for name, md, value in _leaves(params):
            if name in skip:
                continue
            var = {"name": f"{owner}.{name}", "causality": "parameter", "start": value,
                   "unit": md.get("unit", "").strip() or "1",
                   "description": md.get("doc", "")}
            if math.isfinite(md.get("lo", -math.inf)):
                var["min"] = float(md["lo"])
            if math.isfinite(md.get("hi", math.inf)):
                var["max"] = float(md["hi"])
            out.append(var)
    return out


def _command_unit(circuit: Circuit) -> tuple[str, str]:
    kind = circuit.controller.kind
    if kind == "open_loop":
        return "V", "motor voltage (the open_loop controller passes it through)"
    return "N.m", (f"joint torque demand of the {kind} controller "
                   f"({type(circuit.controller).summary}), +dorsiflexion")


def fmu_variables(circuit: Circuit, cc) -> list[dict]:
    """Every variable of the FMU in value-reference order: the three inputs, the outputs
    (each with the replay-log ``signal`` it reads), then the parameters."""
    cu, cdoc = _command_unit(circuit)
    out = [{"name": "command", "causality": "input", "start": 0.0, "unit": cu,
            "description": cdoc},
           {"name": "joint_angle", "causality": "input", "start": 0.0, "unit": "rad",
            "description": "joint angle imposed over the step, +dorsiflexion"},
           {"name": "joint_angular_velocity", "causality": "input", "start": 0.0,
            "unit": "rad/s", "description": "joint angular velocity imposed over the step"}]

    def output(name, signal, unit, doc):
        out.append({"name": name, "causality": "output", "signal": signal, "unit": unit,
                    "description": doc})

    output("joint_torque", "torque_nm", "N.m", "torque the circuit applies to the joint at "
           "the step's end, +dorsiflexion")
    for label, kind in zip(cc.state_names, cc.state_kinds):
        if kind == "pressure":
            output(f"pressure.{label}", label, "Pa", f"gauge pressure of node {label}")
    for label, kind in zip(cc.state_names, cc.state_kinds):
        if kind == "speed":
            output(f"speed.{label}", label, "rad/s", f"angular speed of shaft {label}")
    for label in tuple(cc.state_names) + tuple(cc.probe_names):
        if label.endswith(".current_a"):
            comp = label[:-len(".current_a")]
            output(f"{comp}.current", label, "A", f"current of {comp}")
    if any(c.kind == "battery" for c in circuit.components):
        output("battery_current", "battery_current_a", "A", "current drawn from the "
               "battery")
        output("battery_power", "battery_power_w", "W", "power the battery delivers to "
               "the bus: bus voltage times battery current")
    if circuit.nodes_of_domain(BUS):
        output("bus_voltage", "bus_voltage_v", "V", "bus voltage (the battery's terminals "
               "or the ideal bench supply)")
    output("oil_temperature", "oil_temperature_k", "K", "oil temperature (lumped thermal "
           "model)")
    return out + _parameters(circuit, cc)


# ---- model description ----------------------------------------------------------------------
def _g(x: float) -> str:
    return repr(float(x))


def _model_description(name: str, model_id: str, guid: str, description: str,
                       variables: list[dict], step_size_s: float, version: str) -> bytes:
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": name, "guid": guid, "description": description,
        "generationTool": f"afo_mj {version} (afo-mj export-fmu)",
        "variableNamingConvention": "structured", "numberOfEventIndicators": "0"})
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": model_id, "needsExecutionTool": "true",
        "canHandleVariableCommunicationStepSize": "true",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true", "canGetAndSetFMUstate": "false",
        "canSerializeFMUstate": "false", "providesDirectionalDerivative": "false",
        "canInterpolateInputs": "true", "maxOutputDerivativeOrder": "0"})
    units = ET.SubElement(root, "UnitDefinitions")
    for u in sorted({v["unit"] for v in variables}):
        el = ET.SubElement(units, "Unit", {"name": u})
        d = unit_definition(u)
        if d is not None:
            factor, exps = d
            attrs = {k: str(exps[k]) for k in _BASE if exps.get(k)}
            if factor != 1.0:
                attrs["factor"] = _g(factor)
            ET.SubElement(el, "BaseUnit", attrs)
    cats = ET.SubElement(root, "LogCategories")
    for c, doc in (("logStatusError", "errors"), ("logStatusWarning", "warnings")):
        ET.SubElement(cats, "Category", {"name": c, "description": doc})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stepSize": _g(step_size_s)})
    mv = ET.SubElement(root, "ModelVariables")
    outputs = []
    for i, v in enumerate(variables):
        attrs = {"name": v["name"], "valueReference": str(i), "causality": v["causality"],
                 "description": v["description"]}
        real = {"unit": v["unit"]}
        if v["causality"] == "parameter":
            attrs.update(variability="fixed", initial="exact")
            real["start"] = _g(v["start"])
            for k in ("min", "max"):
                if k in v:
                    real[k] = _g(v[k])
        elif v["causality"] == "input":
            attrs["variability"] = "continuous"
            real["start"] = _g(v["start"])
        else:
            attrs.update(variability="continuous", initial="calculated")
            outputs.append(i + 1)
        sv = ET.SubElement(mv, "ScalarVariable", attrs)
        ET.SubElement(sv, "Real", real)
    ms = ET.SubElement(root, "ModelStructure")
    for tag in ("Outputs", "InitialUnknowns"):
        el = ET.SubElement(ms, tag)
        for idx in outputs:
            ET.SubElement(el, "Unknown", {"index": str(idx)})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


# ---- the binary ------------------------------------------------------------------------------
def libpython_path() -> str:
    """The shared Python library a non-Python host loads ("" for a static build)."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        return ""
    name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY")
    return str(Path(sysconfig.get_config_var("LIBDIR")) / name)


def compile_shim(out: Path, libpython: str) -> None:
    """Compile the shim into the shared library ``out`` (gcc or cc)."""
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    if not cc:
        raise FmuBuildError("no C compiler found (gcc or cc on PATH, or $CC): export-fmu "
                             "compiles the FMU's FMI 2.0 library; install gcc")
    cmd = [cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-std=c99",
           f"-DAFO_MJ_LIBPYTHON={json.dumps(libpython or 'libpython3.so')}",
           str(SHIM_SOURCE), "-o", str(out), "-ldl"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise FmuBuildError(f"compiling the FMU library failed ({' '.join(cmd)}): "
                             f"{res.stderr.strip()[-2000:]}")


def _model_identifier(name: str) -> str:
    ident = re.sub(r"\W", "_", name)
    return "afo_mj_" + ident


def write_fmu(circuit: Circuit, path, *, initial_state: dict | None = None,
              timestep_s: float = 5e-4, step_size_s: float = 1e-3,
              description: str = "") -> dict:
    """Write ``circuit`` as an FMI 2.0 co-simulation FMU at ``path`` (``.fmu``, written
    whole or not at all). ``initial_state``: state label → value at t = 0 (else the
    circuit's); ``timestep_s``: the longest internal step (each communication step is split
    into equal sub-steps no longer than it); ``step_size_s``: the default experiment's
    communication step. Returns ``{path, model_identifier, guid, variables, kernel}``."""
    import afo_mj
    path = Path(path)
    if path.suffix != ".fmu":
        raise FmuExportError(f"--out = {str(path)!r}; allowed: a file name ending in .fmu")
    if not path.parent.is_dir():
        raise FmuExportError(f"--out = {str(path)!r}: folder {str(path.parent)!r} does not "
                             "exist")
    if sys.platform != "linux" or platform.machine() not in ("x86_64", "AMD64"):
        raise FmuExportError(f"export-fmu builds the linux64 binary; this machine is "
                             f"{sys.platform}/{platform.machine()}; allowed: Linux x86-64")
    for key, v in (("timestep_s", timestep_s), ("step_size_s", step_size_s)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= 1.0):
            raise FmuExportError(f"{key} = {v!r}; allowed: 0 < {key} <= 1 s")
    cc = build(circuit)
    init = {k: float(v) for k, v in (initial_state or {}).items()}
    bad = [k for k in init if k not in cc.state_names]
    if bad:
        raise FmuExportError(f"initial_state[{bad[0]!r}]; allowed: {', '.join(cc.state_names)}")
    variables = fmu_variables(circuit, cc)
    names = [v["name"] for v in variables]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FmuExportError(f"circuit {circuit.name!r}: FMU variable {dup[0]!r} twice")
    blob = pickle.dumps(circuit, protocol=4)
    kernel = cc.source_path.stem
    digest = hashlib.sha256(blob + kernel.encode() + json.dumps(
        [variables, init, timestep_s, step_size_s], sort_keys=True).encode()).hexdigest()
    guid = "{" + str(uuid.UUID(digest[:32])) + "}"
    model_id = _model_identifier(circuit.name)
    libpython = libpython_path()
    cfg = {"format": 1, "guid": guid, "afo_mj_version": afo_mj.__version__,
           "circuit": circuit.name, "kernel": kernel, "timestep_s": float(timestep_s),
           "initial_state": init, "variables": variables,
           "host": {"python": sys.version.split()[0], "libpython": libpython,
                    "sys_path": [p for p in sys.path if p and Path(p).is_dir()]}}
    desc = description or (f"afo_mj circuit {circuit.name!r} ({circuit.controller.kind} "
                           "controller) with the joint motion imposed")
    xml = _model_description(circuit.name, model_id, guid, desc, variables, step_size_s,
                             afo_mj.__version__)
    with tempfile.TemporaryDirectory() as tmp:
        so = Path(tmp) / f"{model_id}.so"
        compile_shim(so, libpython)
        part = path.with_name(f".{path.name}.part")
        try:
            with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
                z.writestr("modelDescription.xml", xml)
                z.write(so, f"binaries/linux64/{model_id}.so")
                z.writestr("resources/afo_mj_fmu.json", json.dumps(cfg, indent=1))
                z.writestr("resources/circuit.pickle", blob)
                z.writestr("resources/afo_mj_fmu_bootstrap.py", BOOTSTRAP)
            os.replace(part, path)
        finally:
            if part.exists():
                part.unlink()
    return {"path": path, "model_identifier": model_id, "guid": guid, "kernel": kernel,
            "variables": variables, "libpython": libpython}
