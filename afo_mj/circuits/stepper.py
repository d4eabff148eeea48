"""The one coupled stepper and replay loop of every circuit (source template).

These functions are written once, here, as plain Python. :mod:`afo_mj.circuits.codegen`
copies their source into each circuit's generated module beneath that circuit's straight-line
right-hand side ``rhs`` and compiles the module with numba (cached on disk): so every circuit
is stepped by this code, and the compiled call to ``rhs`` is direct (numba cannot cache a
function that takes another compiled function as an argument). The globals they use
(``rhs``, ``rhs_step``, ``controller``, ``close_extra``, ``begin_extra``, ``N_Y``, ``Y_TYP``,
``F_*``, ``W_*``, ``N_LOSS``, ``N_SRATE``, ``clip_floor``) are the generated module's.

Method (for a circuit driving one joint; MuJoCo supplies the joint's motion)
---------------------------------------------------------------------------
The state ``y`` (node pressures, shaft speeds, motor currents, valve positions) is advanced by
backward Euler over each MuJoCo step ``h`` with the joint velocity at the *end* of the step as
an input and the joint angle at the end of the step as MuJoCo's semi-implicit Euler makes it,
``θ_{n+1} = θ_n + h θ̇_{n+1}`` (so position-dependent forces, e.g. end stops and chamber
volumes, are implicit too: their stiffness reaches MuJoCo as damping ``h ∂τ/∂θ``). First a linearly
implicit (Rosenbrock) prediction ``(I − h J_y) Δy = h f(y_n, θ̇_n) + h J_θ̇ (θ̇_{n+1} − θ̇_n)``,
i.e. ``Δy = a + b Δθ̇``, makes the end-of-step joint torque affine in the unknown velocity,
``τ_{n+1} = τ_0 + G Δθ̇`` (``G ≤ 0``). MuJoCo's Euler/implicitfast integrators treat joint damping
implicitly, so the joint force ``τ_0 − G θ̇_n`` with extra damping ``−G`` integrates the end-of-step
torque together with the body: the torque never lags a step and a kHz hydraulic spring is stable
with the foot. After ``mj_step`` the new velocity closes the step: Newton iterations on
``y − y_n − h f(y, θ̇_{n+1}) = 0`` from the prediction; where they do not converge the step is
redone as adaptive sub-steps (halved on failure, doubled after success, down to
``MIN_SUBSTEP_FRACTION``) with the velocity ramped linearly, each a converged backward-Euler
step. Jacobians are forward differences of ``rhs``, each perturbed point re-evaluating only
the lines its perturbation reaches (``rhs_columns``, :mod:`afo_mj.circuits.jacobian_columns`:
bitwise the full evaluation, at ~40 % of its cost on the HAFO); systems are solved by Gaussian
elimination with partial pivoting (:func:`lu_factor`, :func:`lu_solve`).

The prediction's matrix ``I − h J_y`` (factored) and ``∂τ/∂y`` are kept and reused by the next
steps (a W-method: the linearly implicit step is consistent with any matrix and stays stable
with one close to the Jacobian; Steihaug & Wolfbrandt 1979, Math. Comp. 33:521; Hairer &
Wanner, *Solving ODEs II*, IV.7), as stiff solvers keep theirs (CVODE refreshes it every 20
steps or on slow Newton convergence; Hindmarsh et al. 2005, ACM TOMS 31:363). Each step still
evaluates ``f`` and ``∂f/∂θ̇`` fresh, so only the state coupling ages. The matrix is rebuilt
when it has served ``JAC_MAX_AGE`` steps, when the controller's actuated inputs moved by more
than ``JAC_INPUT_REL`` of their size since it was built (a valve switching), when the step
needed sub-steps, and when the torque MuJoCo integrated missed the step's end torque by more
than ``JAC_COUPLE_REL`` of the torque's size with a matrix from an earlier step (a miss with
one built in the step is the linearisation's own error, which a rebuild would not remove).
Where the step's Newton correction made a fresh
Jacobian (its chord iterations contracted less than tenfold), that one, factored, replaces the
kept matrix and ``∂τ/∂y`` (``jacobian_builds`` counts only the prediction's own builds). The
end state is the same converged backward-Euler step either way (within ``NEWTON_TOL``); what
the reuse changes is the prediction, i.e. the torque and damping handed to MuJoCo, by the
coupling error these rules bound.

The backward-Euler residual is written with ``rhs_step(y, y_old, …)``: the same right-hand side
with each node's oil compliance the mean of ``1/B`` over ``[p_old, p]``
(:func:`~afo_mj.hydraulics.laws.oil_mean_compliance_per_pa`) instead of ``1/B(p)``, so a step
changes a node's oil content by exactly its net inflow. With the tangent compliance a fast
compression of aerated oil (``1/B`` falls tenfold from 0.3 to 10 MPa with 1 % air) gained or
lost oil every transient, which a sealed circuit then kept as a pressure offset (the lab bench
against Radau: 3 % of span, 0.58 % with the mean). The prediction linearises the same residual.

Energy ledger: the input (battery chemistry ``∫V_oc I`` or the supply's ``∫P_bus``) equals the
joint's mechanical output, every named loss (right-point rule, consistent with backward Euler),
the stores' discrete work ``Σ c_k y_{k,n+1} (y_{k,n+1} − y_{k,n})`` (``c_k`` the state's
capacitance over the step, as in ``rhs_step``, its inductance or inertia at ``y_{n+1}``) and the
work done on the stores that are not states (fixed-pressure reservoirs, springs, end stops),
booked by the right-point rule. So the balance residual measures only the Newton tolerance.

A step whose solution has a pressure below the vapour floor is accepted with that pressure
raised to the floor (``clip_floor``): the node gains the volume ``ΔV = c_k r_k`` its flows did
not bring (``r_k = y_k − y_{k,n} − h f_k(y)``, the backward-Euler residual the clip leaves:
the cavitation / outgassing void the oil opens when it is drawn below the floor, which the
node's compliance cannot give). Summing the discrete work over the states,
``Σ c_k y_k (y_k − y_{k,n}) = h Σ c_k y_k f_k + Σ c_k y_k r_k``, and the right-hand side's
power balance ``Σ c_k y_k f_k = P_in − P_mech − Σ losses − Σ store rates`` hold for any ``y``;
so the states' stores book ``Σ c_k y_k r_k`` that no flow supplied (negative at a node below
the atmosphere: the gauge-referenced oil store falls as the pressure is raised towards it).
The void holds it: the store ``cavitation`` books ``−Σ c_k y_k r_k`` (``W_E_FLOOR``, the
ledger's ``stored_change_j["cavitation"]``); at the clipped node ``−y_k c_k r_k =
(p_atm − p_floor) ΔV``,
the work done opening the void against the pressure the ledger refers its stores to (the
atmosphere; positive), plus what the raised pressure changes in the states it couples to
(a pump's shaft, a piston) in the same step. The void is not a state: it is not closed
again (the node resumes from the floor with its oil as it was), so this store only grows
and, as the solver does not clip, is zero on a run that never reaches the floor.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:     # the generated module's globals (module docstring; stepper_globals)
    import math

    from afo_mj.circuits.buffer_views import view2, view3
    from afo_mj.circuits.stepper_globals import (
        F_CAP, F_HEAT, F_LOSS, F_PROBE, F_SRATE, F_TAU, N_CTRL, N_HELD, N_INPUT, N_LOSS, N_P,
        N_PROBE, N_SCRATCH, N_SRATE, N_U, N_U_HEAD, N_W, N_Y, S_WIDTH, U_CMD, U_INV_H, U_VBUS,
        W_A, W_B,
        W_CLIP_STEPS, W_CMD, W_COUPLE_SQ, W_CTRL, W_E_ABS_FLOW, W_E_FLOOR, W_E_LOSS, W_E_MECH,
        W_E_SRATE, W_E_STORE, W_G, W_HEAT_TO_OIL, W_I_BAT, W_NEWTON_FAIL, W_NEWTON_ITERS,
        W_P_MECH, W_SUBSTEPPED, W_SUBSTEPS, W_TAU, W_TAU0, W_TAU_END, W_TAU_MEAS, W_TEMP_K,
        W_THETA, W_THETA_DOT, W_U, Y_TYP, begin_extra, clip_floor, close_extra, controller,
        rhs_columns, rhs_step)
    from afo_mj.control.assistance import N_PH, PH_PHASE, phase_update, table_lookup
    from afo_mj.control.impedance import impedance_torque

#: Newton tolerance on the backward-Euler residual, per state, in units of ``Y_TYP``, for a
#: step of ``NEWTON_TOL_STEP_S``; a step ``h`` uses ``NEWTON_TOL h / NEWTON_TOL_STEP_S``. The
#: residual a step leaves is an error of the stores' content, and so of the energy ledger;
#: scaled with the step, the error over a second of simulation is the same at any step (a
#: 0.1 ms bench closes its ledger as a 1 ms walk does). 1e-8 at 1 ms is 1e-3 Pa on a pressure;
#: 1e-9 cost the HAFO's gait step half a Newton iteration more (3.5 against 3.0 a step).
NEWTON_TOL = 1e-8
NEWTON_TOL_STEP_S = 1e-3
#: A Newton iteration whose residual fell less than to this fraction of the last one's gives
#: up the matrix in use (the kept one for a fresh Jacobian; a fresh one for full Newton).
NEWTON_CONTRACT = 0.3
#: Secant corrections a Newton solve keeps on top of its factored matrix (Broyden).
BROYDEN_MAX = 6
#: Smallest sub-step, as a fraction of the MuJoCo step, before a step is accepted unconverged.
MIN_SUBSTEP_FRACTION = 1.0 / 1024.0
#: Steps a prediction matrix serves before it is rebuilt (module docstring).
JAC_MAX_AGE = 10
#: Relative change of any actuated input since the matrix was built that rebuilds it.
JAC_INPUT_REL = 0.5
#: Coupling miss ``|τ_MuJoCo − τ_end|`` over ``|τ_end| + 1 N·m`` that rebuilds the matrix.
JAC_COUPLE_REL = 1e-3

# scratch rows of the per-side scratch array S (``N_SCRATCH`` rows × ``S_WIDTH``):
# 0: [h, steps the kept prediction matrix has served (0: none), matrices built]; 1: f at the
# Newton iterate; 2: its power flows F; 3: y_old; 4: y_best; 5: Newton step; 6: f0; 7: F0;
# 8: y perturbed; 9: f perturbed; 10: F perturbed; 11: dτ/dy (kept with the matrix);
# 12: y_start; 13 … 13+N_Y: the Newton matrix; then the prediction's LU factors (kept); then
# N_Y rows of right-hand sides (2 columns); then the prediction factors' pivot row
# (13 + 3 N_Y), the Newton matrix's pivot row, and the actuated inputs the prediction matrix
# was built at; then the Jacobian columns' rows (:func:`column_views`): N_Y rows of perturbed
# (f, τ), the row at the moved joint motion, the perturbations


def lu_factor(M, piv, n):
    """Factor ``M`` in place into ``L U`` (Doolittle, partial pivoting): ``U`` on and above
    the diagonal, ``L``'s multipliers below it, the row swapped into step ``c`` in
    ``piv[c]``. With :func:`lu_solve` the prediction's matrix is eliminated once a step and
    each chord iteration only substitutes (``n²`` instead of ``n³/3`` operations)."""
    for c in range(n):
        p_ = c
        big = abs(M[c, c])
        for r_ in range(c + 1, n):
            if abs(M[r_, c]) > big:
                big = abs(M[r_, c])
                p_ = r_
        piv[c] = p_
        if p_ != c:
            for k in range(n):
                tmp = M[c, k]
                M[c, k] = M[p_, k]
                M[p_, k] = tmp
        inv = 1.0 / M[c, c]
        for r_ in range(c + 1, n):
            fac = M[r_, c] * inv
            M[r_, c] = fac
            if fac != 0.0:
                for k in range(c + 1, n):
                    M[r_, k] -= fac * M[c, k]


def lu_solve(M, piv, rhs_mat, n, ncol):
    """Solve ``M X = rhs`` in place with the factors of :func:`lu_factor`."""
    for c in range(n):          # the row interchanges first, in their order
        p_ = int(piv[c])
        if p_ != c:
            for k in range(ncol):
                tmp = rhs_mat[c, k]
                rhs_mat[c, k] = rhs_mat[p_, k]
                rhs_mat[p_, k] = tmp
    for c in range(n):          # then L (unit diagonal), whose rows were swapped with them
        for r_ in range(c + 1, n):
            fac = M[r_, c]
            if fac != 0.0:
                for k in range(ncol):
                    rhs_mat[r_, k] -= fac * rhs_mat[c, k]
    for c in range(n - 1, -1, -1):
        for k in range(ncol):
            s_ = rhs_mat[c, k]
            for j in range(c + 1, n):
                s_ -= M[c, j] * rhs_mat[j, k]
            rhs_mat[c, k] = s_ / M[c, c]


def scratch_views(S):
    """Named views of one side's scratch array: ``(f1, F1, yold, ybest, step, f0, F0, yp, fp,
    Fp, dtau, ystart, M, Mcopy, R)``."""
    n = N_Y
    return (S[1, :n], S[2], S[3, :n], S[4, :n], S[5, :n], S[6, :n], S[7], S[8, :n], S[9, :n],
            S[10], S[11, :n], S[12, :n], S[13:13 + n, :n], S[13 + n:13 + 2 * n, :n],
            S[13 + 2 * n:13 + 3 * n, :2])


def scratch_rows(n_y: int) -> int:
    """Rows of one side's scratch array for ``n_y`` states (the layout above)."""
    return 20 + 4 * n_y + 2 * BROYDEN_MAX


