"""Data-driven discrepancy: a sparse regression of a held-out residual on candidate terms.

When no physical effect of :mod:`afo_mj.calibration.effect_library` explains what the model
misses, the residual of each output channel is regressed on a library of candidate terms built
from the record's states and inputs (:func:`candidate_features`), and the sparsest model that
predicts the *held-out* residual best is reported as a short readable expression with its
held-out gain (:func:`sparse_discrepancy`, :func:`discrepancy_report`).

Method:

* **Library** (:func:`candidate_features`): constant, linear, drift, smoothed sign, absolute
  value, Coulomb-like ``x·sign(v)``, first and second time derivative and pairwise product
  terms of the given signals; near-duplicate columns (``|ρ| > 0.999``) are dropped.
* **Normalisation**: every non-constant column is z-scored with the *training* mean and
  standard deviation (so thresholds compare coefficients in the residual's unit per standard
  deviation of the feature); the coefficients are mapped back to physical units for the report.
* **Sparse regression**: sequentially thresholded least squares (STLSQ; Brunton, Proctor &
  Kutz, "Discovering governing equations from data by sparse identification of nonlinear
  dynamical systems", PNAS 113 (2016) 3932) over a grid of thresholds, plus greedy forward
  selection (orthogonal least squares by exhaustive one-step search; e.g. Hastie, Tibshirani &
  Friedman, *The Elements of Statistical Learning*, 2nd ed., §3.3.2) as a fallback, both
  limited to ``max_terms`` non-constant terms, every support refitted by ordinary least squares
  on the training samples.
* **Model choice on held-out data**: the candidate with the lowest held-out mean squared error,
  then the sparsest candidate within one standard error of it (the one-standard-error rule;
  Hastie, Tibshirani & Friedman, ESL §7.10).

A second, dynamic form (:func:`second_order_discrepancy`) asks whether a channel reads the
model's own output through a second-order linear system (a ringing sensor or an unmodelled
structural mode): ``reading = H(s)·y_model``, ``H = ω_n²/(s² + 2ζω_n s + ω_n²)``, ω_n and ζ
fitted on the training part (grid, then ``scipy.optimize.least_squares``), judged on the
held-out part. :func:`discrepancy_report` reports, per channel, whichever form predicts the
held-out residual better, with the other as the alternative.

The result is labelled a **data-driven discrepancy (not a physical effect)**: a correlation
found in the data, with no claim about the mechanism behind it.

Only numpy, scipy and the standard library are used (calibration layer).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping

import numpy as np

__all__ = [
    "LABEL",
    "DiscrepancyTerm",
    "candidate_features",
    "sparse_discrepancy",
    "second_order_reading",
    "second_order_discrepancy",
    "discrepancy_report",
]

#: Label of every result of this module: a regression, never a physical effect.
LABEL = "data-driven discrepancy (not a physical effect)"

#: |correlation| above which a candidate column counts as a duplicate of a kept one.
REDUNDANT_CORRELATION = 0.999
#: Width of the smoothed sign, as a fraction of the signal's standard deviation.
SIGN_WIDTH = 0.05
#: Minimum relative drop of the held-out RMS for a discrepancy to count as found.
MIN_RELATIVE_GAIN = 0.10
#: A residual whose held-out RMS is at most this multiple of its noise σ is within noise.
NOISE_FACTOR = 1.2
#: Relative Tikhonov term of the STLSQ solves (conditioning of near-collinear columns).
RIDGE = 1e-6


@dataclasses.dataclass(frozen=True)
class DiscrepancyTerm:
    """One term ``coefficient · feature`` of a data-driven discrepancy.

    ``feature`` is the readable name of a library column (e.g. ``"delta_p·sign(velocity)"``,
    ``"d/dt pressure_a_pa"``, ``"1"``); ``coefficient`` is in the channel's unit per unit of the
    feature (physical units, not the normalised ones of the regression)."""

    feature: str
    coefficient: float


# ---------------------------------------------------------------------------- input checks


def _vector(name: str, value: object, n: int | None = None) -> np.ndarray:
    """``value`` as a finite 1-D float array (of length ``n`` when given), else ValueError."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 1-D array of finite numbers; got "
                         f"{type(value).__name__} ({exc})") from None
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array; got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} must have length {n} (the length of time_s/residual); "
                         f"got shape {arr.shape}")
    if arr.shape[0] == 0:
        raise ValueError(f"{name} must not be empty; got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name} must be finite; got {arr[k]} at index {k} "
                         f"({int(bad.sum())} non-finite values)")
    return arr


