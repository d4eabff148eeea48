"""The hand-written compiled kernels as devices: the independent reference of the equivalence
tests.

Before the circuits were generated from components (:mod:`afo_mj.circuits`, issue 18), each
device was one hand-written numba kernel with a coupled-step API (``device_layout`` /
``device_views``, ``begin_step``, ``device_begin`` / ``device_end``, ``W_*`` / ``LOSS_INDEX``):
:mod:`pump_kernel` (the HAFO) and :mod:`valve_kernel` (the valve orthoses). The package now
steps only generated circuits; these kernels, written separately from the generator, stay here
so that the tests can hold every preset's generated circuit to them (``test_hafo_circuit``,
``test_hafo_device``, ``test_valve_circuits``) and ``benchmarks/circuits.py`` can time them.
:class:`KernelDevice` gives them the coupled-device protocol; :func:`pack_parameters` and
:func:`pack_valve_parameters` pack their parameter rows.
"""

from __future__ import annotations

import math

import numpy as np

from component_reference import Cylinder, ServoValve
from kernel_reference import pump_kernel as pa
from kernel_reference import valve_kernel as va
from afo_mj.circuits.device import SIDE_NAMES
from afo_mj.control import assistance as asst
from afo_mj.control.impedance import impedance_table
from afo_mj.devices.hafo import HafoDevice, PumpAnkleParams
from afo_mj.devices.valve_afo import VALVE_PRESETS, ValveAfoDevice, ValveAnkleParams
from afo_mj.hydraulics.fluid import ATMOSPHERIC_PRESSURE_PA, Fluid
from afo_mj.hydraulics.params import ParameterError

__all__ = ["KernelDevice", "KernelLog", "HafoKernelDevice", "ValveKernelDevice",
           "pack_parameters", "pack_valve_parameters"]