def column_views(S):
    """The Jacobian columns' views of one side's scratch array: ``(C, T, D)``, the perturbed
    ``(dy, τ)`` per state (``N_Y`` rows), at the moved joint motion, and the perturbations."""
    n = N_Y
    return (S[16 + 3 * n:16 + 4 * n, :n + 1], S[16 + 4 * n, :n + 1], S[17 + 4 * n, :n])


def broyden_views(S):
    """Newton's secant corrections in one side's scratch array: ``(Bu, Bw, r, r_prev)``,
    ``BROYDEN_MAX`` rows each of ``u`` and ``w`` and the current and last residuals."""
    n = N_Y
    b = 18 + 4 * n
    return (S[b:b + BROYDEN_MAX, :n], S[b + BROYDEN_MAX:b + 2 * BROYDEN_MAX, :n],
            S[b + 2 * BROYDEN_MAX, :n], S[b + 2 * BROYDEN_MAX + 1, :n])


def jacobian(y, yo, theta, theta_dot, h, U, P, S, M):
    """``M = I − h ∂f/∂y`` and ``∂τ/∂y`` (scratch row 11) at ``(y, θ̇)`` by forward
    differences, ``f`` the step's right-hand side from ``yo`` (:func:`rhs_step`), whose value
    and power flows at ``y`` the caller has left in scratch rows 1–2 (Newton evaluates them
    there just before). The perturbed evaluations are ``rhs_columns``'
    (:mod:`afo_mj.circuits.jacobian_columns`): each re-evaluates only what its state reaches,
    bitwise equal to a full evaluation."""
    (f1, F1, yold, ybest, step, f0, F0, yp, fp, Fp, dtau, ystart, Mw, Mc,
     R) = scratch_views(S)
    C, T, D = column_views(S)
    for j in range(N_Y):
        D[j] = 1e-7 * max(abs(y[j]), Y_TYP[j])
    rhs_columns(y, yo, theta, theta_dot, theta, theta_dot, U, P, fp, Fp, D, C, T, 1.0, 0.0)
    for j in range(N_Y):
        d = D[j]
        for k in range(N_Y):
            M[k, j] = -h * (C[j, k] - f1[k]) / d
        M[j, j] += 1.0
        dtau[j] = (C[j, N_Y] - F1[F_TAU]) / d


