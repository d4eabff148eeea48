"""Fingerprints of every shipped device circuit's generated module (issue 40's golden guard).

Issue 40 reshapes the device code (presets as circuit descriptions, one device class, tools by
roles); its acceptance asks that each preset's generated circuit module stay byte-identical,
so that every preset's gait, bench and ledger figures stay bitwise today's. This tool records,
for every circuit the shipped devices and scenarios step, what
:func:`afo_mj.circuits.codegen.generate` produces — the module source text and the packed
parameter row — *without* compiling it (generation takes ~30 ms a circuit; numba's first
compile of a module ~14 s), in ``tests/golden/preset_circuit_hashes.json``, which
``tests/test_preset_circuit_golden.py`` compares against.

The circuits (each under a key ``<source>|<controller kind>``):

* ``preset:<name>`` — every HAFO preset (:data:`afo_mj.devices.hafo.PRESETS`,
  :func:`~afo_mj.devices.hafo.hafo_circuit`) and every valve preset
  (:data:`afo_mj.devices.valve_afo.VALVE_PRESETS`, :func:`~afo_mj.devices.valve_afo.
  valve_circuit`). The ideal device (:mod:`afo_mj.devices.ideal`) has no circuit.
* ``library:<name>`` — every shipped description (:data:`afo_mj.circuits.library.LIBRARY`).
* ``scenario:<path>`` (and ``scenario:<path>#<variant>``) — the circuit of every shipped
  scenario under ``scenarios/`` that wears one: a ``[device]`` preset with its
  ``device.params`` overrides (and each ``[device.variants.<name>]``, as
  :func:`afo_mj.scenarios.device_scenario.device_config` merges them), or a ``[circuit]``
  table (:func:`afo_mj.scenarios.circuit_scenario.circuit_spec`). Scenarios that wear the ideal
  device or nothing have none.

Each in the modes the tools build it in: its own torque controller (device walks, the
environment, bench replay, calibration; ``pump_torque``, ``servo_valve_torque``, …) and
``open_loop``, the command being the motor voltage (the HAFO bench's ``HafoDevice(mode=
"voltage")`` = ``hafo_circuit(p, mode="voltage")``; the circuit bench's
``with_controller(circuit, OpenLoop())`` for a described pump-controlled circuit). A circuit
whose own controller is already ``open_loop`` has the one mode, and so has a valve circuit:
its valves' inputs need a valve controller, and its open-loop bench
(``ValveAfoDevice(mode="valve_command")``) steps the same module with one packed switch set.

What is recorded per circuit:

* ``module_sha256`` — SHA-256 of the whole module text, the hash whose first 20 digits name
  the cached module ``circuit_<digest>.py`` that :func:`~afo_mj.circuits.codegen.build`
  imports (so the same hash is the same kernel that runs).
* ``emitted_sha256`` — SHA-256 of the circuit's own part of that text: everything before the
  stepper template that every module shares, with the comment line that carries the digest of
  the laws the module calls (``# compiled against … <digest>``) normalised to
  ``<dependency digest>``. A change here is this circuit's emitted code.
* ``param_labels_sha256`` / ``param_values_sha256`` / ``n_params`` — the packed parameter row
  ``P`` (labels joined by newlines; values as little-endian float64 bytes): values live in the
  row, never in the code, so a moved parameter value shows here alone.
* ``initial_sha256`` — the initial conditions the module does not hold: the circuit's
  ``options.initial_pressure_pa`` and the emitter's work-vector initial values.

and once for all (``shared``): the dependency digest (laws, assistance, impedance, buffer
views: :func:`afo_mj.circuits.codegen._dependency_digest`) and the SHA-256 of the stepper
template tail, which are the same in every module (the tool checks that they are). Nothing
hashed holds a path, a time or a process-dependent order (checked across ``PYTHONHASHSEED``).

Usage::

    .venv/bin/python tools/preset_circuit_hashes.py --check   # exit 1 naming what changed
    .venv/bin/python tools/preset_circuit_hashes.py --write   # rewrite the golden file
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

GOLDEN = ROOT / "tests" / "golden" / "preset_circuit_hashes.json"
SCENARIOS = ROOT / "scenarios"
FORMAT = "afo_mj preset circuit hashes v1"
#: the comment line of a generated module that carries the laws' digest
DIGEST_PREFIX = "# compiled against laws/assistance/impedance/buffer_views "


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _with_open_loop(circuit):
    from afo_mj.circuits.controllers import OpenLoop
    from afo_mj.scenarios.circuit_scenario import with_controller
    return with_controller(circuit, OpenLoop())


def _preset_modes(params) -> list:
    """The circuits of a preset's parameters, in the modes the tools build them in."""
    from afo_mj.devices.hafo import hafo_circuit
    from afo_mj.devices.valve_afo import ValveAnkleParams, valve_circuit
    if isinstance(params, ValveAnkleParams):
        return [valve_circuit(params)]
    return [hafo_circuit(params, mode="torque"), hafo_circuit(params, mode="voltage")]


def _description_modes(circuit) -> list:
    if circuit.controller.kind != "pump_torque":
        return [circuit]
    return [circuit, _with_open_loop(circuit)]