def _index(name: str, value: object, n: int) -> np.ndarray:
    """``value`` as a non-empty array of distinct sample indices in ``[0, n)`` (or a boolean
    mask of length ``n``), else ValueError."""
    arr = np.asarray(value)
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise ValueError(f"{name} as a boolean mask must have shape ({n},); "
                             f"got shape {arr.shape}")
        arr = np.flatnonzero(arr)
    if arr.ndim != 1 or not (arr.size == 0 or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must be a 1-D array of integer sample indices; got dtype "
                         f"{arr.dtype}, shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name} must not be empty; got shape {arr.shape}")
    if arr.min() < 0 or arr.max() >= n:
        raise ValueError(f"{name} must index samples in [0, {n}); got values from "
                         f"{int(arr.min())} to {int(arr.max())}")
    if np.unique(arr).size != arr.size:
        raise ValueError(f"{name} must not repeat an index; got {arr.size - np.unique(arr).size} "
                         f"repeated")
    return arr.astype(np.intp)


# ---------------------------------------------------------------------------- library


def candidate_features(signals: Mapping[str, np.ndarray], time_s: np.ndarray, *,
                       max_features: int = 60) -> dict[str, np.ndarray]:
    """Library of candidate terms built from a record's states and inputs.

    ``signals`` maps a name to a 1-D array sampled at ``time_s`` (strictly increasing, s). The
    families, added in this order of priority (so a cap drops the later ones first):

    1. ``"1"``: constant (an offset of the residual);
    2. ``x``: each signal (a missing linear term: stiffness, gain, leakage ∝ pressure);
    3. ``"t"``: time in s (a drift: heating, sensor drift);
    4. ``sign(x)``: smoothed sign ``tanh(x / (0.05·std x))`` (a switching offset, Coulomb-like
       friction on a velocity);
    5. ``|x|``: absolute value (direction-independent losses);
    6. ``x·sign(v)``: each signal times the smoothed sign of each velocity-like signal ``v``
       (name containing ``"velocity"`` or ``"speed"``): a load-dependent friction, a pressure
       times direction;
    7. ``d/dt x``: time derivative by central differences (``np.gradient``; a missing inertia,
       damping or compliance);
    8. ``d²/dt² x``: second time derivative (``np.gradient`` twice): a missing mass, or a
       sensor's own second-order dynamics. A sensor of natural frequency ω_n and damping ζ
       reads ``H(s)·x`` with ``H = ω_n²/(s² + 2ζω_n s + ω_n²)``, and below ω_n
       ``H − 1 ≈ −(2ζ/ω_n)s − s²/ω_n²`` (Doebelin, *Measurement Systems*, 5th ed., §3.5): the
       residual ``≈ −(1/ω_n²)·ẍ − (2ζ/ω_n)·ẋ``, so the ``d²/dt²`` coefficient reads as
       ``ω_n = 1/√(−c)``. Differentiating twice amplifies noise, so these terms help only for
       noise-free signals (the model's outputs); held-out selection drops them otherwise;
    9. ``x·y`` and ``x²``: pairwise products of the signals (interactions, quadratic drag).

    A column is skipped when it is (numerically) constant or its ``|correlation|`` with an
    already kept column exceeds 0.999 (redundant: e.g. ``|x|`` of a positive ``x``); at most
    ``max_features`` columns are kept. Returns an insertion-ordered ``{name: column}``.

    Sparse-regression libraries of this kind: Brunton, Proctor & Kutz, PNAS 113 (2016) 3932.
    """
    if not isinstance(signals, Mapping) or not signals:
        raise ValueError(f"signals must be a non-empty mapping of name -> 1-D array; got "
                         f"{type(signals).__name__} of length "
                         f"{len(signals) if hasattr(signals, '__len__') else '?'}")
    t = _vector("time_s", time_s)
    n = t.shape[0]
    if n < 3:
        raise ValueError(f"time_s must have at least 3 samples; got shape {t.shape}")
    if not np.all(np.diff(t) > 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"time_s must be strictly increasing; got {t[k]} then {t[k + 1]} at "
                         f"index {k}")
    if isinstance(max_features, bool) or not isinstance(max_features, int) or max_features < 1:
        raise ValueError(f"max_features must be an integer >= 1; got {max_features!r}")
    sig: dict[str, np.ndarray] = {}
    for name, x in signals.items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"signals keys must be non-empty strings; got {name!r}")
        sig[name] = _vector(f"signals[{name!r}]", x, n)

    kept: dict[str, np.ndarray] = {}
    unit = np.empty((max_features, n))   # centred unit-norm copies of the kept non-constant ones
    n_unit = 0

    def add(name: str, col: np.ndarray) -> None:
        nonlocal n_unit
        if len(kept) >= max_features or name in kept:
            return
        if name == "1":
            kept[name] = col
            return
        c = col - col.mean()
        norm = float(np.linalg.norm(c))
        scale = float(np.abs(col).max())
        if not math.isfinite(norm) or norm <= 1e-12 * max(scale, 1e-300) * math.sqrt(n):
            return                        # constant: redundant with "1"
        u = c / norm
        if n_unit and float(np.abs(unit[:n_unit] @ u).max()) > REDUNDANT_CORRELATION:
            return
        kept[name] = col
        unit[n_unit] = u
        n_unit += 1

    smooth_sign: dict[str, np.ndarray] = {}
    for name, x in sig.items():
        s = float(np.std(x))
        if s > 0.0:
            smooth_sign[name] = np.tanh(x / (SIGN_WIDTH * s))
    velocities = [v for v in sig if ("velocity" in v.lower() or "speed" in v.lower())
                  and v in smooth_sign]

    add("1", np.ones(n))
    for name, x in sig.items():
        add(name, x)
    add("t", t - t[0])
    for name in sig:
        if name in smooth_sign:
            add(f"sign({name})", smooth_sign[name])
    for name, x in sig.items():
        add(f"|{name}|", np.abs(x))
    for v in velocities:
        for name, x in sig.items():
            if name != v:
                add(f"{name}·sign({v})", x * smooth_sign[v])
    for name, x in sig.items():
        add(f"d/dt {name}", np.gradient(x, t))
    for name, x in sig.items():
        add(f"d²/dt² {name}", np.gradient(np.gradient(x, t), t))
    names = list(sig)
    for i, a in enumerate(names):
        for b in names[i:]:
            add(f"{a}²" if a == b else f"{a}·{b}", sig[a] * sig[b])
    return kept