def linearise(y, P, W, S):
    """The prediction of the step ``h = S[0, 0]`` with the inputs held in ``W``: fills
    ``W[W_A + k]``, ``W[W_B + k]``, ``W[W_TAU0]``, ``W[W_G]``. The matrix ``I − h J_y`` and
    ``∂τ/∂y`` are rebuilt by forward differences, or reused from an earlier step (module
    docstring; ``S[0, 1]`` counts the steps they have served, 0 rebuilds them); ``∂f/∂θ̇`` is
    a forward difference every step. One ``rhs_columns`` call evaluates the base point and
    the perturbed ones."""
    h = S[0, 0]
    U = W[W_U:W_U + N_U]
    U[U_INV_H] = 1.0 / h
    theta, thd = W[W_THETA], W[W_THETA_DOT]
    (f1, F1, yold, ybest, step, f0, F0, yp, fp, Fp, dtau, ystart, M, Mc,
     R) = scratch_views(S)
    C, T, D = column_views(S)
    piv = S[13 + 3 * N_Y, :N_Y]
    ujac = S[15 + 3 * N_Y, :N_U]
    age = S[0, 1]
    if age > 0.0 and age < JAC_MAX_AGE:
        # the actuated inputs and the oil's state; not 1/h or the held values (they move
        # every step without changing the Jacobian's structure)
        for k in range(N_U - N_HELD):
            if k != U_INV_H and abs(U[k] - ujac[k]) > JAC_INPUT_REL * max(abs(U[k]),
                                                                          abs(ujac[k])):
                age = 0.0
    build = not (age > 0.0 and age < JAC_MAX_AGE)
    if build:
        for j in range(N_Y):
            D[j] = 1e-7 * max(abs(y[j]), Y_TYP[j])
    dv = 1e-7 * max(abs(thd), 1.0)
    rhs_columns(y, y, theta + h * thd, thd, theta + h * (thd + dv), thd + dv, U, P, f0, F0,
                D, C, T, 1.0 if build else 0.0, 1.0)
    tau0 = F0[F_TAU]
    if not build:
        S[0, 1] = age + 1.0
    else:
        S[0, 1] = 1.0
        S[0, 2] += 1.0
        for k in range(N_U):
            ujac[k] = U[k]
        for j in range(N_Y):
            d = D[j]
            for k in range(N_Y):
                Mc[k, j] = -h * (C[j, k] - f0[k]) / d
            Mc[j, j] += 1.0
            dtau[j] = (C[j, N_Y] - tau0) / d
        # the factors stay in Mc for this and later steps' predictions and chord iterations
        lu_factor(Mc, piv, N_Y)
    dtau_dv = (T[N_Y] - tau0) / dv
    for k in range(N_Y):
        R[k, 0] = h * f0[k]
        R[k, 1] = h * (T[k] - f0[k]) / dv
    lu_solve(Mc, piv, R, N_Y, 2)
    g = dtau_dv
    t0 = tau0
    for k in range(N_Y):
        W[W_A + k] = R[k, 0]
        W[W_B + k] = R[k, 1]
        t0 += dtau[k] * R[k, 0]
        g += dtau[k] * R[k, 1]
    W[W_TAU0] = t0
    W[W_G] = g