def _scenario_sources() -> list:
    """``(source key, [circuit, ...])`` for every shipped scenario that wears a circuit."""
    from afo_mj.circuits.circuit import Circuit
    from afo_mj.devices.ideal import PRESETS as IDEAL_PRESETS
    from afo_mj.scenarios.circuit_scenario import circuit_spec
    from afo_mj.scenarios.device_scenario import device_params
    out = []
    for path in sorted(SCENARIOS.rglob("*.toml")):
        rel = path.relative_to(SCENARIOS).as_posix()
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
        dev, circ = doc.get("device") or {}, doc.get("circuit") or {}
        if circ:
            spec = circuit_spec(circ, rel)
            out.append((f"scenario:{rel}", _description_modes(Circuit.from_dict(spec))))
            continue
        if not dev or dev.get("preset", "hafo") in IDEAL_PRESETS:
            continue
        preset, params, overrides = device_params(dev, rel)
        out.append((f"scenario:{rel}", _preset_modes(params)))
        for vname, vover in (dev.get("variants") or {}).items():
            _, vparams, _ = device_params({"preset": preset, "params": {**overrides, **vover}},
                                          f"{rel}: device.variants.{vname}")
            out.append((f"scenario:{rel}#{vname}", _preset_modes(vparams)))
    return out


def circuit_sources() -> dict:
    """Every fingerprinted circuit by key ``<source>|<controller kind>``, in a fixed order."""
    from afo_mj.circuits.library import LIBRARY
    from afo_mj.devices.hafo import PRESETS
    from afo_mj.devices.valve_afo import VALVE_PRESETS
    sources = [(f"preset:{n}", _preset_modes(p)) for n, p in {**PRESETS, **VALVE_PRESETS}.items()]
    sources += [(f"library:{n}", _description_modes(build())) for n, build in LIBRARY.items()]
    sources += _scenario_sources()
    out = {}
    for source, circuits in sources:
        for c in circuits:
            key = f"{source}|{c.controller.kind}"
            if key in out:
                raise ValueError(f"two circuits under one key {key!r}")
            out[key] = c
    return out


def split_module(text: str) -> tuple[str, str, str]:
    """``(circuit part normalised, dependency digest, template tail)`` of a module's text."""
    from afo_mj.circuits import stepper
    at = text.index(f"\ndef {stepper.TEMPLATE[0].__name__}(")
    cut = text.rindex("\n\n\n", 0, at)
    head, tail = text[:cut], text[cut:]
    lines = head.split("\n")
    digest_lines = [i for i, ln in enumerate(lines) if ln.startswith(DIGEST_PREFIX)]
    if len(digest_lines) != 1:
        raise ValueError(f"generated module: {len(digest_lines)} lines start with "
                         f"{DIGEST_PREFIX!r}; expected 1")
    i = digest_lines[0]
    digest = lines[i][len(DIGEST_PREFIX):]
    lines[i] = DIGEST_PREFIX + "<dependency digest>"
    return "\n".join(lines), digest, tail


def fingerprint(circuit) -> tuple[dict, dict]:
    """``(per-circuit record, shared parts)`` of a circuit's generated module (not compiled)."""
    from afo_mj.circuits.codegen import generate
    text, g, _ = generate(circuit)
    head, digest, tail = split_module(text)
    labels = list(g.P_labels)
    values = np.asarray(g.P, dtype="<f8")
    init = repr((float(circuit.options.initial_pressure_pa),
                 sorted((str(k), float(v)) for k, v in g.work_init.items())))
    rec = {"module_sha256": _sha(text.encode()),
           "emitted_sha256": _sha(head.encode()),
           "param_labels_sha256": _sha("\n".join(labels).encode()),
           "param_values_sha256": _sha(values.tobytes()),
           "n_params": len(labels),
           "initial_sha256": _sha(init.encode())}
    return rec, {"dependency_digest": digest, "template_sha256": _sha(tail.encode())}


def compute() -> dict:
    """The golden document for the present code."""
    circuits, shared = {}, None
    for key, c in circuit_sources().items():
        rec, sh = fingerprint(c)
        if shared is None:
            shared = sh
        elif sh != shared:
            raise ValueError(f"{key}: the shared parts of its module differ from the first "
                             f"circuit's ({sh} against {shared})")
        circuits[key] = rec
    return {"format": FORMAT, "generator": "tools/preset_circuit_hashes.py",
            "shared": shared, "circuits": circuits}


def load_golden(path: Path = GOLDEN) -> dict:
    doc = json.loads(path.read_text(encoding="utf-8"))
    if doc.get("format") != FORMAT:
        raise ValueError(f"{path}: format = {doc.get('format')!r}; allowed: {FORMAT!r}")
    return doc


def differences(golden: dict, now: dict) -> list[str]:
    """One line per difference between two golden documents (empty: identical)."""
    out = []
    for k in sorted(set(golden["shared"]) | set(now["shared"])):
        if golden["shared"].get(k) != now["shared"].get(k):
            out.append(f"shared.{k}: {golden['shared'].get(k)} -> {now['shared'].get(k)} "
                       "(every module changes)")
    g, n = golden["circuits"], now["circuits"]
    out += [f"{k}: in the golden file, no longer generated" for k in g if k not in n]
    out += [f"{k}: generated, not in the golden file" for k in n if k not in g]
    for k in g:
        if k in n:
            out += [f"{k}: {f} {g[k][f]} -> {n[k].get(f)}" for f in g[k] if g[k][f] != n[k].get(f)]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="compare with the golden file")
    mode.add_argument("--write", action="store_true", help="rewrite the golden file")
    args = ap.parse_args(argv)
    now = compute()
    if args.write:
        GOLDEN.parent.mkdir(parents=True, exist_ok=True)
        GOLDEN.write_text(json.dumps(now, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {GOLDEN.relative_to(ROOT)}: {len(now['circuits'])} circuits")
        return 0
    diff = differences(load_golden(), now)
    for line in diff:
        print(line)
    print(f"{len(now['circuits'])} circuits: "
          + ("identical to the golden file" if not diff else f"{len(diff)} differences"))
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
