"""A Jacobian for ``scipy.optimize.least_squares`` kept up to date by secant (Broyden)
updates, with a few finite-difference columns refreshed per iteration.

Why: a calibration fit has ~20 parameters and a forward-difference Jacobian costs one replay
per parameter at every accepted step: on rig 1's Stribeck + hose record, 2,946 of the
calibration's 3,334 replays were the fits' Jacobians. The trust-region steps of such a
fit are short (a few percent of the normalised parameters), where the residuals are nearly
linear: the secant update carries the Jacobian from one step to the next for the price of
the residuals the step already computed.

The method is the secant Levenberg–Marquardt of Madsen, Nielsen & Tingleff, *Methods for
Non-Linear Least Squares Problems* (2nd ed., IMM DTU, 2004), §3.4: after a step
``s = x₊ − x`` with residual change ``y = f(x₊) − f(x)``, Broyden's rank-one update

    B₊ = B + (y − B s) sᵀ / (sᵀ s)

is the least change of ``B`` (Frobenius norm) that satisfies the secant equation
``B₊ s = y`` (Broyden, *Math. Comp.* 19, 1965). Directions the steps do not explore are
never corrected by it, so, as Madsen et al. do with one coordinate per iteration, ``refresh``
columns are retaken by finite differences in turn; a full Jacobian is taken at the start and
whenever the last step was rejected (the trust region shrank: the linear model failed).

Example::

    >>> import numpy as np
    >>> from scipy.optimize import least_squares
    >>> t = np.linspace(0.0, 1.0, 50)
    >>> f = lambda x: x[0] * np.exp(-x[1] * t) - 2.0 * np.exp(-3.0 * t)
    >>> def columns(x, cols):
    ...     J = np.full((t.size, 2), np.nan)
    ...     for j in cols:
    ...         h = np.zeros(2); h[j] = 1e-7
    ...         J[:, j] = (f(x + h) - f(x)) / 1e-7
    ...     return J
    >>> sj = SecantJacobian(f, columns, n_params=2, refresh=1)
    >>> res = least_squares(sj.residuals, [1.0, 1.0], jac=sj.jacobian)
    >>> bool(np.allclose(res.x, [2.0, 3.0], atol=1e-5))
    True
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

__all__ = ["SecantJacobian", "broyden_update", "soft_l1_jacobian_weights"]


def broyden_update(B: np.ndarray, s: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Broyden's rank-one ("good") update ``B + (y − B s) sᵀ / (sᵀ s)`` of the Jacobian
    ``B`` after the step ``s`` changed the residuals by ``y`` (Broyden 1965; Madsen et al.
    2004, eq. 3.33). The result satisfies ``B₊ s = y``; ``B`` is returned unchanged for a
    zero step."""
    ss = float(s @ s)
    if ss == 0.0:
        return B
    return B + np.outer(y - B @ s, s) / ss


def soft_l1_jacobian_weights(f: np.ndarray, f_scale: float) -> np.ndarray:
    """The row weights ``w`` with which ``least_squares(loss="soft_l1")`` reports its
    Jacobian (``res.jac = diag(w) J``): the Gauss–Newton weights of the loss.

    For ``ρ(z) = 2(√(1+z) − 1)``, ``z = (f/C)²`` (scipy's ``soft_l1`` at ``f_scale = C``),
    scipy's ``scale_for_robust_loss_function`` weights each row by
    ``√(ρ'(z) + 2 z ρ''(z))`` (its ``ρ''`` taken in ``f``'s units); with
    ``ρ' = (1+z)^-½`` and ``ρ'' = −½ (1+z)^-3/2`` that is ``(1+z)^-¾`` (floored at
    machine epsilon before the root, as scipy does): the Gauss–Newton Hessian of a robust
    cost with the second-order term of the loss kept (scipy's
    ``optimize/_lsq/common.py``; Triggs et al., *Bundle Adjustment — A Modern Synthesis*,
    2000, on robustified normal equations)."""
    z = (np.asarray(f, dtype=float) / f_scale) ** 2
    return np.maximum((1.0 + z) ** -1.5, np.finfo(float).eps) ** 0.5


class SecantJacobian:
    """The residuals and the Jacobian of one fit, for ``least_squares(fun=residuals,
    jac=jacobian)``.

    ``residuals(x)``: the fit's residual vector. ``columns(x, cols)``: a Jacobian at ``x``
    whose columns ``cols`` are taken (by finite differences; the others may be NaN).
    ``refresh``: columns retaken per iteration, in turn (0: a pure secant update between
    full Jacobians). :attr:`fresh` says which columns of the last Jacobian are finite
    differences at :attr:`x` (all of them after a full one); :attr:`full_jacobians` and
    :attr:`columns_taken` count the work."""

    def __init__(self, residuals: Callable[[np.ndarray], np.ndarray],
                 columns: Callable[[np.ndarray, Sequence[int]], np.ndarray],
                 n_params: int, refresh: int = 2):
        if n_params < 1:
            raise ValueError(f"n_params = {n_params!r}: at least 1 is allowed")
        if refresh < 0:
            raise ValueError(f"refresh = {refresh!r}: 0 or more columns are allowed")
        self._residuals, self._columns = residuals, columns
        self.n_params, self.refresh = int(n_params), int(refresh)
        self.x: np.ndarray | None = None      # where the last Jacobian was taken
        self.f: np.ndarray | None = None      # the residuals there
        self.J: np.ndarray | None = None
        self.fresh = np.zeros(self.n_params, dtype=bool)
        self.full_jacobians = 0
        self.columns_taken = 0
        self._next = 0                        # the next column to refresh
        self._since_jacobian = 0              # residual evaluations since the last Jacobian
        self._kept: list[tuple[np.ndarray, np.ndarray]] = []

    def residuals(self, x: np.ndarray) -> np.ndarray:
        x = np.array(x, dtype=float)
        f = np.asarray(self._residuals(x), dtype=float)
        self._since_jacobian += 1
        self._kept = [(x, f)] + self._kept[:3]
        return f

    def _f_at(self, x: np.ndarray) -> np.ndarray:
        for xk, fk in self._kept:
            if np.array_equal(xk, x):
                return fk
        return np.asarray(self._residuals(x), dtype=float)

    def full(self, x: np.ndarray) -> np.ndarray:
        """A Jacobian at ``x`` with every column retaken; it becomes the kept one."""
        x = np.array(x, dtype=float)
        J = np.array(self._columns(x, range(self.n_params)), dtype=float)
        self.full_jacobians += 1
        self.columns_taken += self.n_params
        self.x, self.f, self.J = x, self._f_at(x), J
        self.fresh[:] = True
        self._since_jacobian = 0
        return J

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        x = np.array(x, dtype=float)
        if self.J is None or self._since_jacobian != 1:
            return self.full(x).copy()
        f = self._f_at(x)
        B = broyden_update(self.J, x - self.x, f - self.f)
        cols = [(self._next + k) % self.n_params
                for k in range(min(self.refresh, self.n_params))]
        self._next = (self._next + len(cols)) % self.n_params
        self.fresh[:] = False
        if cols:
            Jc = np.asarray(self._columns(x, cols), dtype=float)
            B[:, cols] = Jc[:, cols]
            self.fresh[cols] = True
            self.columns_taken += len(cols)
        self.x, self.f, self.J = x, f, B
        self._since_jacobian = 0
        return B.copy()