def newton(y, yold, h, theta, theta_dot, U, P, W, S, first_matrix):
    """Solve ``y − y_old − h f(y, θ̇) = 0`` by Newton from the guess in ``y`` (in place).
    Iterations reuse a factored matrix while each cuts the residual to ``NEWTON_CONTRACT`` of
    the last, first the prediction's (``first_matrix`` non-zero), then a fresh Jacobian made at
    the iterate where one contracted less (simplified Newton; Hairer & Wanner, *Solving ODEs II*,
    IV.8); where that one contracts less too, a fresh Jacobian every iteration (full Newton).
    Each iteration after the first also corrects the matrix's inverse by Broyden's second
    update (Broyden 1965, Math. Comp. 19:577; the form that needs the inverse only, kept as up
    to ``BROYDEN_MAX`` rank-one terms ``u wᵀ``, the residual change weighted by the states'
    scales), so that a kept matrix that has aged still converges superlinearly: on the HAFO's
    gait 3.75 residual evaluations a step instead of 4.0 with half the fresh Jacobians (0.13
    against 0.24 a step). A diverging or cycling iteration halves its last step (damped
    Newton) and drops the corrections. (``first_matrix`` is a float, not a bool: numba
    compiles a function once per literal argument, and ``True``/``False`` at the two call
    sites compiled this one, and all it calls, twice.)
    Leaves ``f`` and the power flows at the solution in scratch rows 1–2."""
    (f1, F1, yo_, ybest, step, f0, F0, yp, fp, Fp, dtau, ystart, Mw, Mcopy,
     R) = scratch_views(S)
    rv = R[:, :1]
    Bu, Bw, rcur, rprev = broyden_views(S)
    tol = NEWTON_TOL * h / NEWTON_TOL_STEP_S
    U[U_INV_H] = 1.0 / h
    err_prev = 1e300
    kept = first_matrix != 0.0
    own = False
    full = False
    nb = 0                      # secant corrections stored for the matrix in use
    have_prev = False           # the previous iteration's residual is in rprev
    for it in range(24):
        rhs_step(y, yold, theta, theta_dot, U, P, f1, F1)
        err = 0.0
        for k in range(N_Y):
            r_ = y[k] - yold[k] - h * f1[k]
            rv[k, 0] = -r_
            rcur[k] = r_
            e = abs(r_) / Y_TYP[k]
            if e > err:
                err = e
        if err < tol:
            return True
        if err > 1e4 * err_prev or (it >= 8 and err > err_prev):
            for k in range(N_Y):
                step[k] *= 0.5
                y[k] = ybest[k] + step[k]
            nb = 0
            have_prev = False
            continue
        if it > 0 and err > NEWTON_CONTRACT * err_prev:
            if kept:
                kept = False
            elif own:
                full = True
        fresh = not kept and (not own or full)
        err_prev = err
        W[W_NEWTON_ITERS] += 1.0
        if fresh:
            # the matrix in use did not serve: a Jacobian at this iterate (after a fresh one
            # that did not serve either, at every iterate: full Newton). In the step's own
            # solve it also replaces the kept prediction matrix (the next steps predict with
            # it); in a sub-step the next step rebuilds that one.
            kept = False
            own = True
            nb = 0
            have_prev = False
            jacobian(y, yold, theta, theta_dot, h, U, P, S, Mw)
            lu_factor(Mw, S[14 + 3 * N_Y, :N_Y], N_Y)
            if first_matrix != 0.0:
                for k in range(N_Y):
                    S[13 + 3 * N_Y, k] = S[14 + 3 * N_Y, k]
                    for j in range(N_Y):
                        Mcopy[k, j] = Mw[k, j]
                for k in range(N_U):
                    S[15 + 3 * N_Y, k] = U[k]
                S[0, 1] = 1.0
            else:
                S[0, 1] = 0.0
        if kept:
            lu_solve(Mcopy, S[13 + 3 * N_Y, :N_Y], rv, N_Y, 1)
        else:
            lu_solve(Mw, S[14 + 3 * N_Y, :N_Y], rv, N_Y, 1)
        # the step -H r with H the matrix's inverse and its secant corrections u w^T
        for k in range(N_Y):
            step[k] = rv[k, 0]
        for i in range(nb):
            c = 0.0
            for k in range(N_Y):
                c += Bw[i, k] * rcur[k]
            for k in range(N_Y):
                step[k] -= Bu[i, k] * c
        if have_prev and nb < BROYDEN_MAX:
            # Broyden's second ("bad") update, in the states' scales: the new inverse maps
            # the last residual change onto the last step; its correction is u = the step
            # just computed, w = D^2 dr / (dr^T D^2 dr) (module docstring)
            den = 0.0
            for k in range(N_Y):
                dr = rcur[k] - rprev[k]
                den += dr * dr / (Y_TYP[k] * Y_TYP[k])
            if den > 0.0:
                c = 0.0
                for k in range(N_Y):
                    dr = rcur[k] - rprev[k]
                    Bw[nb, k] = dr / (Y_TYP[k] * Y_TYP[k] * den)
                    Bu[nb, k] = step[k]
                    c += Bw[nb, k] * rcur[k]
                nb += 1
                for k in range(N_Y):
                    step[k] *= 1.0 - c
        for k in range(N_Y):
            rprev[k] = rcur[k]
        have_prev = True
        for k in range(N_Y):
            ybest[k] = y[k]
            y[k] += step[k]
        for k in range(N_Y):
            if not math.isfinite(y[k]):
                return False
    return False