# ---------------------------------------------------------------------------- regression


def _lstsq_support(G: np.ndarray, b: np.ndarray, support: np.ndarray,
                   ridge: float = 0.0) -> np.ndarray:
    """Coefficients (full length) of the least-squares fit on ``support`` from the Gram matrix
    ``G = ZᵀZ`` and ``b = Zᵀr`` of the training samples (normal equations, minimum-norm
    solution for a rank-deficient support)."""
    xi = np.zeros(G.shape[0])
    if support.size:
        Gs = G[np.ix_(support, support)]
        if ridge > 0.0:
            Gs = Gs + ridge * np.diag(np.diag(Gs))
        xi[support] = np.linalg.lstsq(Gs, b[support], rcond=1e-12)[0]
    return xi


def _stlsq(G: np.ndarray, b: np.ndarray, threshold: float, always: np.ndarray,
           max_iter: int = 20) -> np.ndarray:
    """Sequentially thresholded least squares (Brunton, Proctor & Kutz 2016, PNAS 113, 3932):
    least squares on the active set, zero every coefficient with ``|ξ| < threshold`` (the
    columns in ``always``, the constant, are never thresholded), repeat until the active set no
    longer changes. Returns the final active set (sorted column indices)."""
    p = G.shape[0]
    active = np.ones(p, dtype=bool)
    for _ in range(max_iter):
        xi = _lstsq_support(G, b, np.flatnonzero(active), RIDGE)
        new = active & ((np.abs(xi) >= threshold) | always)
        if np.array_equal(new, active):
            break
        active = new
    return np.flatnonzero(active)


