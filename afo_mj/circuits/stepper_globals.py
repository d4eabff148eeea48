"""The generated module's globals that the stepper template uses, declared for editors and linters.

:mod:`afo_mj.circuits.stepper` is a *template*: :func:`afo_mj.circuits.codegen.generate` copies
its functions' source beneath a circuit's straight-line right-hand side, and there they use
that module's globals (the layout of the work vector ``W`` and the flow vector ``F``, the state
count, the right-hand side itself, the controller and the begin/close hooks). This module
declares every one of those names, with what it is, so that an editor resolves them and a
linter checks the template for names it does not know (``stepper.py`` imports these only under
``typing.TYPE_CHECKING``: nothing here runs, and the generated modules hold the real values).

Names whose value is the same in every circuit (the headers of ``W``, ``U`` and ``F``) are
given it, from :data:`afo_mj.circuits.codegen.W_HEADER`, ``U_NAMES`` and ``F_HEADER`` (a test
keeps them equal); names sized per circuit are given a placeholder 0.
"""

from __future__ import annotations

import numpy as np

# -- sizes, per circuit ---------------------------------------------------------------------
N_Y: int = 0            #: number of states (node pressures, shaft speeds, currents, positions)
N_U: int = 0            #: held inputs: the header U_NAMES, the named actuated inputs, the
                        #: held values
N_U_HEAD: int = 6       #: entries of the held-input header (len(U_NAMES))
N_INPUT: int = 0        #: named actuated inputs (a valve's command, ...)
N_W: int = 0            #: length of the work vector W (per side)
N_P: int = 0            #: length of the packed parameter row P
N_LOSS: int = 0         #: named losses
N_SRATE: int = 0        #: store rates (springs, stops, fixed-pressure reservoirs)
N_PROBE: int = 0        #: probes (flows, powers, positions)
N_CTRL: int = 0         #: controller slots (integrators, filters)
N_HELD: int = 0         #: values held from the last accepted step's end (Emitter.held)
N_SCRATCH: int = 0      #: rows of the scratch matrix S (Jacobians, factors)
S_WIDTH: int = 0        #: columns of the scratch matrix S
#: each state's typical size (the Newton test's scale; Pa, rad/s, A, 1)
Y_TYP: np.ndarray = np.zeros(0)

# -- the held inputs U (W[W_U + ...]) -----------------------------------------------------------
U_CMD: int = 0          #: the controller's command to the actuator (motor voltage), V
U_VBUS: int = 1         #: bus voltage, V
U_MU: int = 2           #: oil dynamic viscosity, Pa·s
U_RHO: int = 3          #: oil density, kg/m³
U_TEMP: int = 4         #: oil temperature, K
U_INV_H: int = 5        #: 1/h of the (sub-)step being solved, 1/s (set by the stepper)

# -- the flow vector F (rhs outputs) ------------------------------------------------------------
F_TAU: int = 0          #: joint torque, N·m
F_PBUS: int = 1         #: bus power drawn, W
F_HEAT: int = 2         #: heat into the oil, W
F_LOSS: int = 0         #: first named loss (per circuit)
F_SRATE: int = 0        #: first store rate (per circuit)
F_CAP: int = 0          #: first state capacitance (per circuit)
F_PROBE: int = 0        #: first probe (per circuit)

# -- the work vector W (per side): its fixed header ---------------------------------------------
W_CMD: int = 0          #: command held this step (torque, or voltage open loop)
W_THETA: int = 1        #: joint angle at the step's start, rad
W_THETA_DOT: int = 2    #: joint velocity at the step's start, rad/s
W_TAU0: int = 3         #: predicted end-of-step torque at zero velocity change, N·m
W_G: int = 4            #: its slope in the velocity change, N·m·s/rad (≤ 0)
W_TAU: int = 5          #: torque delivered over the step, N·m
W_TAU_END: int = 6      #: end-of-step torque after the Newton correction, N·m
W_TAU_MEAS: int = 7     #: the torque the device's own sensor reads, N·m
W_P_MECH: int = 8       #: mechanical power into the joint, W
W_COUPLE_SQ: int = 9    #: running sum of the squared coupling torque error, N²·m²
W_NEWTON_ITERS: int = 10    #: Newton iterations so far
W_NEWTON_FAIL: int = 11     #: steps whose Newton iteration did not converge
W_SUBSTEPPED: int = 12      #: steps redone as sub-steps
W_SUBSTEPS: int = 13        #: sub-steps taken
W_CLIP_STEPS: int = 14      #: steps with a pressure raised to the vapour floor
W_E_MECH: int = 15      #: mechanical energy out, J
W_E_IN: int = 16        #: energy in (battery chemistry or supply), J
W_E_IN_DRAWN: int = 17  #: energy drawn (positive input only), J
W_E_ABS_FLOW: int = 18  #: energy throughput (the balance's scale), J
W_HEAT_TO_OIL: int = 19     #: heat into the oil, J
W_TEMP_K: int = 20      #: oil temperature, K
W_SOC: int = 21         #: battery state of charge
W_I_BAT: int = 22       #: battery current, A
W_P_MAX: int = 23       #: peak pressure so far, Pa
W_E_FLOOR: int = 24     #: the cavitation store (stepper module docstring), J
W_E_OVERLOAD: int = 25  #: bus energy beyond the battery's matched-load power, J
W_OVERLOAD_STEPS: int = 26  #: steps with the battery overloaded
# -- and its per-circuit arrays (offsets) -------------------------------------------------------
W_U: int = 0            #: the held inputs (U_NAMES, then the named actuated inputs)
W_CTRL: int = 0         #: the controller's slots
W_A: int = 0            #: the prediction's state offset a (Δy = a + b Δθ̇)
W_B: int = 0            #: its velocity gain b
W_E_LOSS: int = 0       #: energy of each named loss, J
W_E_SRATE: int = 0      #: energy of each store rate, J
W_E_STORE: int = 0      #: energy stored in each state, J
W_MON: int = 0          #: monitors' peaks
W_Y_MAX: int = 0        #: each state's peak
W_PROBE_INT: int = 0    #: each probe's time integral


# -- the circuit's own functions (generated beside the template) --------------------------------
def rhs_step(y, yo, th, thd, U, P, dy, F):
    """The right-hand side over a step from ``yo`` (each node's compliance the mean of ``1/B``
    over the step): writes ``dy`` and the flow vector ``F``."""


def rhs_columns(y, yo, th, thd, th2, thd2, U, P, dy, F, D, C, T, cols, thcol):
    """The right-hand side's Jacobian columns by forward differences, each perturbed point
    re-evaluating only the lines its perturbation reaches
    (:mod:`afo_mj.circuits.jacobian_columns`)."""


def controller(y, th, thd, cmd, h, P, W):
    """The circuit's controller: sets the held inputs from the command; returns U_CMD's
    value."""


def begin_extra(y, P, W):
    """Per-step hook before the controller (oil viscosity and density, bus voltage)."""


def close_extra(y, h, thd, P, W, F):
    """Per-step hook after the step (energy ledger entries, heat, peaks, monitors)."""


def clip_floor(y, P):
    """Raise pressures below the vapour floor to it; returns whether any was raised."""