def close_substep(y, yold, h, theta, theta_dot, P, W, S):
    """Accept the backward-Euler (sub-)step ``y_old → y`` of length ``h`` (power flows at
    ``y`` in scratch row 2): pressure floor (a clip books the energy of the void it opens,
    ``W_E_FLOOR``: module docstring), right-point ledger, then the circuit's own closing
    (battery, heat, monitors: ``close_extra``)."""
    f1 = S[1, :N_Y]
    F1 = S[2]
    U = W[W_U:W_U + N_U]
    if clip_floor(y, P):
        W[W_CLIP_STEPS] += 1.0
        rhs_step(y, yold, theta, theta_dot, U, P, f1, F1)
        for k in range(N_Y):
            W[W_E_FLOOR] -= F1[F_CAP + k] * y[k] * (y[k] - yold[k] - h * f1[k])
    tau = F1[F_TAU]
    W[W_E_MECH] += h * tau * theta_dot
    for k in range(N_LOSS):
        W[W_E_LOSS + k] += h * F1[F_LOSS + k]
    for k in range(N_SRATE):
        W[W_E_SRATE + k] += h * F1[F_SRATE + k]
    for k in range(N_Y):
        W[W_E_STORE + k] += F1[F_CAP + k] * y[k] * (y[k] - yold[k])
    W[W_HEAT_TO_OIL] += h * F1[F_HEAT]
    close_extra(y, h, theta_dot, P, W, F1)
    W[W_E_ABS_FLOW] += h * abs(tau * theta_dot)


def finish_step(y, P, W, theta_dot_new, S):
    """Second half of the coupled step: the new joint velocity closes it (module docstring).
    Returns the torque MuJoCo integrated (the prediction ``τ_0 + G Δθ̇``)."""
    h = S[0, 0]
    U = W[W_U:W_U + N_U]
    thd0 = W[W_THETA_DOT]
    dthd = theta_dot_new - thd0
    theta = W[W_THETA]
    f1 = S[1, :N_Y]
    F1 = S[2]
    yold = S[3, :N_Y]
    ystart = S[12, :N_Y]
    for k in range(N_Y):
        yold[k] = y[k]
        ystart[k] = y[k]
        y[k] += W[W_A + k] + W[W_B + k] * dthd
    tau = W[W_TAU0] + W[W_G] * dthd
    theta_end = theta + h * theta_dot_new
    if newton(y, yold, h, theta_end, theta_dot_new, U, P, W, S, 1.0):
        close_substep(y, yold, h, theta_end, theta_dot_new, P, W, S)
    else:
        W[W_SUBSTEPPED] += 1.0
        for k in range(N_Y):
            y[k] = ystart[k]
        pos = 0.0
        frac = 0.25
        while pos < 1.0 - 1e-12:
            if frac > 1.0 - pos:
                frac = 1.0 - pos
            for k in range(N_Y):
                yold[k] = y[k]
            thd = thd0 + (pos + frac) * dthd
            th_sub = theta + (pos + frac) * h * thd
            ok = newton(y, yold, frac * h, th_sub, thd, U, P, W, S, 0.0)
            if not ok and frac > MIN_SUBSTEP_FRACTION:
                for k in range(N_Y):
                    y[k] = yold[k]
                frac *= 0.5
                continue
            if not ok:
                W[W_NEWTON_FAIL] += 1.0
                for k in range(N_Y):
                    if not math.isfinite(y[k]):
                        y[k] = yold[k]
                rhs_step(y, yold, th_sub, thd, U, P, f1, F1)
            W[W_SUBSTEPS] += 1.0
            close_substep(y, yold, frac * h, th_sub, thd, P, W, S)
            pos += frac
            if ok:
                frac *= 2.0
    W[W_TAU] = tau
    W[W_TAU_END] = F1[F_TAU]
    W[W_COUPLE_SQ] += (tau - F1[F_TAU]) ** 2
    if S[0, 1] > 1.0 and abs(tau - F1[F_TAU]) > JAC_COUPLE_REL * (abs(F1[F_TAU]) + 1.0):
        # the prediction came from an older matrix (not one built or handed over in this
        # step): rebuild it
        S[0, 1] = 0.0
    W[W_P_MECH] = F1[F_TAU] * theta_dot_new
    return tau