def _forward(G: np.ndarray, b: np.ndarray, rr: float, base: np.ndarray,
             max_terms: int) -> list[np.ndarray]:
    """Greedy forward selection: starting from ``base`` (the constant), add the column that
    lowers the training residual sum of squares most, up to ``max_terms`` columns (ESL §3.3.2).
    Returns the supports of sizes ``len(base) + 1 … len(base) + max_terms``."""
    p = G.shape[0]
    support = list(base)
    out: list[np.ndarray] = []
    for _ in range(max_terms):
        best, best_rss = -1, math.inf
        for j in range(p):
            if j in support:
                continue
            s = np.array(support + [j])
            xi = _lstsq_support(G, b, s)[s]
            rss = rr - 2.0 * xi @ b[s] + xi @ G[np.ix_(s, s)] @ xi
            if rss < best_rss - 1e-15 * abs(rr):
                best, best_rss = j, rss
        if best < 0:
            break
        support.append(best)
        out.append(np.array(sorted(support)))
    return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else 0.0


def _format_number(c: float) -> str:
    return f"{c:.3g}"


def _expression(terms: list[DiscrepancyTerm]) -> str:
    """``"residual ≈ 3.1e-07·delta_p·sign(velocity) − 0.02"`` (``"residual ≈ 0"`` if empty)."""
    if not terms:
        return "residual ≈ 0"
    parts = []
    for k, term in enumerate(terms):
        mag = _format_number(abs(term.coefficient))
        body = mag if term.feature == "1" else f"{mag}·{term.feature}"
        neg = term.coefficient < 0
        if k == 0:
            parts.append(("−" if neg else "") + body)
        else:
            parts.append(("− " if neg else "+ ") + body)
    return "residual ≈ " + " ".join(parts)