class KernelDevice:
    """A device stepped by one of the hand-written compiled kernels
    (:mod:`pump_kernel`, :mod:`valve_kernel`:
    the same coupled-step API and buffer layout), with the coupled-device protocol of
    :class:`~afo_mj.circuits.device.CircuitDevice`. Subclasses name the ``kernel`` and its
    ``loss_names`` and give ``_pack`` (parameter row), ``_initial_state`` and
    ``_kernel_begin_step`` (the bench path's begin step).

    ``begin_step(t, angle, velocity, stance)`` → ``(joint_force, joint_damping)`` per walker
    side (zeros where not worn); MuJoCo steps; ``end_step(velocity_new)`` → delivered torque.
    ``profile`` is a tabulated torque vs stride phase (+dorsiflexion, N·m,
    :mod:`afo_mj.control.assistance`) or ``None`` (transparent: zero commanded torque).
    ``torque_fn(t, angle, velocity) -> N·m`` replaces the profile (bench tests); with
    ``mode="voltage"`` it returns the motor voltage instead (open-loop bench tests).
    """

    coupled = True
    #: the compiled kernel module that steps it (set by the subclass)
    kernel = None
    #: the ledger's loss names, in the order of the kernel's ``LOSS_INDEX``
    loss_names = ()

    def __init__(self, params, sides=("right",),
                 profile: np.ndarray | None = None, timestep_s: float = 1e-3,
                 max_steps: int = 0, mode: str = "torque", torque_fn=None,
                 initial_pressure_pa: float | None = None, min_stride_s: float = 0.4,
                 max_stride_s: float = 3.0):
        if mode not in ("torque", "voltage"):
            raise ParameterError(f"device.mode = {mode!r}; allowed: torque, voltage")
        bad = [s for s in sides if s not in SIDE_NAMES]
        if bad or not sides or len(set(sides)) != len(sides):
            raise ParameterError(f"device.sides = {list(sides)!r}; allowed: a non-empty subset "
                                 "of ['right', 'left']")
        self.params = params
        self.sides = tuple(sides)
        self.side_index = np.array([SIDE_NAMES.index(s) for s in self.sides], dtype=np.int64)
        ns = len(self.sides)
        self.mode = mode
        self.transparent = profile is None and torque_fn is None
        profile = (np.zeros(asst.TABLE_POINTS) if profile is None
                   else np.ascontiguousarray(profile, dtype=float))
        self.torque_fn = torque_fn
        self.timestep_s = float(timestep_s)
        # Every per-side float array is a view of one buffer, laid out by ``_meta``
        # (kernel.device_layout), so that the compiled step (device_begin / device_end)
        # takes two arrays instead of a dozen: the call overhead grows with their number.
        K = self.kernel
        self._meta = K.device_layout(ns, profile.shape[0], self.side_index)
        self._buf = np.zeros(self._meta[K.M_END])
        (self.Y, self.P, self.W, self.S, self.phase_state, self.profile, self._V, self._out,
         self._O) = K.device_views(self._buf, self._meta)
        self.P[:] = self._pack(params, mode)
        self.profile[:] = profile
        p0 = params.reservoir_pressure_pa if initial_pressure_pa is None else initial_pressure_pa
        self._initial_state(p0)
        self.W[:, K.W_SOC] = params.initial_soc
        self.W[:, K.W_TEMP_K] = params.ambient_temperature_k
        self.W[:, K.W_P_MAX] = p0
        self.S[:, 0, 0] = self.timestep_s
        self.phase_state[:] = asst.new_phase_state(ns)
        self.stride_limits = (float(min_stride_s), float(max_stride_s))
        self._buf[self._meta[K.M_LIM]:self._meta[K.M_LIM] + 2] = self.stride_limits
        # per-worn-side work rows and per-walker-side outputs: views of the rows of V and O
        self._theta, self._thd, self._cmd = (self._V[K.V_THETA], self._V[K.V_THETA_DOT],
                                             self._V[K.V_TAU_CMD])
        self._vnew, self._tau = self._V[K.V_THETA_DOT_NEW], self._V[K.V_TAU]
        self._O[K.O_PHASE] = -1.0
        self.force2, self.damping2 = self._O[K.O_FORCE], self._O[K.O_DAMPING]
        self.delivered2, self.commanded2 = self._O[K.O_DELIVERED], self._O[K.O_COMMANDED]
        self.phase2 = self._O[K.O_PHASE]
        self._out2 = (self.force2, self.damping2)
        self.steps = 0
        self.log = KernelLog(max_steps, ns, K.LOG_FIELDS) if max_steps else None
        self._log_data = (self.log.data if self.log is not None
                          else np.zeros((0, len(K.LOG_FIELDS), ns)))
        self.t_s = 0.0

    # -- stepping ------------------------------------------------------------------------------
    def begin_step(self, t: float, angle_rad, velocity_rad_s, stance):
        """Hold inputs, compute the commanded torque and linearise (see module docs of
        :mod:`pump_kernel`); returns views of the per-walker-side
        joint force and extra damping (length 2). The arguments are numpy arrays indexed by
        walker side (0 right, 1 left)."""
        self.t_s = t
        if self.torque_fn is None:
            # phase estimate, profile lookup and linearisation in one compiled call
            self.kernel.device_begin(t, angle_rad, velocity_rad_s, stance, self._buf,
                                     self._meta)
            return self._out2
        si = self.side_index
        th, thd, cmd = self._theta, self._thd, self._cmd
        for k in range(len(si)):
            s = si[k]
            th[k] = angle_rad[s]
            thd[k] = velocity_rad_s[s]
            cmd[k] = self.torque_fn(t, th[k], thd[k])
        self._kernel_begin_step(th, thd, cmd, t)
        f2, d2 = self.force2, self.damping2
        for k in range(len(si)):
            f2[si[k]] = self._out[k, 0]
            d2[si[k]] = self._out[k, 1]
            self.commanded2[si[k]] = cmd[k]
        return self._out2

    def end_step(self, velocity_new_rad_s):
        """Close the step with the ankle velocity MuJoCo produced; returns delivered torques
        (length 2, zero where not worn)."""
        k = self.steps
        # finish_all, delivered torques and the log row in one compiled call
        code = self.kernel.device_end(velocity_new_rad_s, self._buf, self._meta, self._log_data, k,
                             self.t_s + self.timestep_s)
        if not code:
            raise FloatingPointError(
                f"{type(self).__name__} hydraulic state became non-finite at t = "
                f"{self.t_s:.4f} s: {dict(zip(self.kernel.STATE_NAMES, self.Y[0].tolist()))}")
        if code == 2:
            self.log.n = k + 1
        self.steps = k + 1
        return self.delivered2

    # -- results ---------------------------------------------------------------------------
    def ledger(self, k: int = 0) -> dict:
        """Energy ledger of worn side ``k`` (J), with the balance residual."""
        K = self.kernel
        W = self.W[k]
        losses = {n: float(W[i]) for n, i in zip(self.loss_names, K.LOSS_INDEX)}
        stored = {"inductance": float(W[K.W_E_STORE_L]), "rotor": float(W[K.W_E_STORE_ROT]),
                  "oil": float(W[K.W_E_STORE_OIL]),
                  # the reservoir gives energy when it feeds the lines: its store falls
                  "reservoir": float(W[K.W_E_RESERVOIR])}
        e_in = float(W[K.W_E_CHEM])
        e_out = float(W[K.W_E_MECH])
        resid = e_in - e_out - sum(losses.values()) - sum(stored.values())
        drawn = float(W[K.W_E_CHEM_DRAWN])
        scale = max(drawn, 1e-12)
        return {"electrical_in_j": e_in, "electrical_drawn_j": drawn,
                "electrical_regenerated_j": drawn - e_in, "mechanical_out_j": e_out,
                "balance_error_rel": resid / scale,
                "energy_throughput_j": float(W[K.W_E_ABS_FLOW]),
                "hydraulic_j": float(W[K.W_E_HYD]), "losses_j": losses,
                "stored_change_j": stored, "residual_j": resid,
                "heat_to_oil_j": float(W[K.W_HEAT_TO_OIL]),
                "peak_pressure_pa": float(W[K.W_P_MAX]),
                "peak_current_a": float(W[K.W_I_PEAK]),
                "temperature_rise_k": float(W[K.W_TEMP_K] - self.params.ambient_temperature_k),
                "soc": float(W[K.W_SOC]), "pressure_floor_steps": int(W[K.W_CLIP_STEPS]),
                "newton_iterations": int(W[K.W_NEWTON_ITERS]),
                "newton_unconverged_steps": int(W[K.W_NEWTON_FAIL]),
                "substepped_steps": int(W[K.W_SUBSTEPPED]),
                "substeps": int(W[K.W_SUBSTEPS]),
                "coupling_torque_error_rms_nm": float(np.sqrt(W[K.W_COUPLE_SQ]
                                                              / max(self.steps, 1)))}