def hold_inputs(y, Ps, Ws, theta, theta_dot, cmd, h):
    """Hold one side's inputs over the coming step: the joint motion, the viscosity and bus
    voltage (``begin_extra``), and the controller's actuated input from the command."""
    Ws[W_THETA] = theta
    Ws[W_THETA_DOT] = theta_dot
    begin_extra(y, Ps, Ws)
    Ws[W_CMD] = cmd
    Ws[W_U] = controller(y, theta, theta_dot, cmd, h, Ps, Ws)


def couple(y, Ps, Ws, Ss, theta_dot, out_s):
    """Linearise one side about its held inputs; ``out_s = (τ_0 − G θ̇_n, −G)``: the joint
    force and the extra joint damping for MuJoCo. A positive ``G`` (a rising friction branch)
    is never handed over as negative damping: it is applied at the current velocity."""
    linearise(y, Ps, Ws, Ss)
    g = Ws[W_G]
    if g > 0.0:
        Ws[W_G] = 0.0
        out_s[0] = Ws[W_TAU0]
        out_s[1] = 0.0
    else:
        out_s[0] = Ws[W_TAU0] - g * theta_dot
        out_s[1] = -g


def begin_step(Y, P, W, S, theta, theta_dot, cmd, out):
    """First half of the coupled step for every side ``s``: :func:`hold_inputs`, then
    :func:`couple` (``out[s]``: joint force and extra damping)."""
    for s in range(Y.shape[0]):
        hold_inputs(Y[s], P[s], W[s], theta[s], theta_dot[s], cmd[s], S[s, 0, 0])
        couple(Y[s], P[s], W[s], S[s], theta_dot[s], out[s])


def finish_all(Y, P, W, S, theta_dot_new, tau_out):
    """Second half for every side; ``tau_out[s]`` gets the delivered torque. Returns False
    when a state became non-finite."""
    ok = True
    for s in range(Y.shape[0]):
        tau_out[s] = finish_step(Y[s], P[s], W[s], theta_dot_new[s], S[s])
        for k in range(N_Y):
            if not math.isfinite(Y[s, k]):
                ok = False
    return ok


def run_load(buf, meta, theta0, theta_dot0, inertia, stiffness, damping, rest_angle,
             cmd, ext_torque, log):
    """The replay/bench loop of worn side 0 of the device buffer (:func:`device_views`) with
    the joint load simulated: a rigid inertia ``J`` on a torsional spring ``k`` (rest angle
    ``θ_r``) and damper ``c`` driven by the circuit and an external torque, integrated like
    MuJoCo integrates the walker (semi-implicit Euler with the device damping, the load's
    damping and the spring implicit):
    ``(J + h(c + D + h k)) θ̇_{n+1} = J θ̇_n + h(F − k(θ_n − θ_r) + τ_ext)``,
    ``θ_{n+1} = θ_n + h θ̇_{n+1}``. ``cmd[n]`` is the controller's command per step. ``log``
    (steps × columns) gets ``t, θ, θ̇, τ, u`` then every state. Returns the steps done
    (fewer when a state became non-finite). (Every array the stepper sees is a view of the
    buffer, as in gait, so that one compilation serves both.)"""
    Ya, Pa, Wa, Sa, ph, prof, V, outa, O = device_views(buf, meta)
    Y, P, W, S, out = Ya[:1], Pa[:1], Wa[:1], Sa[:1], outa[:1]
    th = V[V_THETA, :1]
    thd = V[V_THETA_DOT, :1]
    c1 = V[V_TAU_CMD, :1]
    vnew = V[V_THETA_DOT_NEW, :1]
    tau = V[V_TAU, :1]
    n = cmd.shape[0]
    h = S[0, 0, 0]
    th[0] = theta0
    thd[0] = theta_dot0
    for i in range(n):
        c1[0] = cmd[i]
        begin_step(Y, P, W, S, th, thd, c1, out)
        f = out[0, 0]
        d = out[0, 1]
        num = inertia * thd[0] + h * (f - stiffness * (th[0] - rest_angle) + ext_torque[i])
        vnew[0] = num / (inertia + h * (damping + d + h * stiffness))
        if not finish_all(Y, P, W, S, vnew, tau):
            return i
        th[0] += h * vnew[0]
        thd[0] = vnew[0]
        log[i, 0] = (i + 1) * h
        log[i, 1] = th[0]
        log[i, 2] = thd[0]
        log[i, 3] = tau[0]
        log[i, 4] = W[0, W_U]
        for k in range(N_Y):
            log[i, 5 + k] = Y[0, k]
    return n