def sparse_discrepancy(channel: str, residual: np.ndarray, features: Mapping[str, np.ndarray],
                       train_idx: np.ndarray, test_idx: np.ndarray, noise_sigma: float, *,
                       max_terms: int = 3) -> dict:
    """Sparse regression of one channel's residual on candidate features, chosen on held-out
    samples: a *data-driven discrepancy*, never a physical effect.

    1. Each non-constant feature is z-scored with its mean and standard deviation on
       ``train_idx`` (centred only when the constant ``"1"`` is in ``features``; a feature
       constant on the training samples is left out).
    2. Candidate supports: STLSQ (Brunton, Proctor & Kutz, PNAS 113 (2016) 3932) on the
       training samples for 40 thresholds from 10⁻³ to 1 times the largest normalised
       least-squares coefficient, the constant never thresholded; plus greedy forward selection
       (ESL §3.3.2); plus the constant alone. Supports with more than ``max_terms`` non-constant
       terms are dropped; each support is refitted by ordinary least squares on ``train_idx``.
    3. Choice: the lowest mean squared error on ``test_idx``, then the sparsest support within
       one standard error of it (one-standard-error rule, Hastie, Tibshirani & Friedman, ESL
       §7.10).
    4. ``found`` is True only when the held-out RMS before (the raw residual) is above
       ``1.2·noise_sigma`` and the chosen model lowers it by at least 10 % (relative);
       otherwise ``terms`` is empty and ``held_out_rms_after`` equals ``held_out_rms_before``.

    Returns ``{"channel", "label", "found", "terms"`` (:class:`DiscrepancyTerm` in physical
    units, sorted by decreasing held-out RMS contribution), ``"expression"``,
    ``"held_out_rms_before"``, ``"held_out_rms_after"``, ``"held_out_gain"`` (``1 − after /
    before`` of the RMS), ``"best_held_out_gain"`` (of the best candidate, found or not),
    ``"noise_sigma"``, ``"within_noise"`` (``after <= 1.2·noise_sigma``), ``"n_features"``,
    ``"n_train"``, ``"n_test"}``. Every number is finite.
    """
    if not isinstance(channel, str) or not channel:
        raise ValueError(f"channel must be a non-empty string; got {channel!r}")
    r = _vector("residual", residual)
    n = r.shape[0]
    if not isinstance(features, Mapping) or not features:
        raise ValueError(f"features must be a non-empty mapping of name -> 1-D array; got "
                         f"{type(features).__name__}")
    names: list[str] = []
    cols: list[np.ndarray] = []
    for name, col in features.items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"features keys must be non-empty strings; got {name!r}")
        names.append(name)
        cols.append(_vector(f"features[{name!r}]", col, n))
    X = np.column_stack(cols)
    tr = _index("train_idx", train_idx, n)
    te = _index("test_idx", test_idx, n)
    overlap = np.intersect1d(tr, te)
    if overlap.size:
        raise ValueError(f"test_idx must not share samples with train_idx; got {overlap.size} "
                         f"shared (first {int(overlap[0])})")
    if tr.size < 2:
        raise ValueError(f"train_idx must hold at least 2 samples; got {tr.size}")
    try:
        sigma = float(noise_sigma)
    except (TypeError, ValueError):
        raise ValueError(f"noise_sigma must be a finite number >= 0; got {noise_sigma!r}") \
            from None
    if not math.isfinite(sigma) or sigma < 0.0:
        raise ValueError(f"noise_sigma must be a finite number >= 0; got {noise_sigma!r}")
    if isinstance(max_terms, bool) or not isinstance(max_terms, int) or max_terms < 1:
        raise ValueError(f"max_terms must be an integer >= 1; got {max_terms!r}")


    before = _rms(r[te])
    result: dict = {
        "channel": channel, "label": LABEL, "found": False, "terms": [],
        "expression": _expression([]), "held_out_rms_before": before,
        "held_out_rms_after": before, "held_out_gain": 0.0, "best_held_out_gain": 0.0,
        "noise_sigma": sigma, "within_noise": bool(before <= NOISE_FACTOR * sigma),
        "n_features": len(names), "n_train": int(tr.size), "n_test": int(te.size),
    }

    # z-scoring on the training samples
    has_const = "1" in names
    const = np.array([nm == "1" for nm in names])
    Xtr = X[tr]
    mu = Xtr.mean(axis=0) if has_const else np.zeros(X.shape[1])
    sd = Xtr.std(axis=0) if has_const else np.sqrt(np.mean(Xtr ** 2, axis=0))
    usable = const | (sd > 1e-12 * np.maximum(np.abs(Xtr).max(axis=0), 1e-300))
    mu = np.where(const, 0.0, mu)
    sd = np.where(const | ~usable, 1.0, sd)
    keep = np.flatnonzero(usable)
    names = [names[k] for k in keep]
    const, mu, sd = const[keep], mu[keep], sd[keep]
    Z = (X[:, keep] - mu) / sd
    Ztr, Zte = Z[tr], Z[te]
    rtr, rte = r[tr], r[te]
    G = Ztr.T @ Ztr
    b = Ztr.T @ rtr
    rr = float(rtr @ rtr)
    base = np.flatnonzero(const)

    # candidate supports
    supports: dict[tuple[int, ...], np.ndarray] = {}

    def consider(s: np.ndarray) -> None:
        s = np.unique(np.concatenate([s, base])).astype(np.intp)
        if int((~const[s]).sum()) <= max_terms:
            supports.setdefault(tuple(s.tolist()), s)

    consider(base)
    xi_ls = _lstsq_support(G, b, np.arange(len(names)), RIDGE)
    top = float(np.abs(xi_ls[~const]).max()) if (~const).any() else 0.0
    if top > 0.0 and math.isfinite(top):
        for lam in top * np.logspace(-3.0, 0.0, 40):
            consider(_stlsq(G, b, float(lam), const))
    for s in _forward(G, b, rr, base, max_terms):
        consider(s)

    # held-out choice with the one-standard-error rule
    fits = []
    for s in supports.values():
        xi = _lstsq_support(G, b, s)
        if not np.all(np.isfinite(xi)):
            continue
        err2 = np.square(rte - Zte[:, s] @ xi[s])
        mse = float(err2.mean())
        se = float(err2.std() / math.sqrt(err2.size))
        fits.append((mse, se, int((~const[s]).sum()), s, xi))
    if not fits:
        return result
    best = min(fits, key=lambda f: f[0])
    tol = best[0] + best[1]
    chosen = min((f for f in fits if f[0] <= tol), key=lambda f: (f[2], f[0]))
    after = math.sqrt(chosen[0])
    gain = 1.0 - after / before if before > 0.0 else 0.0
    result["best_held_out_gain"] = float(max(gain, 0.0)) if math.isfinite(gain) else 0.0
    if result["within_noise"] or not gain >= MIN_RELATIVE_GAIN:
        return result

    # back to physical units: ξ_j (x_j − μ_j)/σ_j → (ξ_j/σ_j)·x_j, offsets into the constant
    s, xi = chosen[3], chosen[4]
    coef: dict[str, float] = {}
    offset = 0.0
    for k in s:
        if const[k]:
            offset += float(xi[k])
        else:
            coef[names[k]] = float(xi[k] / sd[k])
            offset -= float(xi[k] * mu[k] / sd[k])
    terms: list[tuple[float, DiscrepancyTerm]] = []
    Xte = X[te]
    col_of = {nm: j for j, nm in enumerate(features)}
    for nm, c in coef.items():
        terms.append((_rms(c * Xte[:, col_of[nm]]), DiscrepancyTerm(nm, c)))
    if has_const and offset != 0.0:
        terms.append((abs(offset), DiscrepancyTerm("1", offset)))
    terms.sort(key=lambda tc: -tc[0])
    ordered = [tc[1] for tc in terms if math.isfinite(tc[1].coefficient)]
    result.update({
        "found": True, "terms": ordered, "expression": _expression(ordered),
        "held_out_rms_after": after, "held_out_gain": float(gain),
        "within_noise": bool(after <= NOISE_FACTOR * sigma),
    })
    return result


