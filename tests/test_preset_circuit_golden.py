"""Issue 40's golden guard: every shipped device circuit generates today's module.

``tests/golden/preset_circuit_hashes.json`` (written by ``tools/preset_circuit_hashes.py
--write``; its docstring lists what is covered and what each hash is) holds, for every preset,
library circuit and scenario circuit in the modes the tools build it in, the SHA-256 of the
generated module source, of the circuit's own emitted part, and of its packed parameter row.
The refactors of issue 40 must keep them all: then every preset's gait, bench and ledger
figures are bitwise today's. The modules are generated, not compiled (about 3 s for all).

When a change of the emitted code is intended, rerun ``tools/preset_circuit_hashes.py
--write`` and say in the commit which circuits moved and why.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _tool():
    name = "preset_circuit_hashes"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]


GOLDEN = _tool().load_golden()


@pytest.fixture(scope="module")
def now():
    return _tool().compute()


def test_golden_covers_every_shipped_circuit(now):
    """The golden file names exactly the circuits generated today: a preset, library circuit
    or scenario added or dropped is listed (and must be recorded with ``--write``)."""
    missing = sorted(set(now["circuits"]) - set(GOLDEN["circuits"]))
    stale = sorted(set(GOLDEN["circuits"]) - set(now["circuits"]))
    assert not missing and not stale, (f"generated but not in the golden file: {missing}; "
                                       f"in the golden file but not generated: {stale}")
    kinds = {k.split("|")[0].split(":")[0] for k in now["circuits"]}
    assert kinds == {"preset", "library", "scenario"}


def test_shared_module_parts_unchanged(now):
    """The stepper template and the digest of the laws the modules call are today's (a change
    there changes every module: the per-circuit tests then compare only their own parts)."""
    assert now["shared"] == GOLDEN["shared"], _tool().differences(GOLDEN, now)


@pytest.mark.parametrize("key", list(GOLDEN["circuits"]))
def test_circuit_module_unchanged(now, key):
    """The circuit's emitted code, its packed parameter labels and values and its initial
    conditions are today's; with the shared parts unchanged, its whole module is byte-identical
    (same hash, the same cached kernel)."""
    if key not in now["circuits"]:
        pytest.fail(f"{key}: no longer generated")
    g, n = GOLDEN["circuits"][key], now["circuits"][key]
    changed = [f for f in g if f != "module_sha256" and g[f] != n.get(f)]
    assert not changed, (f"{key}: {', '.join(changed)} changed (rerun tools/"
                         "preset_circuit_hashes.py --check to list every circuit that moved)")
    if now["shared"] == GOLDEN["shared"]:
        assert n["module_sha256"] == g["module_sha256"]


def test_hash_is_the_cached_kernel_build_imports(tmp_path, monkeypatch):
    """The recorded module hash and parameter row are those of what
    :func:`~afo_mj.circuits.codegen.build` writes and imports (the kernel that runs): its file
    is named by the first 20 digits of the hash, and its text and ``P`` give the recorded
    hashes (build imports the module; numba compiles lazily, so nothing is compiled here)."""
    from afo_mj.circuits.codegen import build
    from afo_mj.devices.hafo import HAFO, hafo_circuit
    monkeypatch.setenv("AFO_MJ_CACHE_DIR", str(tmp_path))
    cc = build(hafo_circuit(HAFO, mode="torque"))
    rec = GOLDEN["circuits"]["preset:hafo|pump_torque"]
    text = cc.source_path.read_bytes()
    assert cc.source_path.name == f"circuit_{hashlib.sha256(text).hexdigest()[:20]}.py"
    assert hashlib.sha256(text).hexdigest() == rec["module_sha256"]
    assert (hashlib.sha256(np.asarray(cc.P, dtype="<f8").tobytes()).hexdigest()
            == rec["param_values_sha256"])
    assert (hashlib.sha256("\n".join(cc.param_labels).encode()).hexdigest()
            == rec["param_labels_sha256"])


def test_guard_sees_one_character_of_emitted_code(monkeypatch):
    """A one-character change of one emitted line of the HAFO's controller (``err * h`` →
    ``err*h``, the same arithmetic) changes the preset's emitted and module hashes and
    nothing else: the guard catches an edit of the code a preset generates."""
    from afo_mj.circuits.codegen import Emitter
    from afo_mj.devices.hafo import HAFO, hafo_circuit
    tool = _tool()
    rec = GOLDEN["circuits"]["preset:hafo|pump_torque"]
    orig = Emitter.ctrl_line
    monkeypatch.setattr(Emitter, "ctrl_line",
                        lambda self, code: orig(self, code.replace("err * h", "err*h")))
    edited, shared = tool.fingerprint(hafo_circuit(HAFO, mode="torque"))
    assert shared == GOLDEN["shared"]
    assert edited["emitted_sha256"] != rec["emitted_sha256"]
    assert edited["module_sha256"] != rec["module_sha256"]
    same = ("param_labels_sha256", "param_values_sha256", "n_params", "initial_sha256")
    assert {f: edited[f] for f in same} == {f: rec[f] for f in same}


def test_guard_sees_a_moved_parameter_value():
    """A preset value moved by one part in 10¹⁵ changes the packed row's hash alone."""
    from afo_mj.devices.hafo import HAFO, hafo_circuit
    rec = GOLDEN["circuits"]["preset:hafo|pump_torque"]
    p = HAFO.replace(pulley_radius_m=HAFO.pulley_radius_m * (1 + 1e-15))
    moved, _ = _tool().fingerprint(hafo_circuit(p, mode="torque"))
    assert moved["param_values_sha256"] != rec["param_values_sha256"]
    assert moved["emitted_sha256"] == rec["emitted_sha256"]