def run_imposed(buf, meta, theta, theta_dot, cmd, imposed, slots, temp_k, sub, load, log):
    """The replay loop of worn side 0 of the device buffer with the joint motion imposed (a recorded
    angle and its velocity per sample, e.g. a bench record): the same coupled step with the measured
    velocity as the end velocity. Sample ``i`` → ``i + 1`` is ``sub`` equal steps of
    ``h = S[0, 0, 0]`` over which the angle, velocity and (when ``temp_k`` is not empty) the oil
    temperature are interpolated linearly and ``cmd[i]`` is held. ``imposed[i, j]`` (samples ×
    inputs, held likewise) replaces the held input ``U[slots[j]]`` after the controller has run: a
    measured actuated input (the motor voltage ``U_CMD``, a valve's command) drives the circuit
    whatever its controller computed. ``log`` (samples × columns) gets, at the end of each
    sample, ``t, θ, θ̇, τ, u`` (``τ`` the joint torque at the step's end), every state, every
    probe, then the battery current, the bus voltage and the oil temperature. Returns the
    samples done (fewer when a state became non-finite).

    ``load`` empty: the joint motion is imposed. ``load = (J, k, c, θ_r, θ_0, θ̇_0)``: the joint
    is a simulated load instead (a bench whose foot is free: the measured angle is an output,
    ``theta``/``theta_dot`` are not read), an inertia ``J`` on a torsional spring ``k`` (rest
    angle ``θ_r``) and damper ``c`` starting at ``(θ_0, θ̇_0)``, integrated in every sub-step
    as :func:`run_load` integrates it (semi-implicit Euler with the device's damping ``−G``,
    the load's damping and the spring implicit)."""
    Ya, Pa, Wa, Sa, ph, prof, V, outa, O = device_views(buf, meta)
    Y, P, W, S, out = Ya[:1], Pa[:1], Wa[:1], Sa[:1], outa[:1]
    th = V[V_THETA, :1]
    thd = V[V_THETA_DOT, :1]
    vnew = V[V_THETA_DOT_NEW, :1]
    tau = V[V_TAU, :1]
    n = cmd.shape[0]
    nt = theta.shape[0]
    h = S[0, 0, 0]
    nimp = slots.shape[0]
    loaded = load.shape[0] >= 6
    if loaded:
        th[0] = load[4]
        thd[0] = load[5]
    for i in range(n):
        i1 = i + 1 if i + 1 < nt else i
        for j in range(sub):
            f0 = j / sub
            f1 = (j + 1) / sub
            if temp_k.shape[0] > 0:
                W[0, W_TEMP_K] = temp_k[i] + f0 * (temp_k[i1] - temp_k[i])
            if not loaded:
                th[0] = theta[i] + f0 * (theta[i1] - theta[i])
                thd[0] = theta_dot[i] + f0 * (theta_dot[i1] - theta_dot[i])
            hold_inputs(Y[0], P[0], W[0], th[0], thd[0], cmd[i], h)
            for m in range(nimp):
                W[0, W_U + slots[m]] = imposed[i, m]
            couple(Y[0], P[0], W[0], S[0], thd[0], out[0])
            if loaded:
                num = load[0] * thd[0] + h * (out[0, 0] - load[1] * (th[0] - load[3]))
                vnew[0] = num / (load[0] + h * (load[2] + out[0, 1] + h * load[1]))
            else:
                vnew[0] = theta_dot[i] + f1 * (theta_dot[i1] - theta_dot[i])
            if not finish_all(Y, P, W, S, vnew, tau):
                return i
            if loaded:
                th[0] += h * vnew[0]
                thd[0] = vnew[0]
        log[i, 0] = (i + 1) * sub * h
        log[i, 1] = th[0] if loaded else theta[i1]
        log[i, 2] = vnew[0]
        log[i, 3] = W[0, W_TAU_END]
        log[i, 4] = W[0, W_U]
        for k in range(N_Y):
            log[i, 5 + k] = Y[0, k]
        for k in range(N_PROBE):
            log[i, 5 + N_Y + k] = S[0, 2, F_PROBE + k]
        c = 5 + N_Y + N_PROBE
        log[i, c] = W[0, W_I_BAT]
        log[i, c + 1] = W[0, W_U + U_VBUS]
        log[i, c + 2] = W[0, W_TEMP_K]
    return n


# ---- walking: the whole coupled step of every worn side in two compiled calls ---------------
# (CircuitDevice.begin_step / end_step with a gait-phase profile: one dispatch each per MuJoCo
# step instead of a Python loop over the sides; a call's cost grows with its number of array
# arguments, so every per-side array is a view of one buffer ``buf`` laid out by the int64
# array ``meta``: offsets M_*, then the walker side of each worn side.)

#: ``meta`` entries: offsets of Y, P, W, S, phase state, profile, V, out, O, stride limits;
#: then buffer length, worn sides, profile points, what the profile buffer holds
#: (``CMD_PROFILE`` a torque table, ``CMD_IMPEDANCE`` impedance rows); the worn sides' walker
#: indices follow
(M_Y, M_P, M_W, M_S, M_PH, M_PROFILE, M_V, M_OUT, M_O, M_LIM, M_END, M_NS,
 M_NPROF, M_CMD) = range(14)
N_META = 14
CMD_PROFILE, CMD_IMPEDANCE = 0, 1
#: rows of the per-worn-side work array ``V`` (N_V × sides)
V_THETA, V_THETA_DOT, V_TAU_CMD, V_THETA_DOT_NEW, V_TAU = range(5)
N_V = 5
#: rows of the per-walker-side output array ``O`` (N_O × 2)
O_FORCE, O_DAMPING, O_DELIVERED, O_COMMANDED, O_PHASE = range(5)
N_O = 5
#: the device log's first columns; the circuit's states and probes follow
LOG_HEADER = ("time_s", "commanded_torque_nm", "delivered_torque_nm", "measured_torque_nm",
              "phase", "actuated_input", "bus_voltage_v", "battery_current_a",
              "mechanical_power_w", "oil_temperature_k", "ankle_velocity_rad_s",
              "ankle_angle_rad")
N_LOG_HEAD = len(LOG_HEADER)
#: constants the generated module carries with the template
LAYOUT_CONSTANTS = ("M_Y", "M_P", "M_W", "M_S", "M_PH", "M_PROFILE", "M_V", "M_OUT", "M_O",
                    "M_LIM", "M_END", "M_NS", "M_NPROF", "M_CMD", "N_META", "V_THETA",
                    "V_THETA_DOT", "V_TAU_CMD", "V_THETA_DOT_NEW", "V_TAU", "N_V", "O_FORCE",
                    "O_DAMPING",
                    "O_DELIVERED", "O_COMMANDED", "O_PHASE", "N_O", "N_LOG_HEAD",
                    "CMD_PROFILE", "CMD_IMPEDANCE")


