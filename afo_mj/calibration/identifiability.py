"""Which declared parameters can a record estimate? Sensitivity SVD and subset selection.

Before any fit the calibration of a described rig (``afo-mj calibrate`` with a ``[circuit]``)
replays the record once per declared parameter with that parameter moved by a small factor,
which gives the sensitivity matrix ``J`` of the normalised training residuals to the
parameters' factors (each column: how every output sample moves per relative change of one
datasheet value). From ``J``:

* the **singular values** of ``J`` whitened by the sensor noise (each channel's rows divided
  by its noise σ over its scale) say how many independent directions the record can resolve
  (Golub & Van Loan, *Matrix Computations*, 4th ed., §2.4; for parameter estimation: Bard,
  *Nonlinear Parameter Estimation*, 1974, §7-5);
* **subset selection** by QR factorisation with column pivoting picks the parameters in the
  order of how much new, independent sensitivity each adds (Businger & Golub 1965; Golub &
  Van Loan §5.4.2 and §12.2, "subset selection using the SVD/QR"; Lund & Foss 2008,
  *Automatica* 44, 278–281, for dynamic models): a parameter whose pivoted diagonal
  ``|R_kk|`` falls below ``|R_00| / max_condition`` is (nearly) a combination of those before
  it and is held;
* the **predicted standard error** of each selected factor, ``sqrt(diag((J_wᵀ J_w)⁻¹))``
  (the Cramér–Rao bound for white Gaussian noise; Bard §7-5), must be below
  ``max_relative_se``, else the parameter is held (the worst first, then the rest re-checked).

A held parameter stays at the description's (datasheet) value and is reported with why.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np
from scipy.linalg import qr

__all__ = ["ParameterRow", "Identifiability", "select_parameters", "similarity"]


@dataclasses.dataclass(frozen=True)
class ParameterRow:
    """One declared parameter's line of the identifiability table."""

    name: str
    sensitivity: float          # RMS of its whitened column (noise σ per unit factor change)
    pivot_rank: int | None      # its place in the pivoted QR order (None: not considered)
    pivot_ratio: float          # |R_kk| / |R_00|
    predicted_relative_se: float | None
    fitted: bool
    reason: str

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class Identifiability:
    """The table, the whitened singular values and the indices of the selected parameters."""

    rows: tuple[ParameterRow, ...]
    singular_values: tuple[float, ...]
    selected: tuple[int, ...]

    def as_dict(self) -> dict:
        return {"parameters": [r.as_dict() for r in self.rows],
                "singular_values": list(self.singular_values),
                "fitted": [self.rows[i].name for i in self.selected],
                "held": [r.name for r in self.rows if not r.fitted]}