class KernelLog:
    """Preallocated per-step device signals (per worn side): ``data[step, field, side]`` (one
    step's signals side by side in memory), written by the compiled
    kernel's ``device_end``."""

    def __init__(self, n: int, ns: int, fields=()):
        self.n = 0
        self.FIELDS = tuple(fields)
        self.data = np.zeros((n, len(self.FIELDS), ns))

    def arrays(self) -> dict:
        return {f: self.data[:self.n, i].copy() for i, f in enumerate(self.FIELDS)}


def pack_parameters(p: PumpAnkleParams, mode: float = pa.MODE_TORQUE) -> np.ndarray:
    """The flat parameter row the compiled kernel reads (``pump_kernel.P_*``)."""
    P = np.zeros(pa.N_P)
    m, dr, pu, ho, cy = p.motor, p.driver, p.pump, p.hose, p.cylinder
    fl = Fluid(p.fluid)
    cyl = Cylinder(cy)
    P[pa.P_R] = m.resistance_ohm
    P[pa.P_L] = m.inductance_h
    P[pa.P_K] = m.torque_constant_nm_a
    P[pa.P_J] = m.rotor_inertia_kg_m2 + pu.rotor_inertia_kg_m2
    P[pa.P_TC_M] = m.coulomb_torque_nm if m.friction_enabled else 0.0
    P[pa.P_BV_M] = m.viscous_coefficient_nm_s_rad if m.friction_enabled else 0.0
    P[pa.P_WC_M] = m.smoothing_speed_rad_s
    P[pa.P_I_LIM] = dr.current_limit_a
    P[pa.P_DUTY] = dr.max_duty
    P[pa.P_R_ON] = dr.on_resistance_ohm
    P[pa.P_P_Q] = dr.quiescent_power_w
    P[pa.P_CUR_LIM_ON] = 1.0 if dr.current_limit_enabled else 0.0
    if pu.variable_displacement_enabled:
        raise ParameterError("pump.variable_displacement_enabled = True; the pump-controlled "
                             "ankle uses a fixed-displacement pump (allowed: False)")
    P[pa.P_D] = pu.displacement_m3_rev / (2 * math.pi)
    P[pa.P_CS] = pu.slip_coefficient if pu.leakage_enabled else 0.0
    P[pa.P_CF] = pu.coulomb_coefficient if pu.coulomb_friction_enabled else 0.0
    P[pa.P_CV] = pu.viscous_coefficient if pu.viscous_friction_enabled else 0.0
    P[pa.P_T0] = pu.drag_torque_nm
    P[pa.P_WC_P] = pu.smoothing_speed_rad_s
    P[pa.P_HOSE_K] = 128.0 * ho.length_m / (math.pi * ho.bore_m ** 4)
    P[pa.P_V_HOSE] = p.hose_volume_m3
    P[pa.P_KWALL_INV] = 1.0 / ho.wall_bulk_modulus_pa if ho.wall_compliance_enabled else 0.0
    P[pa.P_A_E] = p.effective_area_m2
    P[pa.P_N_CYL] = p.cylinders
    P[pa.P_R_PULLEY] = p.pulley_radius_m
    P[pa.P_V_DEAD] = cy.dead_volume_a_m3
    P[pa.P_STROKE] = cy.stroke_m
    P[pa.P_G_LEAK] = cyl.leakage_conductance_m3 if cy.internal_leakage_enabled else 0.0
    if cy.seal_friction_enabled:
        ps, rs = cyl.piston_seal, cyl.rod_seal
        # one piston seal + two cable seals per cylinder, all sliding at the piston speed
        P[pa.P_SEAL_FC] = ps.coulomb_force_n + 2 * rs.coulomb_force_n
        P[pa.P_SEAL_STRIB] = ps._stribeck_gain + 2 * rs._stribeck_gain
        P[pa.P_SEAL_VST] = ps._v_st
        P[pa.P_SEAL_VC] = ps._v_c
        P[pa.P_SEAL_FV] = ps._fv + 2 * rs._fv
        P[pa.P_SEAL_CP] = ps._cp + 2 * rs._cp
    else:
        P[pa.P_SEAL_VST] = P[pa.P_SEAL_VC] = 1.0
    rv = p.relief
    P[pa.P_REL_CRACK] = rv.cracking_dp_pa
    P[pa.P_REL_OVER] = rv.override_dp_pa
    P[pa.P_REL_AMAX] = rv.max_area_m2
    P[pa.P_REL_ALEAK] = rv.leakage_area_m2 if rv.leakage_enabled else 0.0
    P[pa.P_REL_CD] = rv.discharge_coefficient
    P[pa.P_REL_PCR] = rv.transition_pressure_pa
    P[pa.P_FLUSH_G] = p.flushing_conductance_m3_s_pa
    P[pa.P_P_RES] = p.reservoir_pressure_pa
    P[pa.P_FLUSH_BAND] = p.flushing_band_pa
    P[pa.P_MAKEUP_G] = p.makeup_conductance_m3_s_pa
    P[pa.P_MAKEUP_BAND] = p.makeup_band_pa
    f = p.fluid
    P[pa.P_B_L] = f.liquid_bulk_modulus_pa
    P[pa.P_AIR] = f.air_fraction if f.entrained_air_enabled else 0.0
    P[pa.P_N_POLY] = f.polytropic_index
    P[pa.P_P_ATM] = ATMOSPHERIC_PRESSURE_PA
    P[pa.P_P_FLOOR] = f.pressure_floor_pa
    P[pa.P_RHO] = f.density_kg_m3
    P[pa.P_CAV_BAND] = f.cavitation_band_pa
    P[pa.P_V_PORT] = p.pump_port_volume_m3
    b = p.battery
    P[pa.P_BAT_R] = b.internal_resistance_ohm
    P[pa.P_BAT_NS] = b.cells_series
    P[pa.P_BAT_CAP_C] = 3600.0 * b.capacity_ah
    P[pa.P_C_TH] = p.heat_capacity_j_k
    P[pa.P_R_TH] = p.thermal_resistance_k_w
    P[pa.P_T_AMB] = p.ambient_temperature_k
    P[pa.P_WALTHER_B] = fl.walther_b
    P[pa.P_WALTHER_C] = fl.walther_c
    P[pa.P_RHO_T_COEF] = f.thermal_expansion_per_k
    P[pa.P_T_REF] = f.reference_temperature_k
    c = p.control
    P[pa.P_K_PRESSURE] = c.pressure_gain_rad_s_per_pa
    P[pa.P_K_SPEED] = c.speed_gain_v_s_per_rad
    P[pa.P_K_INT] = c.pressure_integral_gain_rad_per_pa
    P[pa.P_INT_LIM] = c.integral_limit_pa_s
    P[pa.P_MODE] = mode
    return P


