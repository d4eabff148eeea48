"""The device a command names: a registered device, or the device a scenario file wears.

Commands that act on a device rather than on a walk (``afo-mj schematic``,
``afo-mj export-fmu``) take a *source*: the name of a registered device
(:mod:`afo_mj.devices.registry`: a preset, an alias or a library circuit), or a walking or
bench scenario file whose ``[circuit]`` description or ``[device]`` preset (with its
``params`` overrides and ``--set`` overrides) is the device. :func:`device_source` turns either
into the device's :class:`~afo_mj.circuits.device_spec.DeviceSpec`, so those commands read the
spec and never switch on which family of device they were given.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from afo_mj.circuits.device_spec import DeviceSpec
from afo_mj.hydraulics.params import ParameterError
from afo_mj.scenarios.schema import Key, ScenarioError, Table, check_table

__all__ = ["device_source", "preset_overrides"]


def preset_overrides(overrides: Sequence[str], name: str) -> dict:
    """``--set device.params.NAME=VALUE`` items as a preset's dotted overrides (the value a
    number where it reads as one); anything else refused naming the item."""
    out = {}
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep or not key.startswith("device.params."):
            raise ScenarioError(f"--set {item!r} with the device {name!r}; allowed: "
                                "device.params.NAME=VALUE")
        try:
            out[key[len("device.params."):]] = float(value)
        except ValueError:
            out[key[len("device.params."):]] = value
    return out


#: the top level of a calibration rig file (``afo-mj calibrate --scenario``): a described
#: circuit with its load, sensors and calibration options (those three tables are declared
#: and checked by afo_mj.calibration.calibration_setup)
RIG = Table("", (
    Key("name", "string"),
    Key("description", "string"),
    Key("circuit", "table", doc="the rig's circuit (afo_mj.scenarios.circuit_scenario)"),
    Key("load", "table", doc="the load the joint drives"),
    Key("sensors", "table", doc="the measured signals"),
    Key("calibration", "table", doc="calibration options")),
    note="(a calibration rig file)")


def _rig_circuit(text: str, src: str, overrides: Sequence[str]):
    """The ``[circuit]`` of a calibration rig file (one with ``[load]``, ``[sensors]`` or
    ``[calibration]`` beside it), or None for any other document."""
    import tomllib

    from afo_mj.circuits.circuit import Circuit
    from afo_mj.scenarios.circuit_scenario import circuit_spec
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{src}: not valid TOML ({exc})") from None
    if "circuit" not in doc or not any(k in doc for k in ("load", "sensors", "calibration")):
        return None
    check_table(doc, RIG, src)
    if overrides:
        raise ScenarioError(f"--set {list(overrides)!r} with the rig file {src}; allowed: "
                            "none (edit its [circuit])")
    return Circuit.from_dict(circuit_spec(doc["circuit"], src))


def device_source(source: str, overrides: Sequence[str] = ()) -> tuple[DeviceSpec, str]:
    """``(spec, origin)`` of ``source`` (module docstring): a file path is read as a scenario
    (bench or walk); any other string as a registered device name. Raises
    :class:`~afo_mj.scenarios.walk_scenario.ScenarioError` naming what is wrong (no such file
    or device, a scenario that wears no circuit, the ideal source)."""
    from afo_mj.devices.registry import device_entry, device_names, device_spec
    src = str(source)
    path = Path(src)
    if not path.is_file():
        try:
            entry = device_entry(src, key="SOURCE")
        except ParameterError as exc:
            raise ScenarioError(f"{exc} (or a scenario file: {src!r} is no file)") from None
        ov = preset_overrides(overrides, src) if entry.from_params is not None else None
        if entry.from_params is None and overrides:
            raise ScenarioError(f"--set {list(overrides)!r} with the library circuit "
                                f"{src!r}; allowed: none (write a [circuit] scenario with "
                                "library = and its overrides)")
        try:
            return device_spec(src, ov, key="SOURCE"), src
        except ParameterError as exc:
            raise ScenarioError(f"{src}: {exc}") from None
    from afo_mj.scenarios.bench_scenario import is_bench_document, load_bench_scenario
    from afo_mj.scenarios.device_scenario import device_config
    from afo_mj.scenarios.walk_scenario import load_scenario
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{src}: cannot read it ({exc})") from None
    circuits = ", ".join(device_names())
    rig = _rig_circuit(text, src, overrides)
    if rig is not None:
        return DeviceSpec.from_circuit(rig), str(path)
    if is_bench_document(text):
        return load_bench_scenario(path, overrides=overrides).spec, str(path)
    cfg = device_config(load_scenario(path, overrides=overrides))
    if cfg is None:
        raise ScenarioError(f"{src}: the scenario wears no device (no [circuit] and no "
                            f"[device]); allowed: a scenario with a [circuit] description or "
                            f"a [device] preset, or a device name ({circuits})")
    spec = cfg.device_spec()
    if spec is None:
        raise ScenarioError(f"{src}: device.preset = {cfg.preset!r} is not a circuit (it "
                            f"delivers its command ideally); allowed: a circuit device "
                            f"({circuits}) or a [circuit] description")
    return spec, str(path)