# ---------------------------------------------------------------------------- dynamic form

#: Natural frequencies tried by the grid of :func:`second_order_discrepancy`, as fractions of
#: the Nyquist frequency (log-spaced) and damping ratios.
_GRID_FN = np.logspace(np.log10(0.005), np.log10(0.9), 36)
_GRID_ZETA = np.array([0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 1.0, 1.5])


def second_order_reading(y: np.ndarray, sample_period_s: float, natural_frequency_hz: float,
                         damping_ratio: float) -> np.ndarray:
    """``y`` read through a second-order instrument, ``H(s) = ω_n²/(s² + 2ζω_n s + ω_n²)``
    (unit static gain; Doebelin, *Measurement Systems*, 5th ed., §3.4), starting at rest at
    ``y[0]``.

    Exact for ``y`` linear between samples: ``H`` discretised with a first-order hold
    (``scipy.signal.cont2discrete(method="foh")``), filtered by ``scipy.signal.lfilter`` from
    the steady state of ``y[0]``.

    >>> import numpy as np
    >>> float(second_order_reading(np.ones(5), 1e-3, 80.0, 0.05)[-1])
    1.0
    """
    from scipy import signal
    wn = 2.0 * math.pi * natural_frequency_hz
    num, den, _ = signal.cont2discrete(([wn * wn], [1.0, 2.0 * damping_ratio * wn, wn * wn]),
                                       sample_period_s, method="foh")
    b = np.ravel(num)
    a = np.ravel(den)
    zi = signal.lfilter_zi(b, a) * y[0]
    return signal.lfilter(b, a, y, zi=zi)[0]


