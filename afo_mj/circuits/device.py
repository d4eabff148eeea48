"""A generated circuit worn on a joint: the coupled-device protocol for MuJoCo, the replay
loops with the load simulated or imposed, and the energy ledger named per component.

``CircuitDevice`` speaks the protocol :func:`afo_mj.gait.walk.run_walk` and
:meth:`afo_mj.human.test_stand.AnkleTestStand.run_device` use (``coupled``, ``timestep_s``,
``begin_step`` → joint force and extra damping per walker side, ``end_step`` → delivered
torque), so any described circuit walks and runs on the test stand like the presets.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from afo_mj.control import assistance as asst
from afo_mj.control.impedance import impedance_table
from afo_mj.circuits import stepper
from afo_mj.circuits.circuit import Circuit
from afo_mj.circuits.codegen import CompiledCircuit, build
from afo_mj.circuits.components import CircuitError
from afo_mj.circuits.device_spec import DeviceSpec, regroup

SIDE_NAMES = ("right", "left")


class CircuitLog:
    """Preallocated per-step device signals, ``data[step, field, side]`` (one step's signals
    side by side in memory), written by the compiled ``device_end``: the header
    (:data:`afo_mj.circuits.stepper.LOG_HEADER`), every state by name, every probe by name,
    every actuated input by name, every controller slot as ``controller.<name>``."""

    def __init__(self, n: int, ns: int, fields):
        self.n = 0
        self.FIELDS = tuple(fields)
        self.data = np.zeros((n, len(self.FIELDS), ns))

    def arrays(self) -> dict:
        return {f: self.data[:self.n, i].copy() for i, f in enumerate(self.FIELDS)}


@dataclasses.dataclass(frozen=True)
class JointLoad:
    """A simulated joint load for :meth:`CircuitDevice.run_imposed`: a rigid inertia on a
    torsional spring and a viscous damper, ``J θ̈ = τ − k (θ − θ_r) − c θ̇`` (the bench's foot
    on its load spring; Newton's second law for a rotating body), starting at
    ``(θ_0, θ̇_0)``."""

    inertia_kg_m2: float
    stiffness_nm_rad: float = 0.0
    damping_nm_s_rad: float = 0.0
    rest_angle_rad: float = 0.0
    initial_angle_rad: float = 0.0
    initial_velocity_rad_s: float = 0.0

    def __post_init__(self):
        checks = (("inertia_kg_m2", self.inertia_kg_m2 > 0, "> 0"),
                  ("stiffness_nm_rad", self.stiffness_nm_rad >= 0, ">= 0"),
                  ("damping_nm_s_rad", self.damping_nm_s_rad >= 0, ">= 0"))
        for key, ok, allowed in checks:
            v = getattr(self, key)
            if not (math.isfinite(v) and ok):
                raise CircuitError(f"load.{key} = {v!r}; allowed: {allowed}")
        for key in ("rest_angle_rad", "initial_angle_rad", "initial_velocity_rad_s"):
            if not math.isfinite(getattr(self, key)):
                raise CircuitError(f"load.{key} = {getattr(self, key)!r}; allowed: finite")

    def row(self) -> np.ndarray:
        """The kernel's ``load`` argument ``(J, k, c, θ_r, θ_0, θ̇_0)``."""
        return np.array([self.inertia_kg_m2, self.stiffness_nm_rad, self.damping_nm_s_rad,
                         self.rest_angle_rad, self.initial_angle_rad,
                         self.initial_velocity_rad_s], dtype=float)


class CircuitDevice:
    """One compiled circuit per worn side, stepped with MuJoCo (the coupled-device protocol).

    The command per step is, in this order of precedence: ``torque_fn(t, angle, velocity)``
    (a torque for a torque controller, a voltage for ``open_loop``; bench tests), the
    tabulated ``profile`` of torque vs stride phase (+dorsiflexion, N·m,
    :mod:`afo_mj.control.assistance`) or the emulated ``impedance`` (rows of
    :func:`afo_mj.control.impedance.impedance_table`) with the phase estimated from the foot
    switch, or 0 (transparent). ``initial_state`` maps state labels to their values at t = 0
    (else the circuit's: pressures at ``options.initial_pressure_pa``, the rest at 0).
    ``max_steps`` > 0 keeps a device log of that many steps.

    ``circuit`` is a :class:`~afo_mj.circuits.device_spec.DeviceSpec` (a registered device,
    :mod:`afo_mj.devices.registry`: its initial state, log names, named ledger and mass budget
    come with it) or a bare description (compiled or not: the ledger by component, no
    masses). ``open_loop``: ``torque_fn`` gives the device's open-loop command (the motor
    voltage, a valve command) instead of a torque (:meth:`DeviceSpec.circuit_for`)."""

    coupled = True

    def __init__(self, circuit: Circuit | CompiledCircuit | DeviceSpec, sides=("right",),
                 timestep_s: float = 1e-3, torque_fn=None, profile=None, max_steps: int = 0,
                 min_stride_s: float = 0.4, max_stride_s: float = 3.0, impedance=None,
                 initial_state: dict | None = None, open_loop: bool = False):
        if isinstance(circuit, DeviceSpec):
            spec = circuit
            cc = build(spec.circuit_for(open_loop))
            if initial_state is None:
                initial_state = dict(spec.initial_state)
        else:
            cc = circuit if isinstance(circuit, CompiledCircuit) else build(circuit)
            spec = DeviceSpec.from_circuit(cc.circuit)
            if open_loop:
                spec.circuit_for(True)       # refused unless the controller is open loop
        if open_loop and torque_fn is None:
            raise CircuitError(f"device {spec.name!r}: open_loop needs a torque_fn giving the "
                               f"{spec.open_loop_channel} command")
        #: what the tools know about this device (:class:`DeviceSpec`)
        self.spec = spec
        self.params = spec.params
        self.open_loop = bool(open_loop)
        #: log column renames (generic name → the name consumers read); the columns are the
        #: same, only their keys in :meth:`CircuitLog.arrays` change
        self.log_names = dict(spec.log_names)
        bad = [s for s in sides if s not in SIDE_NAMES]
        if bad or not sides or len(set(sides)) != len(sides):
            raise CircuitError(f"device.sides = {list(sides)!r}; allowed: a non-empty subset "
                               "of ['right', 'left']")
        if not timestep_s > 0:
            raise CircuitError(f"device timestep_s = {timestep_s!r}; allowed: > 0")
        self.cc = cc
        self.k = k = cc.module
        self.sides = tuple(sides)
        self.side_index = np.array([SIDE_NAMES.index(s) for s in self.sides], dtype=np.int64)
        ns = len(self.sides)
        self.timestep_s = float(timestep_s)
        self.torque_fn = torque_fn
        if impedance is not None and profile is not None:
            raise CircuitError("device: both profile and impedance given; allowed: one")
        self.impedance = impedance
        self.transparent = profile is None and torque_fn is None and impedance is None
        if impedance is not None:
            profile = impedance_table(impedance)
        profile = (np.zeros(asst.TABLE_POINTS) if profile is None
                   else np.ascontiguousarray(profile, dtype=float))
        # one buffer, laid out by meta (stepper.device_views), so that the compiled
        # device_begin / device_end take two arrays instead of a dozen
        sizes = {k.M_Y: ns * k.N_Y, k.M_P: ns * k.N_P, k.M_W: ns * k.N_W,
                 k.M_S: ns * k.N_SCRATCH * k.S_WIDTH, k.M_PH: ns * asst.N_PH,
                 k.M_PROFILE: profile.shape[0], k.M_V: k.N_V * ns, k.M_OUT: ns * 2,
                 k.M_O: k.N_O * 2, k.M_LIM: 2}
        meta = np.zeros(k.N_META + ns, dtype=np.int64)
        off = 0
        for m in range(k.M_END):
            meta[m] = off
            off += sizes[m]
        meta[k.M_END], meta[k.M_NS], meta[k.M_NPROF] = off, ns, profile.shape[0]
        meta[k.M_CMD] = k.CMD_IMPEDANCE if impedance is not None else k.CMD_PROFILE
        meta[k.N_META:] = self.side_index
        self._meta = meta
        self._buf = np.zeros(off)
        (self.Y, self.P, self.W, self.S, self.phase_state, self.profile, self._V, self._out,
         self._O) = k.device_views(self._buf, meta)
        self.Y[:] = cc.y0
        for label, v in (initial_state or {}).items():
            if label not in cc.state_names:
                raise CircuitError(f"initial_state[{label!r}]; allowed: "
                                   f"{', '.join(cc.state_names)}")
            self.Y[:, cc.index(label)] = float(v)
        self.W[:, k.W_Y_MAX:k.W_Y_MAX + k.N_Y] = self.Y
        self.P[:] = cc.P
        self.S[:, 0, 0] = self.timestep_s
        for key, v in cc.w_init.items():
            self.W[:, getattr(k, "W_" + key)] = v
        self.W[:, k.W_P_MAX] = cc.circuit.options.initial_pressure_pa
        self.profile[:] = profile
        self.phase_state[:] = asst.new_phase_state(ns)
        self.stride_limits = (float(min_stride_s), float(max_stride_s))
        self._buf[meta[k.M_LIM]:meta[k.M_LIM] + 2] = self.stride_limits
        self._th, self._thd, self._cmd = (self._V[k.V_THETA], self._V[k.V_THETA_DOT],
                                          self._V[k.V_TAU_CMD])
        self._vnew, self._tau = self._V[k.V_THETA_DOT_NEW], self._V[k.V_TAU]
        self._O[k.O_PHASE] = -1.0
        self.force2, self.damping2 = self._O[k.O_FORCE], self._O[k.O_DAMPING]
        self.delivered2, self.commanded2 = self._O[k.O_DELIVERED], self._O[k.O_COMMANDED]
        self.phase2 = self._O[k.O_PHASE]
        self._out2 = (self.force2, self.damping2)
        self.log_fields = tuple(self.log_names.get(f, f) for f in (
            stepper.LOG_HEADER + tuple(cc.state_names) + tuple(cc.probe_names)
            + tuple(cc.input_names) + tuple(f"controller.{n}" for n in cc.ctrl_names)))
        self.log = CircuitLog(max_steps, ns, self.log_fields) if max_steps else None
        self._log_data = (self.log.data if self.log is not None
                          else np.zeros((0, len(self.log_fields), ns)))
        self.steps = 0
        self.t_s = 0.0
        if open_loop and spec.open_loop_switch is not None:
            self.P[:, cc.param_labels.index(spec.open_loop_switch)] = 1.0

    # -- masses ------------------------------------------------------------------------------
    def worn_masses(self) -> list:
        """:class:`afo_mj.human.walker.WornMass` items for the walker: the spec's mass budget
        on each worn side (ankle parts at the side's sites, the supply at the waist, a
        tethered supply not worn); none when the spec models no masses."""
        from afo_mj.human.walker import WornMass
        out = []
        for side in self.sides:
            suf = "r" if side == "right" else "l"
            for it in self.spec.masses or ():
                if it.site == "off_body":
                    continue
                site = "waist" if it.site == "waist" else f"{it.site}_{suf}"
                out.append(WornMass(site, it.mass_kg, f"{self.spec.mass_label}_{side}_{it.name}"))
        return out

    @property
    def mass_total_kg(self) -> float | None:
        """Worn mass, every worn side (a tethered supply is not counted); None when the spec
        models no masses."""
        if self.spec.masses is None:
            return None
        return len(self.sides) * sum(i.mass_kg for i in self.spec.masses
                                     if i.site != "off_body")

    @property
    def mass_at_ankle_kg(self) -> float | None:
        """Mass worn at one ankle (what the published 0.97 kg of the HAFO refers to)."""
        if self.spec.masses is None:
            return None
        return sum(i.mass_kg for i in self.spec.masses if i.site not in ("waist", "off_body"))

    # -- state by name -----------------------------------------------------------------------
    def state(self, name: str) -> np.ndarray:
        """The present value of state ``name`` (a circuit state label or its log name, e.g.
        ``"chamber_a_pa"``) on each worn side (a view)."""
        generic = {v: k for k, v in self.log_names.items()}.get(name, name)
        if generic not in self.cc.state_names:
            raise CircuitError(f"state = {name!r}; allowed: "
                               + ", ".join(self.log_names.get(n, n)
                                           for n in self.cc.state_names))
        return self.Y[:, self.cc.state_names.index(generic)]

    # -- coupled protocol --------------------------------------------------------------------
    def begin_step(self, t: float, angle_rad, velocity_rad_s, stance):
        """Hold the inputs, run the controller, linearise; returns views of the per-walker-side
        joint force and extra damping (length 2; arguments indexed by walker side)."""
        self.t_s = t
        if self.torque_fn is None:
            self.k.device_begin(t, angle_rad, velocity_rad_s, stance, self._buf, self._meta)
            return self._out2
        si = self.side_index
        for j in range(len(si)):
            s = si[j]
            self._th[j] = angle_rad[s]
            self._thd[j] = velocity_rad_s[s]
            self._cmd[j] = self.torque_fn(t, self._th[j], self._thd[j])
        self.k.device_couple(self._buf, self._meta)
        return self._out2

    def native_coupling(self):
        """The entry points and buffers a compiled loop steps this device with
        (:class:`afo_mj.circuits.native_entry.NativeCoupling`), or None when the command
        comes from a Python ``torque_fn`` (that device needs the Python loop). The loop calls
        ``begin``/``end`` as :meth:`begin_step`/:meth:`end_step` do and reports back with
        :meth:`native_finished`."""
        if self.torque_fn is not None:
            return None
        from afo_mj.circuits.native_entry import NativeCoupling, entry_points
        ep = entry_points(self.cc)
        return NativeCoupling(ep.begin_address, ep.end_address, self._buf, self._meta,
                              self._log_data, self.force2, self.damping2, self.delivered2)

    def native_finished(self, steps: int, last_t_s: float, failed: bool = False) -> None:
        """A compiled loop stepped this device ``steps`` times, the last one beginning at
        ``last_t_s``: the step counter, the log's length and the time move on as
        :meth:`end_step` would have moved them; ``failed`` (a state became non-finite in the
        last step) raises the error :meth:`end_step` raises."""
        if steps:
            self.t_s = float(last_t_s)
        if failed:
            self.steps += steps - 1
            if self.log is not None:
                self.log.n = min(self.steps, self.log.data.shape[0])
            raise FloatingPointError(
                f"circuit {self.cc.circuit.name!r}: a state became non-finite at t = "
                f"{self.t_s:.4f} s: {dict(zip(self.cc.state_names, self.Y[0].tolist()))}")
        self.steps += steps
        if self.log is not None:
            self.log.n = min(self.steps, self.log.data.shape[0])

    def end_step(self, velocity_new_rad_s):
        """Close the step with the joint velocity MuJoCo produced; returns the delivered
        torques (length 2, zero where not worn)."""
        n = self.steps
        code = self.k.device_end(velocity_new_rad_s, self._buf, self._meta, self._log_data, n,
                                 self.t_s + self.timestep_s)
        if not code:
            raise FloatingPointError(
                f"circuit {self.cc.circuit.name!r}: a state became non-finite at t = "
                f"{self.t_s:.4f} s: {dict(zip(self.cc.state_names, self.Y[0].tolist()))}")
        if code == 2:
            self.log.n = n + 1
        self.steps = n + 1
        return self.delivered2

    # -- ledger ----------------------------------------------------------------------------
    def ledger(self, j: int = 0) -> dict:
        """Energy ledger of worn side ``j`` (J): :meth:`component_ledger`, with, for a spec
        that names its ledger (:class:`~afo_mj.circuits.device_spec.LedgerGroups`), the
        losses and stores grouped by name, the electrical input drawn and regenerated, the
        hydraulic energy the pump delivered (the input less the upstream losses and store
        changes), the peak motor current, the oil temperature rise, the battery's state of
        charge, the sub-stepped step count and the spec's extra figures."""
        g = self.component_ledger(j)
        groups = self.spec.ledger
        if groups is None:
            return g
        W, kk = self.W[j], self.k
        what = f"device {self.spec.name!r}"
        losses = regroup(g["losses_j"], groups.losses, f"{what} losses")
        stored = regroup(g["stored_change_j"], groups.stores, f"{what} stores")
        e_in, drawn = g["input_j"], g["input_drawn_j"]
        hydraulic = (e_in - sum(losses[n] for n in groups.upstream_losses)
                     - sum(stored[n] for n in groups.upstream_stores))
        ilim = self.spec.current_limit_a
        g.update({
            "electrical_in_j": e_in, "electrical_drawn_j": drawn,
            "electrical_regenerated_j": drawn - e_in, "hydraulic_j": hydraulic,
            "losses_j": losses, "stored_change_j": stored,
            "peak_current_a": (g["monitors"]["motor.current_over_limit"] * ilim
                               if ilim is not None else None),
            "temperature_rise_k": float(W[kk.W_TEMP_K]
                                        - self.cc.circuit.thermal.ambient_temperature_k),
            "soc": float(W[kk.W_SOC]), "substeps": int(W[kk.W_SUBSTEPS])})
        for key, (section, entry) in self.spec.ledger_extras.items():
            g[key] = g[section][entry]
        return g

    def component_ledger(self, j: int = 0) -> dict:
        """Energy ledger of worn side ``j`` (J): input, mechanical output, every loss and
        store by component instance (and ``cavitation``: the void opened where a pressure was
        clipped at the vapour floor, :mod:`afo_mj.circuits.stepper`; ``battery_overload``: the
        bus energy beyond the battery's matched-load power,
        :class:`~afo_mj.circuits.components.Battery`), and the balance
        residual; with each state's peak over the run (``state_peaks``, from its initial
        value) and each probe's time integral
        (``probe_integrals``: a flow probe's volume, m³)."""
        k, W, cc = self.k, self.W[j], self.cc
        losses = {n: float(W[k.W_E_LOSS + i]) for i, n in enumerate(cc.loss_names)}
        stored = {}
        for i, (name, kind, keeps) in enumerate(zip(cc.state_names, cc.state_kinds,
                                                    cc.state_stores)):
            if not keeps:
                continue
            label = {"pressure": "oil", "speed": "rotor"}.get(kind, "state")
            stored[f"{label}.{name}"] = float(W[k.W_E_STORE + i])
        for i, n in enumerate(cc.srate_names):
            stored[n] = float(W[k.W_E_SRATE + i])
        # the void a pressure clipped at the vapour floor opened (stepper module docstring)
        stored["cavitation"] = float(W[k.W_E_FLOOR])
        # bus energy beyond the battery's matched-load power (negative: made by the model;
        # afo_mj.circuits.components.Battery)
        stored["battery_overload"] = float(W[k.W_E_OVERLOAD])
        e_in = float(W[k.W_E_IN])
        e_out = float(W[k.W_E_MECH])
        resid = e_in - e_out - sum(losses.values()) - sum(stored.values())
        scale = max(float(W[k.W_E_ABS_FLOW]), 1e-12)
        return {"input_j": e_in, "input_drawn_j": float(W[k.W_E_IN_DRAWN]),
                "mechanical_out_j": e_out, "losses_j": losses, "stored_change_j": stored,
                "residual_j": resid, "balance_error_rel": resid / scale,
                "energy_throughput_j": scale,
                "heat_to_oil_j": float(W[k.W_HEAT_TO_OIL]),
                "peak_pressure_pa": float(W[k.W_P_MAX]),
                "monitors": {n: float(W[k.W_MON + i]) for i, n in enumerate(cc.monitor_names)},
                "state_peaks": {n: float(W[k.W_Y_MAX + i])
                                for i, n in enumerate(cc.state_names)},
                "probe_integrals": {n: float(W[k.W_PROBE_INT + i])
                                    for i, n in enumerate(cc.probe_names)},
                "newton_iterations": int(W[k.W_NEWTON_ITERS]),
                "jacobian_builds": int(self.S[j, 0, 2]),
                "newton_unconverged_steps": int(W[k.W_NEWTON_FAIL]),
                "substepped_steps": int(W[k.W_SUBSTEPPED]),
                "pressure_floor_steps": int(W[k.W_CLIP_STEPS]),
                "battery_overload_steps": int(W[k.W_OVERLOAD_STEPS]),
                "coupling_torque_error_rms_nm": float(np.sqrt(W[k.W_COUPLE_SQ]
                                                              / max(self.steps, 1)))}

    # -- replay loops ------------------------------------------------------------------------
    def _log_dict(self, log, n):
        out = {"time_s": log[:n, 0], "angle_rad": log[:n, 1], "velocity_rad_s": log[:n, 2],
               "torque_nm": log[:n, 3], "actuated_input": log[:n, 4]}
        for i, name in enumerate(self.cc.state_names):
            out[name] = log[:n, 5 + i]
        return out

    def run_load(self, command, inertia_kg_m2: float, stiffness_nm_rad: float = 0.0,
                 damping_nm_s_rad: float = 0.0, rest_angle_rad: float = 0.0,
                 theta0_rad: float = 0.0, external_torque_nm=None) -> dict:
        """Drive a simulated load (inertia on a torsional spring and damper) with the
        per-step ``command`` (side 0 only). Returns the logged signals per step."""
        cmd = np.ascontiguousarray(command, dtype=float)
        ext = (np.zeros_like(cmd) if external_torque_nm is None
               else np.ascontiguousarray(external_torque_nm, dtype=float))
        if not inertia_kg_m2 > 0:
            raise CircuitError(f"load inertia_kg_m2 = {inertia_kg_m2!r}; allowed: > 0")
        log = np.zeros((cmd.shape[0], 5 + len(self.cc.state_names)))
        n = self.k.run_load(self._buf, self._meta, float(theta0_rad),
                            0.0, float(inertia_kg_m2), float(stiffness_nm_rad),
                            float(damping_nm_s_rad), float(rest_angle_rad), cmd, ext, log)
        self.steps += n
        if n < cmd.shape[0]:
            raise FloatingPointError(f"circuit {self.cc.circuit.name!r}: non-finite state "
                                     f"at step {n}")
        return self._log_dict(log, n)

    def input_slot(self, name: str) -> int:
        """Index into the held input vector ``U`` of an actuated input: ``"command"`` (the
        controller's output, ``U_CMD``: the motor voltage of a motor-driven circuit) or a named
        input ``component.key`` (:attr:`CompiledCircuit.input_names`, e.g. a valve's
        ``servo.command``)."""
        from afo_mj.circuits.codegen import U_NAMES
        if name == "command":
            return 0
        if name in self.cc.input_names:
            return len(U_NAMES) + self.cc.input_names.index(name)
        raise CircuitError(f"imposed input {name!r}; allowed: command, "
                           f"{', '.join(self.cc.input_names) or '(no named inputs)'}")

    def run_imposed(self, command, angle_rad, velocity_rad_s, inputs=None, temperature_k=None,
                    substeps: int = 1, load: "JointLoad | None" = None) -> dict:
        """Replay with the joint motion imposed (per-sample angle and velocity, side 0).

        ``command`` is the controller's command per sample; ``inputs`` maps actuated inputs
        (:meth:`input_slot` names) to per-sample values that replace what the controller set
        (a measured motor voltage or valve command); ``temperature_k`` imposes the oil
        temperature per sample (else the lumped thermal model runs); each sample interval is
        ``substeps`` steps of ``timestep_s``. Returns the logged signals per sample (the state
        at the end of each interval): ``time_s, angle_rad, velocity_rad_s, torque_nm,
        actuated_input``, the states and probes by name, ``battery_current_a``,
        ``bus_voltage_v``, ``oil_temperature_k``.

        ``load`` (a :class:`JointLoad`): the joint is not imposed but simulated, an inertia on
        a spring and damper driven by the circuit (a bench whose foot is free); the angle and
        velocity arrays then only fix the sample count and ``angle_rad``/``velocity_rad_s`` of
        the log are the simulated motion."""
        cmd = np.ascontiguousarray(command, dtype=float)
        th = np.ascontiguousarray(angle_rad, dtype=float)
        thd = np.ascontiguousarray(velocity_rad_s, dtype=float)
        n = cmd.shape[0]
        names = list(inputs or {})
        slots = np.array([self.input_slot(k) for k in names], dtype=np.int64)
        imposed = np.zeros((n, len(names)))
        for j, k in enumerate(names):
            imposed[:, j] = np.asarray(inputs[k], dtype=float)[:n]
        temp = (np.zeros(0) if temperature_k is None
                else np.ascontiguousarray(temperature_k, dtype=float))
        if temp.shape[0] not in (0, th.shape[0]):
            raise CircuitError(f"temperature_k has {temp.shape[0]} samples; allowed: "
                               f"{th.shape[0]} (one per angle sample)")
        if th.shape[0] < n or thd.shape[0] < n:
            raise CircuitError(f"run_imposed: {n} commands for {th.shape[0]} angles; allowed: "
                               "at least one angle and velocity per command")
        sub = int(substeps)
        if sub < 1:
            raise CircuitError(f"run_imposed substeps = {substeps!r}; allowed: >= 1")
        if temp.shape[0]:
            self.W[0, self.k.W_TEMP_K] = temp[0]
        ny, npr = len(self.cc.state_names), len(self.cc.probe_names)
        log = np.zeros((n, 8 + ny + npr))
        load_row = np.zeros(0) if load is None else load.row()
        done = self.k.run_imposed(self._buf, self._meta, th, thd,
                                  cmd, imposed, slots, temp, sub, load_row, log)
        self.steps += done * sub
        if done < n:
            raise FloatingPointError(f"circuit {self.cc.circuit.name!r}: non-finite state "
                                     f"at sample {done}")
        out = self._log_dict(log, done)
        for i, name in enumerate(self.cc.probe_names):
            out[name] = log[:done, 5 + ny + i]
        for i, name in enumerate(("battery_current_a", "bus_voltage_v", "oil_temperature_k")):
            out[name] = log[:done, 5 + ny + npr + i]
        return out