def select_parameters(jac: np.ndarray, names: Sequence[str], row_weights: np.ndarray,
                      *, movable: Sequence[bool] | None = None, max_condition: float = 300.0,
                      max_relative_se: float = 0.05,
                      tolerances: Sequence[float] | None = None) -> Identifiability:
    """Select the parameters a record can estimate (module docstring).

    ``jac``: sensitivities (samples × parameters) of the normalised residuals to each
    parameter's factor; ``row_weights``: per sample, 1 over the normalised noise σ of its
    channel (whitening); ``movable``: False for a parameter a factor cannot move (its
    described value is 0). Example: two identical columns → the second is held as
    "a combination of ...".

    ``tolerances`` (relative, per parameter: what the datasheet already knows): the pivoted
    QR then orders the columns scaled by them, i.e. by the change of the outputs over one
    datasheet tolerance (a ±2 % bore and a ±30 % cable compliance compared by what their
    uncertainty does to the record, not per unit change), and a parameter whose predicted
    standard error is not below its tolerance is held (the record would know it no better
    than the datasheet does).
    """
    J = np.asarray(jac, dtype=float)
    w = np.asarray(row_weights, dtype=float)
    if J.ndim != 2 or J.shape[1] != len(names):
        raise ValueError(f"jac shape {J.shape}; allowed: (samples, {len(names)})")
    if w.shape != (J.shape[0],) or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ValueError(f"row_weights shape {w.shape}; allowed: ({J.shape[0]},), finite, > 0")
    if not np.all(np.isfinite(J)):
        raise ValueError("jac has non-finite entries (a replay failed at a probe)")
    n, p = J.shape
    movable = [True] * p if movable is None else list(movable)
    tol = np.ones(p) if tolerances is None else np.asarray(tolerances, dtype=float)
    if tol.shape != (p,) or not np.all(np.isfinite(tol)) or np.any(tol <= 0):
        raise ValueError(f"tolerances shape {tol.shape}; allowed: ({p},), finite, > 0")
    Jw = J * w[:, None]
    sens = np.sqrt(np.sum(Jw ** 2, axis=0) / max(n, 1))
    Js = Jw * tol[None, :]
    sv = np.linalg.svd(Jw, compute_uv=False) if p else np.zeros(0)
    cand = [j for j in range(p) if movable[j] and sens[j] > 0.0]
    reason = {j: ("described value is 0: a factor cannot move it" if not movable[j]
                  else "no sensitivity in this record") for j in range(p) if j not in cand}
    ratio = np.zeros(p)
    rank: dict[int, int] = {}
    sel: list[int] = []
    if cand:
        _, R, piv = qr(Js[:, cand], mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        for k, jj in enumerate(piv):
            j = cand[jj]
            rank[j] = k
            ratio[j] = float(d[k] / d[0]) if d[0] > 0 else 0.0
            if ratio[j] >= 1.0 / max_condition:
                sel.append(j)
            else:
                prev = [cand[q] for q in piv[:k]]
                coef, *_ = np.linalg.lstsq(Js[:, prev], Js[:, j], rcond=None)
                share = np.abs(coef) * np.linalg.norm(Js[:, prev], axis=0)
                top = [names[prev[q]] for q in np.argsort(-share)[:3]]
                reason[j] = (f"nearly a combination of {', '.join(top)}"
                             + (f" and {len(prev) - 3} more" if len(prev) > 3 else "")
                             + f" (pivot ratio {ratio[j]:.2g} < 1/{max_condition:g})")
    se: dict[int, float] = {}
    while sel:
        A = Jw[:, sel]
        cov = np.linalg.pinv(A.T @ A)
        s = np.sqrt(np.maximum(np.diag(cov), 0.0))
        se = {j: float(v) for j, v in zip(sel, s)}
        limit = np.minimum(max_relative_se, tol[sel]) if tolerances is not None else \
            np.full(len(sel), max_relative_se)
        worst = int(np.argmax(s / limit))
        if s[worst] <= limit[worst]:
            break
        j = sel.pop(worst)
        reason[j] = (f"predicted relative SE {s[worst]:.2g} > {limit[worst]:g} with the "
                     "others fitted" + (" (its datasheet tolerance)" if limit[worst]
                                        < max_relative_se else ""))
    rows = tuple(ParameterRow(
        names[j], float(sens[j]), rank.get(j), float(ratio[j]),
        se.get(j) if j in sel else None, j in sel,
        "fitted" if j in sel else reason.get(j, "held")) for j in range(p))
    return Identifiability(rows, tuple(float(v) for v in sv), tuple(sorted(sel)))


def similarity(a: np.ndarray, b: np.ndarray, row_weights: np.ndarray) -> float:
    """The cosine of two sensitivity columns whitened by ``row_weights`` (1 over each
    sample's noise): +1 when one change of the outputs is a positive multiple of the other
    (no record with that noise separates them), 0 when orthogonal. The two-column case of
    the screen's pivoted QR: the second pivot's ratio is ``sqrt(1 − cos²)``."""
    w = np.asarray(row_weights, dtype=float)
    x = np.asarray(a, dtype=float) * w
    y = np.asarray(b, dtype=float) * w
    nx, ny = float(np.linalg.norm(x)), float(np.linalg.norm(y))
    if not (nx > 0.0 and ny > 0.0 and np.isfinite(nx) and np.isfinite(ny)):
        return 0.0
    return float(x @ y) / (nx * ny)