_SUPPLY_CODE = {"constant_speed": va.SUPPLY_CONSTANT_SPEED, "unloading": va.SUPPLY_UNLOADING,
                "pressure_control": va.SUPPLY_PRESSURE_CONTROL,
                "variable_displacement": va.SUPPLY_VARIABLE}


def pack_valve_parameters(p: ValveAnkleParams) -> np.ndarray:
    """The flat parameter row of :mod:`valve_kernel`: the HAFO
    kernel's row for the shared components, then this circuit's."""
    P = np.zeros(va.N_P)
    base = p.replace(pump=p.pump.replace(variable_displacement_enabled=False))
    P[:len(pack_parameters(base))] = pack_parameters(base)
    P[va.P_CIRCUIT] = va.CIRCUIT_SERVO if p.circuit == "servo" else va.CIRCUIT_DIGITAL
    P[va.P_SUPPLY] = _SUPPLY_CODE[p.supply_mode]
    a = p.accumulator
    P[va.P_ACC_ON] = 1.0 if p.accumulator_enabled else 0.0
    P[va.P_ACC_V0] = a.gas_volume_m3
    P[va.P_ACC_P0] = a.precharge_pressure_pa
    P[va.P_ACC_N] = a.polytropic_index
    P[va.P_ACC_BAND] = p.accumulator_blend_pa
    u = p.unloading
    P[va.P_UL_ON] = 1.0 if p.supply_mode == "unloading" else 0.0
    P[va.P_UL_CUT_OUT] = u.cut_out_pressure_pa
    P[va.P_UL_CUT_IN] = u.cut_in_pressure_pa
    P[va.P_UL_AMAX] = u.max_area_m2
    P[va.P_UL_ALEAK] = u.leakage_area_m2 if u.leakage_enabled else 0.0
    P[va.P_UL_TAU] = u.time_constant_s
    P[va.P_UL_BAND] = max(u.switching_band_pa, 1.0)
    P[va.P_UL_HYST] = 1.0 if u.hysteresis_enabled else 0.0
    P[va.P_UL_CD] = u.discharge_coefficient
    P[va.P_UL_PCR] = u.transition_pressure_pa
    sv = p.servo_valve
    S = ServoValve(sv)
    P[va.P_SV_AFULL] = p.servo_full_area_m2
    P[va.P_SV_LAP] = S.overlap_m / sv.spool_max_m
    P[va.P_SV_ALEAK] = S.leakage_area_m2
    P[va.P_SV_TAU] = 1.0 / (2 * math.pi * sv.natural_frequency_hz)
    P[va.P_SV_CD] = sv.discharge_coefficient
    P[va.P_SV_PCR] = sv.transition_pressure_pa
    P[va.P_SV_COIL_W] = p.servo_coil_power_w
    sw = p.switching_valve
    P[va.P_SW_AMAX] = sw.max_area_m2
    P[va.P_SW_ALEAK] = sw.leakage_area_m2 if sw.leakage_enabled else 0.0
    P[va.P_SW_TSW] = sw.switching_time_s
    P[va.P_SW_TAUS] = sw.approach_time_constant_s
    P[va.P_SW_ESW] = sw.switching_energy_j
    P[va.P_SW_HOLD] = sw.holding_power_w
    P[va.P_SW_CD] = sw.discharge_coefficient
    P[va.P_SW_PCR] = sw.transition_pressure_pa
    P[va.P_PWM_F] = p.pwm_frequency_hz
    P[va.P_RV_AMAX] = p.release_valve_area_m2
    P[va.P_CV_G] = p.check_valve_conductance_m3_s_pa
    P[va.P_CV_CRACK] = p.check_valve_cracking_pa
    P[va.P_CV_BAND] = 2e4
    P[va.P_V_MAN] = p.manifold_volume_m3
    c = p.valve_control
    P[va.P_W_SET] = p.motor_speed_rad_s
    P[va.P_W_MAX] = p.motor_speed_rad_s
    P[va.P_K_W_P] = c.supply.speed_gain_v_s_per_rad
    P[va.P_K_W_I] = c.supply.speed_integral_gain_v_per_rad
    P[va.P_WINT_LIM] = c.supply.speed_integral_limit_rad
    P[va.P_PS_FOLLOW] = 1.0 if p.supply_pressure_follows_demand else 0.0
    P[va.P_PS_SET] = p.supply_pressure_set_pa
    P[va.P_PS_MARGIN] = p.supply_pressure_margin_pa
    P[va.P_PS_MIN] = p.supply_pressure_min_pa
    P[va.P_K_PS_P] = c.supply.pressure_gain_rad_s_per_pa
    P[va.P_K_PS_I] = c.supply.pressure_integral_gain_rad_per_pa
    P[va.P_PSINT_LIM] = c.supply.pressure_integral_limit_pa_s
    P[va.P_VD_P_COMP] = p.compensator_pressure_pa
    P[va.P_VD_BAND] = p.compensator_band_pa
    P[va.P_VD_EMIN] = p.min_displacement_fraction
    P[va.P_K_V] = c.valve_gain_per_pa
    P[va.P_K_VI] = c.valve_integral_gain_per_pa_s
    P[va.P_VINT_LIM] = c.valve_integral_limit_pa_s
    P[va.P_TAU_MAX] = p.max_torque_nm
    P[va.P_CMD] = va.CMD_PROFILE
    return P