def device_views(buf, meta):
    """``(Y, P, W, S, phase_state, profile, V, out, O)``: views of the device buffer (float64,
    C-contiguous, laid out by ``meta``: :class:`afo_mj.circuits.device.CircuitDevice` sizes
    it to hold every block), made by :mod:`afo_mj.circuits.buffer_views` (a ``reshape``
    costs ~25 ns in numba: nine of them twice a step were a tenth of the HAFO's compiled
    gait step)."""
    ns = meta[M_NS]
    Y = view2(buf, meta[M_Y], ns, N_Y)
    P = view2(buf, meta[M_P], ns, N_P)
    W = view2(buf, meta[M_W], ns, N_W)
    S = view3(buf, meta[M_S], ns, N_SCRATCH, S_WIDTH)
    ph = view2(buf, meta[M_PH], ns, N_PH)
    prof = buf[meta[M_PROFILE]:meta[M_PROFILE] + meta[M_NPROF]]
    V = view2(buf, meta[M_V], N_V, ns)
    out = view2(buf, meta[M_OUT], ns, 2)
    O = view2(buf, meta[M_O], N_O, 2)
    return Y, P, W, S, ph, prof, V, out, O


def device_begin(t, angle2, velocity2, stance2, buf, meta):
    """First half of the coupled step of every worn side ``k`` (walker side
    ``meta[N_META + k]``): gait phase from the foot switch and the commanded torque from the
    tabulated profile (:mod:`afo_mj.control.assistance`) or, with ``meta[M_CMD] =
    CMD_IMPEDANCE``, the impedance rows (:func:`afo_mj.control.impedance.impedance_torque`),
    then :func:`begin_step`. Writes the joint force, extra damping, commanded torque and phase
    into ``O`` (walker sides)."""
    Y, P, W, S, phase_state, profile, V, out, O = device_views(buf, meta)
    lo = buf[meta[M_LIM]]
    hi = buf[meta[M_LIM] + 1]
    ns = meta[M_NS]
    th = V[V_THETA]
    thd = V[V_THETA_DOT]
    cmd = V[V_TAU_CMD]
    for k in range(ns):
        s = meta[N_META + k]
        th[k] = angle2[s]
        thd[k] = velocity2[s]
        ph = phase_update(phase_state[k], t, stance2[s] != 0, lo, hi)
        if meta[M_CMD] == CMD_IMPEDANCE:
            cmd[k] = impedance_torque(profile, ph, th[k], thd[k])
        else:
            cmd[k] = table_lookup(profile, ph)
        O[O_PHASE, s] = ph
    device_couple(buf, meta)


def device_couple(buf, meta):
    """:func:`begin_step` of every worn side with the angle, velocity and command held in
    ``V``; writes the joint force, extra damping and commanded torque into ``O`` (walker
    sides). The second half of :func:`device_begin`, and the whole of it for a device whose
    command comes from Python."""
    Y, P, W, S, phase_state, profile, V, out, O = device_views(buf, meta)
    ns = meta[M_NS]
    cmd = V[V_TAU_CMD]
    begin_step(Y, P, W, S, V[V_THETA], V[V_THETA_DOT], cmd, out)
    for k in range(ns):
        s = meta[N_META + k]
        O[O_FORCE, s] = out[k, 0]
        O[O_DAMPING, s] = out[k, 1]
        O[O_COMMANDED, s] = cmd[k]


def device_end(velocity2, buf, meta, log, k, t):
    """Second half for every worn side: :func:`finish_all` with the new joint velocities,
    delivered torques into ``O[O_DELIVERED]`` and, when ``k < log.shape[0]``, row ``k`` of the
    device log (steps × columns × sides: ``LOG_HEADER``, the states, the probes) at time
    ``t``. Returns 0 when a state became non-finite, 2 when the log row was written, 1
    otherwise."""
    Y, P, W, S, phase_state, profile, V, out, O = device_views(buf, meta)
    ns = meta[M_NS]
    vnew = V[V_THETA_DOT_NEW]
    tau = V[V_TAU]
    for j in range(ns):
        vnew[j] = velocity2[meta[N_META + j]]
    if not finish_all(Y, P, W, S, vnew, tau):
        return 0
    for j in range(ns):
        O[O_DELIVERED, meta[N_META + j]] = tau[j]
    if k >= log.shape[0]:
        return 1
    for j in range(ns):
        write_log_row(log[k, :, j], t, Y[j], W[j], S[j], phase_state[j, PH_PHASE], vnew[j])
    return 2


def write_log_row(row, t, y, W, S, phase, theta_dot):
    """One side's log row (``LOG_HEADER``, then the states, the probes at the step's end,
    from the power flows left in scratch row 2, the actuated inputs and the controller's
    slots). The angle is the step's end angle ``θ_n + h θ̇_{n+1}`` (MuJoCo's semi-implicit
    Euler)."""
    row[0] = t
    row[1] = W[W_CMD]
    row[2] = W[W_TAU]
    row[3] = W[W_TAU_MEAS]
    row[4] = phase
    row[5] = W[W_U + U_CMD]
    row[6] = W[W_U + U_VBUS]
    row[7] = W[W_I_BAT]
    row[8] = W[W_P_MECH]
    row[9] = W[W_TEMP_K]
    row[10] = theta_dot
    row[11] = W[W_THETA] + S[0, 0] * theta_dot
    for i in range(N_Y):
        row[N_LOG_HEAD + i] = y[i]
    c = N_LOG_HEAD + N_Y
    for i in range(N_PROBE):
        row[c + i] = S[2, F_PROBE + i]
    c += N_PROBE
    for i in range(N_INPUT):
        row[c + i] = W[W_U + N_U_HEAD + i]
    c += N_INPUT
    for i in range(N_CTRL):
        row[c + i] = W[W_CTRL + i]


#: template functions that return views: compiled inline into their callers (a compiled call
#: that returns a tuple of arrays reference-counts each of them, ~0.3 µs per call)
INLINE = (scratch_views, column_views, broyden_views, device_views)
#: the template functions, in the order the generated module defines them
TEMPLATE = (lu_factor, lu_solve, scratch_views, column_views, broyden_views, jacobian,
            linearise, newton, close_substep, finish_step, hold_inputs, couple, begin_step,
            finish_all, device_views,
            run_load, run_imposed, write_log_row, device_couple, device_begin, device_end)