def second_order_discrepancy(channel: str, residual: np.ndarray, model_output: np.ndarray,
                             time_s: np.ndarray, train_idx: np.ndarray, test_idx: np.ndarray,
                             noise_sigma: float) -> dict:
    """Does the channel read the model's output through a second-order system?

    Fits ``residual ≈ H(s)·y − y`` (``y`` = ``model_output``, :func:`second_order_reading`)
    on ``train_idx`` over the natural frequency (0.5 % to 90 % of the Nyquist frequency) and
    the damping ratio (0.005–3): a grid of 36 × 9, then bounded least squares in
    ``(log f_n, log ζ)``; the held-out RMS after is measured on ``test_idx``. ``found`` as in
    :func:`sparse_discrepancy` (above 1.2 σ before, ≥ 10 % held-out drop). Needs uniform
    sampling (else ``found`` is False with a ``"reason"``).

    Returns the keys of :func:`sparse_discrepancy` (``terms`` empty; ``expression`` names the
    filter) plus ``"form": "second_order_reading"``, ``"natural_frequency_hz"`` and
    ``"damping_ratio"``."""
    from scipy.optimize import least_squares
    r = _vector("residual", residual)
    n = r.shape[0]
    y = _vector("model_output", model_output, n)
    t = _vector("time_s", time_s, n)
    tr = _index("train_idx", train_idx, n)
    te = _index("test_idx", test_idx, n)
    sigma = float(noise_sigma)
    before = _rms(r[te])
    result: dict = {
        "channel": channel, "label": LABEL, "form": "second_order_reading", "found": False,
        "terms": [], "expression": _expression([]), "held_out_rms_before": before,
        "held_out_rms_after": before, "held_out_gain": 0.0, "best_held_out_gain": 0.0,
        "noise_sigma": sigma, "within_noise": bool(before <= NOISE_FACTOR * sigma),
        "natural_frequency_hz": None, "damping_ratio": None,
        "n_features": 2, "n_train": int(tr.size), "n_test": int(te.size),
    }
    dt = np.diff(t)
    h = float(np.median(dt)) if dt.size else 0.0
    if n < 10 or h <= 0.0 or float(np.max(np.abs(dt - h))) > 1e-6 * h:
        result["reason"] = "needs uniformly sampled data"
        return result
    nyq = 0.5 / h
    if float(np.std(y[tr])) <= 0.0:
        result["reason"] = "the model output is constant"
        return result

    def resid(z: np.ndarray, idx: np.ndarray) -> np.ndarray:
        f, zeta = math.exp(z[0]), math.exp(z[1])
        return r[idx] - (second_order_reading(y, h, f, zeta)[idx] - y[idx])

    best_z, best_sse = None, math.inf
    for f in _GRID_FN * nyq:
        for zeta in _GRID_ZETA:
            z = np.array([math.log(f), math.log(zeta)])
            e = resid(z, tr)
            sse = float(e @ e)
            if math.isfinite(sse) and sse < best_sse:
                best_z, best_sse = z, sse
    if best_z is None:
        return result
    lo = np.array([math.log(0.005 * nyq), math.log(0.005)])
    hi = np.array([math.log(0.9 * nyq), math.log(3.0)])
    try:
        sol = least_squares(resid, np.clip(best_z, lo, hi), bounds=(lo, hi), args=(tr,),
                            x_scale=1.0, diff_step=1e-4, max_nfev=60)
        z = sol.x if float(2.0 * sol.cost) <= best_sse else best_z
    except ValueError:
        z = best_z
    after = _rms(resid(z, te))
    gain = 1.0 - after / before if before > 0.0 else 0.0
    if not math.isfinite(gain):
        return result
    result["best_held_out_gain"] = float(max(gain, 0.0))
    if result["within_noise"] or gain < MIN_RELATIVE_GAIN:
        return result
    f, zeta = math.exp(z[0]), math.exp(z[1])
    result.update({
        "found": True, "natural_frequency_hz": f, "damping_ratio": zeta,
        "expression": (f"{channel} reads the model through ω_n²/(s² + 2ζω_n s + ω_n²), "
                       f"f_n = {f:.3g} Hz, ζ = {zeta:.2g}"),
        "held_out_rms_after": after, "held_out_gain": float(gain),
        "within_noise": bool(after <= NOISE_FACTOR * sigma),
    })
    return result