class HafoKernelDevice(KernelDevice):
    """The HAFO stepped by its hand-written kernel :mod:`pump_kernel`
    (what :class:`HafoDevice` was before the generated circuit): the reference of the
    equivalence tests and of the speed comparison. Same arguments as :class:`HafoDevice`;
    log and ledger under the same names."""

    kernel = pa
    loss_names = pa.LOSS_NAMES
    worn_masses = HafoDevice.worn_masses
    mass_total_kg = HafoDevice.mass_total_kg
    mass_at_ankle_kg = HafoDevice.mass_at_ankle_kg

    def _pack(self, params, mode: str) -> np.ndarray:
        return pack_parameters(params, pa.MODE_VOLTAGE if mode == "voltage" else pa.MODE_TORQUE)

    def _initial_state(self, p0: float) -> None:
        """Every pressure node at ``p0`` (gauge), the rest at zero."""
        self.Y[:, pa.Y_PPA:pa.Y_PCB + 1] = p0

    def _kernel_begin_step(self, th, thd, cmd, t: float) -> None:
        pa.begin_step(self.Y, self.P, self.W, self.S, th, thd, cmd, self._out)


class ValveKernelDevice(KernelDevice):
    """A :class:`ValveAnkleParams` orthosis stepped by the hand-written valve kernel
    (:mod:`valve_kernel`): what :class:`afo_mj.devices.valve_afo.ValveAfoDevice` was before
    the generated circuit, the reference of the equivalence tests.

    ``profile``: assistance torque vs stride phase, or ``impedance``: rows of
    :func:`impedance_table` (passive-AFO emulation, clutched spring, per-phase impedance), or
    ``torque_fn(t, θ, θ̇)`` (bench; with ``mode="valve_command"`` it returns the valve command
    ``u ∈ [−1, 1]`` instead, open loop); none of them: transparent (zero torque commanded).
    """

    kernel = va

    def __init__(self, params: ValveAnkleParams = VALVE_PRESETS["valve"], sides=("right",),
                 profile=None, impedance=None, timestep_s: float = 1e-3, max_steps: int = 0,
                 torque_fn=None, min_stride_s: float = 0.4, max_stride_s: float = 3.0,
                 mode: str = "torque"):
        if not isinstance(params, ValveAnkleParams):
            raise ParameterError(f"device params = {type(params).__name__}; allowed: "
                                 "ValveAnkleParams")
        if mode not in ("torque", "valve_command"):
            raise ParameterError(f"device.mode = {mode!r}; allowed: torque, valve_command "
                                 "(torque_fn returns the valve command u in [-1, 1])")
        if mode == "valve_command" and torque_fn is None:
            raise ParameterError("device.mode = 'valve_command' needs a torque_fn giving u")
        if impedance is not None and profile is not None:
            raise ParameterError("device: both profile and impedance given; allowed: one")
        self.impedance = impedance
        prof = impedance_table(impedance) if impedance is not None else profile
        self.loss_names = va.LOSS_NAMES if params.circuit == "servo" else va.LOSS_NAMES_DIGITAL
        super().__init__(params, sides=sides, profile=prof, timestep_s=timestep_s,
                         max_steps=max_steps, mode="torque", torque_fn=torque_fn,
                         initial_pressure_pa=params.reservoir_pressure_pa,
                         min_stride_s=min_stride_s, max_stride_s=max_stride_s)
        if mode == "valve_command":
            self.P[:, va.P_MODE] = va.MODE_VALVE_COMMAND
        if impedance is not None:
            self.P[:, va.P_CMD] = va.CMD_IMPEDANCE
            self.transparent = False
        self.W[:, va.W_PS_MAX] = self.Y[:, va.Y_PS]

    def _pack(self, params, mode: str) -> np.ndarray:
        return pack_valve_parameters(params)

    def _initial_state(self, p0: float) -> None:
        Y = self.Y
        Y[:, :] = 0.0
        for k in (va.Y_PP, va.Y_PVA, va.Y_PVB, va.Y_PCA, va.Y_PCB):
            Y[:, k] = p0
        ps = self.params.initial_supply_pressure_pa
        Y[:, va.Y_PS] = max(ps, p0)
        Y[:, va.Y_W] = (self.params.motor_speed_rad_s
                        if self.params.supply_mode != "pressure_control" else 0.0)
        if self.params.supply_mode == "unloading":
            # a charged accumulator below cut-out: the unloading valve is shut
            Y[:, va.Y_XU] = 0.0

    def _kernel_begin_step(self, th, thd, cmd, t: float) -> None:
        va.begin_step(self.Y, self.P, self.W, self.S, th, thd, cmd, self._out, t)

    worn_masses = ValveAfoDevice.worn_masses
    mass_total_kg = ValveAfoDevice.mass_total_kg
    mass_at_ankle_kg = ValveAfoDevice.mass_at_ankle_kg

    def ledger(self, k: int = 0) -> dict:
        out = super().ledger(k)
        W = self.W[k]
        out["peak_supply_pressure_pa"] = float(W[va.W_PS_MAX])
        out["pump_volume_m3"] = float(W[va.W_Q_PUMP])
        out["cylinder_volume_in_m3"] = float(W[va.W_Q_DELIVERED])
        return out
