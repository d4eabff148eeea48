"""Finite-difference Jacobian columns that re-evaluate only what a perturbation changes.

The coupled stepper (:mod:`afo_mj.circuits.stepper`) differentiates a circuit's right-hand
side by forward differences: one evaluation per state for ``∂f/∂y`` and one more for the joint
velocity column ``∂f/∂θ̇`` every step. A full evaluation recomputes every component, but
perturbing one state changes only the lines that read it, directly or through another line:
the motor current reaches the shaft and the winding, not the hoses, the valves or the oil's
compliance of the other nodes. This module turns a circuit's straight-line right-hand side
(the ``rhs_step`` body :mod:`afo_mj.circuits.codegen` writes: simple assignments to locals,
``dy[k]`` and ``F[…]``) into one function, ``rhs_columns``, that

* evaluates the lines that ``dy`` and the joint torque ``F[F_TAU]`` depend on (the base point:
  the power flows, probes and monitors are left out) into ``dy`` and ``F[F_TAU]``;
* with ``cols`` non-zero, for each state ``j`` re-evaluates, with ``y[j] + D[j]``, only the
  lines that depend on ``y[j]`` (into renamed locals) and writes the perturbed ``dy`` and
  torque into row ``j`` of ``C`` (``C[j, N_Y]`` the torque);
* with ``thcol`` non-zero, does the same for the joint angle and velocity moved to
  ``(th2, thd2)`` into ``T`` (``T[N_Y]`` the torque).

Every value is computed by the same expression, in the same order, on the same operands as a
full evaluation at the perturbed point would compute it; the lines not re-evaluated would
give the base values again. So the columns are bitwise equal to full evaluations (the tests
compare them with ``rhs_step`` at the perturbed points) at a fraction of the cost: this is the
sparsity-exploiting finite difference of Curtis, Powell & Reid (1974, IMA J. Appl. Math.
13:117), here at the level of the expressions rather than of the Jacobian's columns.
"""

from __future__ import annotations

import ast

#: arrays of the right-hand side whose constant-index elements are tracked one by one
_TRACKED_ARRAYS = ("y", "yo", "dy", "F")
#: the output the columns carry besides ``dy``
_TORQUE = "F[F_TAU]"


class ColumnCodeError(ValueError):
    """The right-hand side is not the straight-line code this module can split."""


def _key(node) -> str | None:
    """The dependency key of an assignment target or operand: a local's name, or
    ``'y[3]'``-style for an element of a tracked array; None for anything else."""
    if isinstance(node, ast.Name):
        return node.id
    if (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name)
            and node.value.id in _TRACKED_ARRAYS):
        return f"{node.value.id}[{ast.unparse(node.slice)}]"
    return None


def _reads(expr) -> set:
    """Keys an expression reads (locals and tracked array elements)."""
    out = set()
    for node in ast.walk(expr):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load):
            out.add(node.id)
        elif isinstance(node, ast.Subscript):
            k = _key(node)
            if k is not None:
                out.add(k)
    return out


class _Rename(ast.NodeTransformer):
    """Replace the operands listed in ``names`` (by key) with their renamed locals."""

    def __init__(self, names: dict):
        self.names = names

    def visit_Name(self, node):
        if isinstance(node.ctx, ast.Load) and node.id in self.names:
            return ast.copy_location(ast.Name(self.names[node.id], ast.Load()), node)
        return node

    def visit_Subscript(self, node):
        k = _key(node)
        if k is not None and k in self.names and isinstance(node.ctx, ast.Load):
            return ast.copy_location(ast.Name(self.names[k], ast.Load()), node)
        return self.generic_visit(node)


def _parse(body: list[str]) -> list[tuple[str, set, ast.expr]]:
    """``(target key, read keys, value)`` of every line; raises :class:`ColumnCodeError`
    unless every line is one assignment to a local or a tracked array element and no
    target is assigned twice."""
    out, seen = [], set()
    for line in body:
        tree = ast.parse(line)
        if (len(tree.body) != 1 or not isinstance(tree.body[0], ast.Assign)
                or len(tree.body[0].targets) != 1):
            raise ColumnCodeError(f"not a single assignment: {line!r}")
        st = tree.body[0]
        tk = _key(st.targets[0])
        if tk is None:
            raise ColumnCodeError(f"assignment to an untracked target: {line!r}")
        if tk in seen:
            raise ColumnCodeError(f"{tk} is assigned twice")
        seen.add(tk)
        out.append((tk, _reads(st.value), st.value))
    return out


def _needed(lines, n_y: int) -> list[bool]:
    """Which lines ``dy`` and the joint torque depend on (backwards from the outputs)."""
    need = {f"dy[{k}]" for k in range(n_y)} | {_TORQUE}
    keep = [False] * len(lines)
    for i in range(len(lines) - 1, -1, -1):
        tk, reads, _ = lines[i]
        if tk in need:
            keep[i] = True
            need |= reads
    return keep


def _local(key: str, suffix: str) -> str:
    """The renamed local holding a re-evaluated value."""
    if key == _TORQUE:
        return f"tau_{suffix}"
    if key.startswith("dy["):
        return f"dy{key[3:-1]}_{suffix}"
    return f"{key}_{suffix}"


def _perturbed(lines, keep, seeds: dict, suffix: str) -> tuple[list[str], dict]:
    """Re-evaluate the kept lines that depend on ``seeds`` (key → operand replacing it);
    returns the emitted lines and the key → local map of everything that changed."""
    names = dict(seeds)
    out = []
    for (tk, reads, value), k in zip(lines, keep):
        if not k or not (reads & names.keys()):
            continue
        new = _Rename(names).visit(ast.parse(ast.unparse(value), mode="eval").body)
        loc = _local(tk, suffix)
        out.append(f"{loc} = {ast.unparse(new)}")
        names[tk] = loc
    return out, names


def column_function(body: list[str], n_y: int, decorator: str) -> str:
    """Source of ``rhs_columns(y, yo, th, thd, th2, thd2, U, P, dy, F, D, C, T, cols, thcol)``
    for the right-hand side ``body`` (module docstring). ``cols`` and ``thcol`` are floats
    (non-zero: compute): numba compiles a function once per literal argument, and literal
    ``True``/``False`` at the stepper's call sites compiled this, its largest function, twice
    (6 s of a circuit's first compilation)."""
    lines = _parse(body)
    keep = _needed(lines, n_y)
    src = [decorator,
           "def rhs_columns(y, yo, th, thd, th2, thd2, U, P, dy, F, D, C, T, cols, thcol):"]
    ind = "    "
    for line, k in zip(body, keep):
        if k:
            src.append(ind + line)

    def outputs(names, row):
        for k in range(n_y):
            key = f"dy[{k}]"
            src.append(f"{ind * 2}{row}{k}] = {names.get(key, key)}")
        src.append(f"{ind * 2}{row}{n_y}] = {names.get(_TORQUE, _TORQUE)}")

    src.append(ind + "if cols != 0.0:")
    for j in range(n_y):
        yq = f"yq{j}"
        src.append(f"{ind * 2}{yq} = y[{j}] + D[{j}]")
        emitted, names = _perturbed(lines, keep, {f"y[{j}]": yq}, f"c{j}")
        src += [ind * 2 + e for e in emitted]
        outputs(names, f"C[{j}, ")
    src.append(ind + "if thcol != 0.0:")
    emitted, names = _perturbed(lines, keep, {"th": "th2", "thd": "thd2"}, "t")
    src += [ind * 2 + e for e in emitted] or [ind * 2 + "pass"]
    outputs(names, "T[")
    return "\n".join(src)
