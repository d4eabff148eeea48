"""A gymnasium environment over the steppable walk: learn or tune an ankle assistance
controller without editing the walk loop.

:class:`AnkleAssistEnv` (registered as ``afo_mj/AnkleAssist-v0``; vector form through
``gymnasium.make_vec``) steps the walker a walking scenario names at a chosen control rate
(the action is held over the MuJoCo steps of one control period): ``walker.model =
"torque"`` a :class:`afo_mj.gait.walk.Walk`, ``"muscle"`` a
:class:`afo_mj.gait.muscle_walk.MuscleWalkStepper` (the reflex walker of ``afo-mj run``:
stepped with a zero action to its end, its record is that walk's). The models are the
entries of :data:`afo_mj.gait.walkers.WALKER_MODELS`, the one place they are told
apart:

* **action** (2,): per side (right, left), either the ankle torque itself (``mode="torque"``,
  N·m, + dorsiflexion, within ±``max_torque_nm``: an ideal, massless device) or the torque
  command of a worn device, built as ``afo-mj run`` builds a condition
  (:func:`afo_mj.experiments.device_walk.make_device`; the command goes through its pump or
  valves, hoses and cylinders, which deliver what they can): with ``mode="device"`` the
  scenario's own device (its ``[device]`` preset, any HAFO or valve preset, or its
  ``[circuit]`` description, on its ``device.sides``; an unworn side's action is not used),
  with ``mode="hafo"`` the HAFO preset ``hafo_preset`` on both ankles whatever the scenario
  wears (the case of ``mode="device"`` whose scenario says ``[device] preset = hafo_preset,
  sides = ["right", "left"]``; it differs only in the energy term below). The command is the
  torque reference of the circuit's
  controller (``torque_fn`` of :class:`afo_mj.circuits.device.CircuitDevice`, the input the
  assistance profile drives in ``afo-mj run``); the scenario's ``[assistance]`` is not used.
  A device with no torque controller takes its open-loop command instead, as its spec names
  it (:attr:`AnkleAssistEnv.command_channel`: a circuit whose ``open_loop`` controller passes
  the command to the motor takes the motor voltage, V, within ± its supply: the battery's
  open-circuit voltage at full charge or the ideal supply's; :attr:`AnkleAssistEnv.action_limit`).
  The ideal preset (no circuit) is refused with ``mode="device"``. The worn
  device's masses are on the body (a described circuit has none);
* **observation** (:data:`OBSERVATION_NAMES`): joint angles and velocities of both legs, the
  phase per leg (torque walker: its controller's estimate; muscle walker: time since the
  leg's last heel strike over its last stride, 0 before its second) and the stance flags
  (the controller's foot switch), both feet's ground reaction forces per body
  weight, the pelvis speed, and the torque delivered at each ankle in the last step; with a
  worn device then its circuit's states per worn side (``hafo``: line and chamber pressures,
  shaft speed, motor current; ``device``: whatever its circuit's states are:
  :attr:`AnkleAssistEnv.observation_names`);
* **reward**: ``reward_fn(env)`` if given, else :func:`default_reward`, per control step:
  ``− w_track × mean squared angle error (rad², against the scenario's reference at each leg's
  phase) − w_effort × Σ (human ankle moment / (m g L))² − w_energy × P / (m g v)`` (the
  human ankle moment: the record's ``joint_moment_nm``, actuators or muscles; the
  first two at the end of the control step; ``L`` = 0.53 × stature, ``v`` the pelvis speed,
  at least 0.3 m/s) with ``P`` the mean over the control step of the device's electrical
  power (``device``: the energy drawn from the circuit's source, the ledger's
  ``input_drawn_j`` — a battery's chemical energy or an ideal supply's — over the control
  step's duration; ``hafo``: the power at the bus, battery current × bus voltage summed over
  both sides and counted when positive, kept as it was before ``device`` existed: it leaves
  out the battery's internal loss and nets one side's regeneration against the other's
  draw, so it reads about 11 % less than the ledger's drawn energy, 24.8 J against 28.0 J over
  1.5 s of random commands on ``gait_assist_hafo.toml``) or of the action's positive
  mechanical power (ideal); the terms of the last step are in :attr:`AnkleAssistEnv.last`;
  with a worn device the step's ``info`` adds the commanded and delivered torque per walker
  side (``device_commanded_torque_nm``, ``device_delivered_torque_nm``, N·m, zero where not
  worn) and :attr:`AnkleAssistEnv.device` is the device itself (its ``log``, its
  ``ledger(side)``);
* **termination** on a fall, **truncation** when the walk is over (torque walker: the
  scenario's strides done; muscle walker: ``afo-mj run``'s duration walked,
  :func:`afo_mj.gait.muscle_scenario.muscle_walk_duration_s`).

Example::

    import gymnasium as gym
    import afo_mj.experiments.walk_env  # registers the id
    env = gym.make("afo_mj/AnkleAssist-v0", scenario="scenarios/walk_healthy.toml")
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    dev = gym.make("afo_mj/AnkleAssist-v0", scenario="scenarios/gait_assist_valve.toml",
                   mode="device")              # the scenario's valve AFO, torque-commanded
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np

from afo_mj.gait.walkers import walker_model

__all__ = ["AnkleAssistEnv", "OBSERVATION_NAMES", "default_reward", "ENV_ID"]

ENV_ID = "afo_mj/AnkleAssist-v0"
OBSERVATION_NAMES = tuple(
    [f"{s}_{j}_angle_rad" for s in ("right", "left") for j in ("hip", "knee", "ankle")]
    + [f"{s}_{j}_velocity_rad_s" for s in ("right", "left") for j in ("hip", "knee", "ankle")]
    + ["right_phase", "left_phase", "right_stance", "left_stance"]
    + [f"{s}_grf_{c}_per_body_weight" for s in ("right", "left") for c in ("x", "z")]
    + ["pelvis_speed_m_s", "right_ankle_device_torque_nm", "left_ankle_device_torque_nm"])
GRAVITY_M_S2 = 9.81
MODES = ("torque", "hafo", "device")
#: the torque action's bound when ``max_torque_nm`` is not given, N·m
DEFAULT_MAX_TORQUE_NM = 60.0


def _command_fn(command: np.ndarray, sides):
    """The ``torque_fn`` that feeds a circuit device its commanded torque from ``command``
    (per walker side, right then left): the device asks once per worn side, in ``sides``
    order, every step (:meth:`afo_mj.circuits.device.CircuitDevice.begin_step`)."""
    idx = [("right", "left").index(s) for s in sides]
    n, calls = len(idx), [0]

    def torque_fn(t, th, thd):
        v = command[idx[calls[0] % n]]
        calls[0] += 1
        return v
    return torque_fn


def _supply_voltage_v(circuit) -> float:
    """The bound of a motor-voltage action: the circuit's battery at full charge (its
    open-circuit voltage, :meth:`~afo_mj.hydraulics.battery.BatteryParams.open_circuit_voltage_v`)
    or, without one, its ideal supply (``options.supply_voltage_v``)."""
    bats = [c for c in circuit.components if c.kind == "battery"]
    if bats:
        return float(bats[0].params.battery.open_circuit_voltage_v(1.0))
    return float(circuit.options.supply_voltage_v)


def default_reward(env: "AnkleAssistEnv", w_track: float = 1.0, w_effort: float = 1.0,
                   w_energy: float = 0.1) -> float:
    """Tracking, effort and energy of the last control step (module docstring)."""
    return -(w_track * env.last["track_rad2"] + w_effort * env.last["effort"]
             + w_energy * env.last["energy"])


class AnkleAssistEnv(gym.Env):
    """The assistance environment (module docstring). ``scenario``: a walking scenario file
    (its walker, reference, strides; its ``[device]`` or ``[circuit]`` is worn only in
    ``mode="device"``, which needs one; the env's ``mode`` says what the action drives);
    ``hafo_preset``: ``mode="hafo"``'s HAFO preset (:data:`afo_mj.devices.hafo.PRESETS`);
    ``control_rate_hz``: actions per second (the MuJoCo step
    must divide its period); ``overrides``: ``--set``-style scenario overrides. The walker is
    the one the scenario names (:data:`afo_mj.gait.walkers.WALKER_MODELS`)."""

    metadata = {"render_modes": []}

    def __init__(self, scenario="scenarios/walk_healthy.toml", mode: str = "torque",
                 control_rate_hz: float = 100.0, max_torque_nm: float | None = None,
                 reward_fn=None, overrides=(), hafo_preset: str = "hafo_gait"):
        from afo_mj.scenarios.walk_scenario import load_scenario
        if mode not in MODES:
            raise ValueError(f"mode = {mode!r}; allowed: {', '.join(map(repr, MODES))}")
        torque_given = max_torque_nm is not None
        max_torque_nm = DEFAULT_MAX_TORQUE_NM if max_torque_nm is None else max_torque_nm
        if not (math.isfinite(max_torque_nm) and 0 < max_torque_nm <= 200):
            raise ValueError(f"max_torque_nm = {max_torque_nm!r}; allowed: 0 < N·m <= 200")
        self.scenario = load_scenario(Path(scenario), overrides=list(overrides))
        self.walker_entry = walker_model(self.scenario, ENV_ID)
        self.reference = self.scenario.load_reference()
        self.cycle_time_s = self.scenario.cycle_time_s(self.reference)
        dt = self.scenario.walker.timestep_s
        sub = (1.0 / control_rate_hz) / dt if control_rate_hz > 0 else math.nan
        if not (math.isfinite(sub) and sub >= 1 and abs(sub - round(sub)) < 1e-9):
            raise ValueError(f"control_rate_hz = {control_rate_hz!r}; allowed: a rate whose "
                             f"period is a whole number of {dt * 1e3:g} ms MuJoCo steps")
        self.substeps = int(round(sub))
        self.mode, self.max_torque_nm, self.hafo_preset = mode, float(max_torque_nm), hafo_preset
        self._command = np.zeros(2)        # the commanded torque per walker side (N·m)
        self.device_config = (self._device_config(scenario) if mode == "device"
                              else self._hafo_config(hafo_preset) if mode == "hafo" else None)
        #: what the action is (per walker side): the torque (``commanded_torque_nm``: the
        #: ideal device, or a worn device's torque reference), or a worn open-loop circuit's
        #: command (``motor_voltage_v``), and its bound (N·m, or V: the circuit's supply)
        self.command_channel, self.action_limit = "commanded_torque_nm", self.max_torque_nm
        if self.device_config is not None:
            spec = self.device_config.device_spec()
            if not spec.torque_controlled:
                if torque_given:
                    raise ValueError(
                        f"max_torque_nm = {max_torque_nm!r} with a device that takes no torque "
                        f"command ({spec.name!r}: its action is {spec.open_loop_channel}, "
                        "bounded by its supply); allowed: leave max_torque_nm unset")
                self.command_channel = spec.open_loop_channel
                self.action_limit = _supply_voltage_v(spec.circuit)
        self._device_states: tuple[str, ...] = ()
        if self.device_config is not None:
            self._device_states = tuple(f"{side}_device.{n}" for side in self.device_config.sides
                                        for n in self._make_device(0).cc.state_names)
        self.reward_fn = reward_fn or default_reward
        self.action_space = gym.spaces.Box(-self.action_limit, self.action_limit, (2,),
                                           np.float64)
        # bounds: angles ±π, velocities ±100 rad/s, phase and stance 0…1, forces ±20 body
        # weights, speed ±20 m/s, device torques ±1000 N·m
        n_dev = len(self.observation_names) - len(OBSERVATION_NAMES)
        hi = np.array([math.pi] * 6 + [100.0] * 6 + [1.0] * 4 + [20.0] * 4 + [20.0]
                      + [1000.0] * 2 + [1e9] * n_dev)
        lo = -hi
        lo[12:16] = 0.0
        self.observation_space = gym.spaces.Box(lo, hi, dtype=np.float64)
        self.walk = None
        self.device = None
        self.last: dict = {}

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        sc = self.scenario
        self._command[:] = 0.0
        worn, self.device = (), None
        if self.device_config is not None:
            steps = int(self.walker_entry.duration(sc, self.reference)
                        / sc.walker.timestep_s) + 4
            self.device = self._make_device(steps)
            # a circuit description has no worn-mass layout (its parts' masses are metadata)
            wm = getattr(self.device, "worn_masses", None)
            worn = tuple(wm()) if wm is not None else ()
        self.walk = self.walker_entry.stepper(self.scenario, self.reference, self.device, worn)
        self.last = {"track_rad2": 0.0, "effort": 0.0, "energy": 0.0}
        return self._observation(), {"time_s": 0.0}

    def step(self, action):
        if self.walk is None:
            raise RuntimeError("AnkleAssistEnv.step before reset()")
        a = np.clip(np.asarray(action, float).reshape(2), -self.action_limit,
                    self.action_limit)
        if not np.all(np.isfinite(a)):
            what = ("torques (N·m)" if self.command_channel == "commanded_torque_nm"
                    else f"commands ({self.command_channel})")
            raise ValueError(f"action = {action!r}; allowed: two finite {what}")
        w = self.walk
        mg = w.phys.body_mass_kg * GRAVITY_M_S2
        leg = self.scenario.walker.height_m * 0.53            # leg length ~ 0.53 stature
        v_ref = max(w.pelvis_speed_m_s, 0.3)
        energy = 0.0
        n = 0
        for _ in range(self.substeps):
            if w.done:
                break
            if self.device is not None:
                self._command[:] = a
                w.step()
            else:
                w.step(a)
            n += 1
            d = self.device
            if self.mode == "hafo":     # the bus power (module docstring: not the ledger's)
                energy += max(float(np.sum(d.W[:, d.k.W_I_BAT] * d.W[:, d.k.W_U + d.k.U_VBUS])),
                              0.0)
            elif d is not None:
                drawn = float(np.sum(d.W[:, d.k.W_E_IN_DRAWN]))
                energy += (drawn - self._drawn_j) / d.timestep_s
                self._drawn_j = drawn
            else:
                energy += float(np.sum(np.maximum(a * w.joint_velocities_rad_s[:, 2], 0.0)))
        # tracking and effort at the end of the control step; energy its mean power
        ph = w.phase
        ref = np.stack([self.reference.angles_rad(ph[s]) for s in range(2)])
        track = float(np.mean((w.joint_angles_rad - ref) ** 2))
        tau_h = self.walker_entry.ankle_moments(w)[0] if w.steps else 0.0
        effort = float(np.sum((tau_h / (mg * leg)) ** 2))
        self.last = {"track_rad2": track, "effort": effort,
                     "energy": energy / max(n, 1) / (mg * v_ref)}
        reward = float(self.reward_fn(self))
        terminated = w.fallen
        truncated = w.done and not terminated
        info = {"time_s": w.time_s, "fell": terminated, **self.last}
        if self.device is not None:
            info["device_commanded_torque_nm"] = self.device.commanded2.copy()
            info["device_delivered_torque_nm"] = self.device.delivered2.copy()
        return self._observation(), reward, terminated, truncated, info

    @property
    def observation_names(self) -> tuple[str, ...]:
        """The observation's entries: :data:`OBSERVATION_NAMES`, then with a worn device
        (``mode="hafo"`` or ``"device"``) each worn side's circuit states
        (``<side>_device.<state name>``, SI; the HAFO's: line and chamber pressures in Pa,
        shaft speed, motor current)."""
        return OBSERVATION_NAMES + self._device_states

    # -- the worn device -------------------------------------------------------------------
    @staticmethod
    def _hafo_config(preset: str):
        """``mode="hafo"``'s device: the HAFO preset ``preset`` on both ankles, as a scenario's
        ``[device] preset = <preset>, sides = ["right", "left"]`` (no ``params``) wears it
        (:func:`afo_mj.experiments.device_walk.preset_config`)."""
        from afo_mj.devices.hafo import PRESETS
        from afo_mj.experiments.device_walk import preset_config
        if preset not in PRESETS:
            raise ValueError(f"hafo_preset = {preset!r}; allowed: {', '.join(PRESETS)} (a "
                             "valve preset: mode = 'device' with a scenario that wears it)")
        return preset_config(preset, ("right", "left"), key="hafo_preset")

    def _device_config(self, path):
        """The scenario's device (:func:`afo_mj.scenarios.device_scenario.device_config`),
        refused where it wears none or the ideal source (no circuit to command)."""
        from afo_mj.scenarios.device_scenario import device_config
        cfg = device_config(self.scenario)
        if cfg is None:
            raise ValueError(f"mode = 'device' with scenario {str(path)!r}: it wears no "
                             "device (no [device] preset or [circuit] description); allowed: "
                             "a device scenario (e.g. scenarios/gait_assist_hafo.toml), or "
                             "mode = 'torque' / 'hafo'")
        if cfg.preset == "ideal":
            raise ValueError(f"mode = 'device' with device.preset = 'ideal' ({path}): the "
                             "ideal device is no circuit and has no torque-command input; "
                             "allowed: mode = 'torque' (the action is then the torque itself)")
        return cfg

    def _make_device(self, max_steps: int):
        """The worn device (:attr:`device_config`) with the action as its commanded torque (a
        log of ``max_steps`` steps), built as ``afo-mj run`` builds a condition."""
        from afo_mj.experiments.device_walk import make_device
        cfg = self.device_config
        self._drawn_j = 0.0
        return make_device(cfg, "transparent", self.scenario.walker.timestep_s, max_steps,
                           torque_fn=_command_fn(self._command, cfg.sides))

    def _observation(self) -> np.ndarray:
        w = self.walk
        mg = w.phys.body_mass_kg * GRAVITY_M_S2
        dev = self.walker_entry.ankle_moments(w)[1] if w.steps else np.zeros(2)
        parts = [w.joint_angles_rad.ravel(), w.joint_velocities_rad_s.ravel(), w.phase,
                 w.stance.astype(float), (w.grf_n / mg).ravel(), [w.pelvis_speed_m_s], dev]
        if self.device is not None:
            parts.append(self.device.Y.ravel())
        return np.concatenate(parts)


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point=AnkleAssistEnv)
