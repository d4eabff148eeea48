"""The stepper template's globals are declared (issue 40 item 5): ``afo_mj/circuits/stepper.py``
is linted for undefined names (no F821 exemption), and the declarations in
:mod:`afo_mj.circuits.stepper_globals` match what a generated module defines: the fixed
headers' values equal the generator's tables, and every declared name is a global of a real
generated module (the HAFO's)."""

from __future__ import annotations

import ast
from pathlib import Path

from afo_mj.circuits import codegen, stepper_globals
from afo_mj.devices.registry import device_spec

ROOT = Path(__file__).resolve().parents[1]


def _declared() -> set[str]:
    tree = ast.parse((ROOT / "afo_mj" / "circuits" / "stepper_globals.py").read_text())
    out = set()
    for node in tree.body:
        if isinstance(node, ast.AnnAssign):
            out.add(node.target.id)
        elif isinstance(node, ast.FunctionDef):
            out.add(node.name)
    return out


def test_fixed_headers_equal_the_generators_tables():
    for i, n in enumerate(codegen.W_HEADER):
        assert getattr(stepper_globals, f"W_{n}") == i, n
    for i, n in enumerate(codegen.U_NAMES):
        assert getattr(stepper_globals, f"U_{n}") == i, n
    for i, n in enumerate(codegen.F_HEADER):
        assert getattr(stepper_globals, f"F_{n}") == i, n
    assert stepper_globals.N_U_HEAD == len(codegen.U_NAMES)


def test_every_declared_name_is_a_global_of_a_generated_module():
    text, _g, _layout = codegen.generate(device_spec("hafo").circuit)
    tree = ast.parse(text)
    defined = set()
    for node in tree.body:
        if isinstance(node, ast.Assign):
            defined |= {t.id for t in node.targets if isinstance(t, ast.Name)}
        elif isinstance(node, ast.FunctionDef):
            defined.add(node.name)
    missing = sorted(_declared() - defined)
    assert not missing, f"declared but not generated: {missing}"


def test_the_template_is_linted_for_undefined_names():
    import tomllib
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    ignores = cfg["tool"]["ruff"]["lint"].get("per-file-ignores", {})
    assert "afo_mj/circuits/stepper.py" not in ignores
