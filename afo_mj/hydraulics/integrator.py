"""Fixed-step, linearly implicit integration of stiff hydraulic states.

ROS2 (Verwer, Spee, Blom & Hundsdorfer 1999, SIAM J. Sci. Comput. 20:1456) is a two-stage,
second-order, L-stable Rosenbrock W-method:

    (I − γ h J) k1 = f(t, y)
    (I − γ h J) k2 = f(t + h, y + h k1) − 2 k1
    y⁺ = y + h (3/2 k1 + 1/2 k2),        γ = 1 + 1/√2

It stays second order with an approximate Jacobian ``J`` and, being L-stable, damps modes far
faster than the step (kHz oil-column modes at a 1 ms step) instead of ringing as the trapezoidal
rule would.

The outside world sees a fixed step (e.g. one 1 ms MuJoCo step, inputs held). Inside it,
:meth:`Ros2.advance` subdivides only where the embedded first-order solution ``y + h k1``
disagrees with ``y⁺`` by more than the tolerance (``err = h (k1 + k2)/2``), which happens at
events the Jacobian did not see coming: a piston reaching its end stop, a valve slamming shut.
In smooth operation it takes one step per call. ``J`` is formed by one *batched* forward-difference
evaluation: the right-hand side is called once on an (n, n+1) array holding the state and its n
perturbations, so the Python overhead of a Jacobian is that of one call.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)


class SimulationError(RuntimeError):
    """The integration produced a non-finite state; the message names the state and time."""


class Ros2:
    """ROS2 stepper for ``dy/dt = f(t, Y, u)`` where ``f`` accepts ``Y`` of shape (n, k).

    ``f`` returns ``(dY, extra)``; ``extra`` (anything, e.g. power flows) is passed through from
    the unperturbed column of the Jacobian batch so callers get outputs at ``y`` for free.
    ``scale`` gives each state's typical magnitude for the difference increments;
    ``error_scale`` (default ``scale``) the magnitude below which its error is not controlled
    (absolute tolerance ``atol_fraction * error_scale``; relative tolerance ``rtol``).
    """

    def __init__(self, f: Callable, scale: np.ndarray, rel_increment: float = 1e-7,
                 names: list[str] | None = None, rtol: float = 1e-2, atol_fraction: float = 1e-2,
                 max_subdivision: int = 1024, error_scale: np.ndarray | None = None):
        self.f = f
        self.rtol = rtol
        self.atol = atol_fraction * np.asarray(scale if error_scale is None else error_scale,
                                               dtype=float)
        self.max_subdivision = max_subdivision
        self.substeps_taken = 0
        self.rejected = 0
        self._h_next = None
        self.scale = np.asarray(scale, dtype=float)
        self.n = self.scale.size
        self.rel_increment = rel_increment
        self.names = names or [f"y[{i}]" for i in range(self.n)]
        self._eye = np.eye(self.n)
        self._cols = np.arange(self.n)

    def jacobian(self, t: float, y: np.ndarray, u):
        """``(J, f(y), extra(y))`` from one batched forward-difference call."""
        n = self.n
        dy = self.rel_increment * np.maximum(np.abs(y), self.scale)
        batch = np.empty((n, n + 1))
        batch[:, :] = y[:, None]
        batch[self._cols, self._cols + 1] += dy
        out, extra = self.f(t, batch, u)
        f0 = out[:, 0]
        jac = (out[:, 1:] - f0[:, None]) / dy[None, :]
        return jac, f0, extra

    def _stage(self, t, y, h, u, jac, f0):
        minv = np.linalg.inv(self._eye - (GAMMA * h) * jac)
        k1 = minv @ f0
        f1, _ = self.f(t + h, (y + h * k1)[:, None], u)
        k2 = minv @ (f1[:, 0] - 2.0 * k1)
        y_next = y + h * (1.5 * k1 + 0.5 * k2)
        err = np.max(np.abs(0.5 * h * (k1 + k2)) / (self.atol + self.rtol * np.abs(y)))
        return y_next, err

    def step(self, t: float, y: np.ndarray, h: float, u):
        """One plain ROS2 step (no error control); returns ``(y_next, f(y), extra(y))``."""
        jac, f0, extra = self.jacobian(t, y, u)
        y_next, _ = self._stage(t, y, h, u, jac, f0)
        self._check(t + h, y_next, h)
        return y_next, f0, extra

    def advance(self, t: float, y: np.ndarray, dt: float, u, on_substep=None):
        """Integrate over ``[t, t + dt]`` with inputs ``u`` held, subdividing where needed.

        ``on_substep(h, extra)`` is called for each accepted substep with the outputs at its
        start. Returns the state at ``t + dt``.
        """
        t_end = t + dt
        h = min(dt, self._h_next or dt)
        h_min = dt / self.max_subdivision
        while t < t_end - 1e-15 * dt:
            h = min(h, t_end - t)
            jac, f0, extra = self.jacobian(t, y, u)
            while True:
                y_next, err = self._stage(t, y, h, u, jac, f0)
                if (err <= 1.0 and np.all(np.isfinite(y_next))) or h <= h_min:
                    break
                self.rejected += 1
                h = max(h * max(0.2, 0.9 / np.sqrt(err) if np.isfinite(err) else 0.2), h_min)
            self._check(t + h, y_next, h)
            if on_substep is not None:
                on_substep(h, extra)
            self.substeps_taken += 1
            t += h
            y = y_next
            h_taken = h
            if err < 0.5:
                h = h * min(4.0, 0.9 / np.sqrt(max(err, 1e-10)))
        # remember the step size that worked (not the remainder-trimmed last one)
        self._h_next = max(h, h_taken) if dt > 0 else self._h_next
        return y

    def _check(self, t, y, h):
        if not np.all(np.isfinite(y)):
            bad = [self.names[i] for i in np.flatnonzero(~np.isfinite(y))]
            raise SimulationError(f"non-finite state at t = {t:.6g} s: {', '.join(bad)} "
                                  f"(step {h:g} s); check parameters and inputs")