def discrepancy_report(residuals: Mapping[str, np.ndarray], signals: Mapping[str, np.ndarray],
                       time_s: np.ndarray, train_idx: np.ndarray, test_idx: np.ndarray,
                       noise: Mapping[str, float], *, max_terms: int = 3) -> dict[str, dict]:
    """Data-driven discrepancy of every channel of ``residuals``: one shared
    :func:`candidate_features` library from ``signals`` and ``time_s``, then
    :func:`sparse_discrepancy` per channel with its noise σ from ``noise`` (held-out model
    choice, ESL §7.10; STLSQ, Brunton, Proctor & Kutz 2016) and, for a channel that is also a
    signal (the model's output of it) and is not within its noise,
    :func:`second_order_discrepancy`. Per channel the form with the lower held-out RMS among
    those found is reported (``"form"``), the other under ``"alternative"``. Returns
    ``{channel: result}``."""
    if not isinstance(residuals, Mapping) or not residuals:
        raise ValueError(f"residuals must be a non-empty mapping of channel -> 1-D array; got "
                         f"{type(residuals).__name__}")
    if not isinstance(noise, Mapping):
        raise ValueError(f"noise must be a mapping of channel -> noise σ; got "
                         f"{type(noise).__name__}")
    missing = [ch for ch in residuals if ch not in noise]
    if missing:
        raise ValueError(f"noise must give a σ for every channel of residuals; missing "
                         f"{missing} (has {sorted(noise)})")
    features = candidate_features(signals, time_s)
    n = np.asarray(time_s).shape[0]
    out: dict[str, dict] = {}
    for ch, res in residuals.items():
        _vector(f"residuals[{ch!r}]", res, n)
        static = sparse_discrepancy(ch, res, features, train_idx, test_idx, noise[ch],
                                    max_terms=max_terms)
        dynamic = None
        if ch in signals and not static["within_noise"]:
            dynamic = second_order_discrepancy(ch, res, signals[ch], time_s, train_idx,
                                               test_idx, noise[ch])
        if dynamic is not None and dynamic["found"] and (
                not static["found"]
                or dynamic["held_out_rms_after"] < static["held_out_rms_after"]):
            best, other = dynamic, static
        else:
            best, other = static, dynamic
        if other is not None:
            best["alternative"] = {k: other[k] for k in (
                "form", "found", "expression", "held_out_gain", "best_held_out_gain")
                if k in other}
            best["alternative"].setdefault("form", "sparse_regression")
        best.setdefault("form", "sparse_regression")
        out[ch] = best
    return out
