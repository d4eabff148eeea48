"""The secant (Broyden) Jacobian of the calibration fits, against the update's defining
properties, scipy's own robust-loss Jacobian and fits with an analytic Jacobian."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from afo_mj.calibration.secant_jacobian import (
    SecantJacobian, broyden_update, soft_l1_jacobian_weights)


def test_broyden_update_is_the_least_change_meeting_the_secant_equation():
    rng = np.random.default_rng(3)
    B = rng.normal(size=(7, 4))
    s, y = rng.normal(size=4), rng.normal(size=7)
    B1 = broyden_update(B, s, y)
    assert np.allclose(B1 @ s, y, atol=1e-12)          # the secant equation
    v = rng.normal(size=4)
    v -= (v @ s) / (s @ s) * s                          # a direction the step did not take
    assert np.allclose(B1 @ v, B @ v, atol=1e-12)      # is left as it was
    assert np.linalg.matrix_rank(B1 - B) == 1
    assert broyden_update(B, np.zeros(4), y) is B


def test_soft_l1_weights_are_those_scipy_reports_its_jacobian_with():
    t = np.linspace(0.0, 1.0, 60)
    rng = np.random.default_rng(1)
    y = 2.0 * np.exp(-3.0 * t) + rng.normal(0.0, 0.3, t.size)
    y[[5, 17]] += 3.0                                   # outliers: weights well below 1

    def jac(x):
        e = np.exp(-x[1] * t)
        return np.column_stack([e, -x[0] * t * e])

    res = least_squares(lambda x: x[0] * np.exp(-x[1] * t) - y, [1.0, 1.0], jac=jac,
                        loss="soft_l1", f_scale=0.2)
    w = soft_l1_jacobian_weights(res.fun, 0.2)
    assert w.min() < 0.1
    assert np.allclose(res.jac, w[:, None] * jac(res.x), rtol=1e-12, atol=1e-15)


def _problem():
    """A sum of three decaying exponentials (six parameters), noise-free: its minimiser is
    the generating parameters."""
    t = np.linspace(0.0, 4.0, 400)
    truth = np.array([1.0, 0.5, 0.6, 2.0, 0.3, 6.0])

    def model(x):
        return sum(x[2 * k] * np.exp(-x[2 * k + 1] * t) for k in range(3))

    data = model(truth)

    def f(x):
        return model(x) - data

    def exact(x):
        cols = []
        for k in range(3):
            e = np.exp(-x[2 * k + 1] * t)
            cols += [e, -x[2 * k] * t * e]
        return np.column_stack(cols)

    return f, exact, truth


def test_fit_with_the_secant_jacobian_reaches_the_analytic_fits_minimum():
    f, exact, truth = _problem()
    x0 = [0.8, 0.6, 0.8, 1.5, 0.2, 5.0]
    bounds = ([0.0] * 6, [5.0, 20.0] * 3)
    ref = least_squares(f, x0, jac=exact, bounds=bounds, method="trf", xtol=1e-12,
                        ftol=1e-12, gtol=1e-12)
    assert np.allclose(ref.x, truth, rtol=1e-6)
    seen = []

    def columns(x, cols):
        seen.append(list(cols))
        J = np.full((f(x).size, 6), np.nan)
        for j in cols:
            h = np.zeros(6)
            h[j] = 1e-7 * max(1.0, abs(x[j]))
            J[:, j] = (f(x + h) - f(x)) / h[j]
        return J

    sj = SecantJacobian(f, columns, n_params=6, refresh=2)
    res = least_squares(sj.residuals, x0, jac=sj.jacobian, bounds=bounds, method="trf",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=400)
    assert np.allclose(res.x, ref.x, rtol=1e-4)
    # cheaper per Jacobian than finite differences of every column
    assert sj.columns_taken < 6 * res.njev
    # the refreshed columns go round in turn between full Jacobians
    partial = [c for c in seen if len(c) == 2]
    assert partial and all(c in ([0, 1], [2, 3], [4, 5]) for c in partial)


def test_a_rejected_step_or_a_new_point_takes_a_full_jacobian():
    f, exact, _ = _problem()

    def columns(x, cols):
        J = np.full((400, 6), np.nan)
        J[:, list(cols)] = exact(x)[:, list(cols)]
        return J

    sj = SecantJacobian(f, columns, n_params=6, refresh=1)
    x = np.array([1.0, 0.5, 0.6, 2.0, 0.3, 6.0])
    sj.residuals(x)
    J0 = sj.jacobian(x)
    assert sj.full_jacobians == 1 and sj.fresh.all()
    assert np.allclose(J0, exact(x))
    x1 = x + 0.01
    sj.residuals(x1)                         # one evaluation, then accepted: secant step
    J1 = sj.jacobian(x1)
    assert sj.full_jacobians == 1 and sj.fresh.sum() == 1 and sj.fresh[0]
    assert np.allclose(J1[:, 0], exact(x1)[:, 0])
    # the other columns are the secant update's
    assert np.allclose(J1[:, 1:], broyden_update(J0, x1 - x, f(x1) - f(x))[:, 1:])
    x2 = x1 + 0.01
    sj.residuals(x2 + 0.3)                   # a rejected trial ...
    sj.residuals(x2)                         # ... then the accepted one
    sj.jacobian(x2)
    assert sj.full_jacobians == 2 and sj.fresh.all()


@pytest.mark.parametrize("kw, match", [({"n_params": 0}, "n_params = 0"),
                                       ({"n_params": 2, "refresh": -1}, "refresh = -1")])
def test_bad_arguments_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        SecantJacobian(lambda x: x, lambda x, c: None, **kw)
