"""The human controller interface: what moves the walker, declared once, registered by name.

A *human controller* is the person's side of a walk: it reads the walker's state each step and
drives the walker's actuators. :class:`HumanController` is what one declares:

* ``name``: the registry name a scenario's ``[walker] model`` uses;
* ``Params``: its parameters, a frozen dataclass whose construction validates them (a
  :class:`afo_mj.hydraulics.params.Parameters` subclass gets range checks that name the
  key, the value and what is allowed); a scenario's ``[controller]`` table fills it;
* ``actuators``: which of the walker's actuators it drives — ``"ff"`` (the joint torque
  motors, :attr:`afo_mj.human.walker.WalkerPhysics.ff_act`), ``"pd"`` (the joint servos) and
  ``"residual"`` (the pelvis residuals, as OpenSim's residual actuators);
* ``reads``: what it reads each step (documentation and a check: ``"qpos"``, ``"qvel"``,
  ``"touch"`` — the heel and ball contact sensors — ``"grf"``, ``"time"``);
* ``signals``: the per-step signals it records beside the joints (name → unit, per-step
  shape), e.g. the muscle walker's activations;
* :meth:`~HumanController.build_physics` (the body it drives), :meth:`~HumanController.start`
  (posture, velocity and its own state at ``t = 0``), :meth:`~HumanController.step` (one step:
  writes its actuators' ``ctrl`` and returns its gait events per side),
  :attr:`~HumanController.stance` (its stance state per leg, the foot switch a worn device
  reads) and :meth:`~HumanController.joint_moments_nm` (the human joint moments of the step).

A controller written in Python against this interface is stepped by
:class:`afo_mj.gait.controller_walk.ControllerWalk` (a Python loop, as a Python
:class:`~afo_mj.circuits.device.AnkleDevice` is stepped); one that also gives a compiled step
(:meth:`~HumanController.compiled`: a ``numba.cfunc`` of one fixed C signature,
:mod:`afo_mj.gait.controller_loop`) is stepped by the same walk in compiled code, with no
Python per step. Every entry point that walks a
scenario (``afo-mj run``, ``compare``, ``sweep``, ``render``, ``walk_batch``, the gymnasium
environment) walks it once it is registered with :func:`register_controller` — one new file
and one registry line, no change to the walks, the loops or the application.

The two built-in controllers are written against this interface too and have their own
steppers, :class:`~afo_mj.gait.controller_walk.ControllerWalk` subclasses (:data:`BUILTIN`,
resolved by :mod:`afo_mj.gait.walkers`, not registered): ``"torque"`` — the PD tracking
controller :class:`afo_mj.gait.tracking_controller.TrackingController` (its law
:mod:`afo_mj.gait.control_law`), stepped by :class:`afo_mj.gait.walk.Walk`, which keeps the
dedicated compiled loop of :mod:`afo_mj.gait.walk_loop`; ``"muscle"`` — the reflex controller
:class:`afo_mj.gait.reflex_controller.ReflexController` (its law :mod:`afo_mj.gait.reflex_law`,
Geyer & Herr 2010), stepped by :class:`afo_mj.gait.muscle_walk.MuscleWalkStepper` in
:mod:`afo_mj.gait.controller_loop`. Either walked by the plain ``ControllerWalk`` is the
dedicated stepper's walk bit for bit (``tests/test_controller_interface.py``,
``tests/test_tracking_controller.py``).

Example (a controller that holds every joint at 0 with PD torques; it falls)::

    @dataclasses.dataclass(frozen=True)
    class HoldParams(Parameters):
        kp_nm_per_rad: float = param(200.0, unit="N*m/rad", lo=0.0, hi=5000.0)

    class Hold(HumanController):
        name = "hold"
        Params = HoldParams
        reads = ("qpos", "qvel", "touch")

        def step(self, t, phys):
            ctrl = phys.data.ctrl
            q, v = phys.leg_angles_rad(), phys.leg_velocities_rad_s()
            ctrl[phys.ff_act] = -self.params.kp_nm_per_rad * q - 10.0 * v
            return self.contact_events(t, phys)

    register_controller(Hold)
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any, ClassVar, Mapping

import numpy as np

__all__ = ["HumanController", "ControllerSetup", "ControllerError", "CompiledStep",
           "register_controller",
           "unregister_controller", "controller_class", "controller_names", "BUILTIN",
           "ACTUATOR_GROUPS", "READS", "EV_NONE", "EV_HEEL_STRIKE", "EV_TOE_OFF",
           "EV_SWING_CONTACT"]

#: gait event codes a step returns per side (a swing contact: the start of a floor contact of
#: a swinging foot, a scuff, recorded in ``GaitEvents.swing_toe_contacts``)
EV_NONE, EV_HEEL_STRIKE, EV_TOE_OFF, EV_SWING_CONTACT = 0, 1, 2, 3
#: the walker's actuator groups a controller may drive
ACTUATOR_GROUPS = ("ff", "pd", "residual")
#: what a controller may read each step
READS = ("time", "qpos", "qvel", "touch", "grf")
#: the built-in controllers, stepped by their own compiled walks (module docstring)
BUILTIN = ("torque", "muscle")


class ControllerError(ValueError):
    """A controller declaration or registration that cannot be honoured (names what and why)."""


@dataclasses.dataclass(frozen=True)
class ControllerSetup:
    """What a controller is built for: the walker (:class:`afo_mj.human.walker.WalkerParams`),
    the reference gait (:class:`afo_mj.gait.reference.ReferenceGait`; None for a controller
    that tracks none), the gait cycle time the scenario asks for (s; None: none asked) and
    the number of strides."""

    walker: Any
    reference: Any = None
    cycle_time_s: float | None = None
    strides: int = 10


@dataclasses.dataclass(frozen=True)
class CompiledStep:
    """A controller's compiled step (:mod:`afo_mj.gait.controller_loop`): the address of its
    cfunc of :data:`~afo_mj.gait.controller_loop.STEP_SIGNATURE`, its int64 ``block`` (the
    addresses and sizes it reads its arrays from), its ``state`` array (float64, 1-D: the
    declared signals are read from it, ``signal_index[name]`` the entries of each in the
    declared shape), whether the joint moments recorded are the ones it writes to ``out``
    (``moments_from_out``; else MuJoCo's actuator forces on the leg joints), and ``keep``:
    every array the block points into, held alive while the walk runs."""

    address: int
    block: np.ndarray
    state: np.ndarray
    signal_index: Mapping[str, np.ndarray]
    moments_from_out: bool = False
    keep: tuple = ()


class HumanController(abc.ABC):
    """A human controller (module docstring). Subclasses set the class attributes and
    implement :meth:`step`; :meth:`start` defaults to the reference's posture at heel strike of
    the right leg moving at the reference's speed, :meth:`build_physics` to the walker with its
    PD servos off, and the stance state and events to :meth:`contact_events`."""

    #: registry name (``[walker] model``)
    name: ClassVar[str] = ""
    #: parameters: a frozen dataclass type, or None for a controller without parameters
    Params: ClassVar[type | None] = None
    #: the actuator groups it drives (:data:`ACTUATOR_GROUPS`)
    actuators: ClassVar[tuple[str, ...]] = ("ff",)
    #: what it reads each step (:data:`READS`)
    reads: ClassVar[tuple[str, ...]] = ("time", "qpos", "qvel", "touch")
    #: per-step signals it records: name -> (unit, per-step shape)
    signals: ClassVar[Mapping[str, tuple[str, tuple[int, ...]]]] = {}
    #: how it answers a worn device, for a device run's ``human_response`` block
    device_response_note: ClassVar[str] = (
        "the controller's own law answers the device; no written-in rule lowers the wearer's "
        "effort by the device's torque")
    #: stance detection of :meth:`contact_events`: on above / off below these fractions of
    #: body weight on a foot's heel and ball sensors
    stance_on_fraction: ClassVar[float] = 0.05
    stance_off_fraction: ClassVar[float] = 0.01
    #: the shortest stance or swing (s): a foot that bounces at contact does not end its stance
    min_phase_s: ClassVar[float] = 0.05

    def __init__(self, params=None, setup: ControllerSetup | None = None):
        if self.Params is not None:
            params = self.Params() if params is None else params
            if not isinstance(params, self.Params):
                raise ControllerError(f"{type(self).__name__}: params {params!r}; allowed: "
                                      f"a {self.Params.__name__}")
        elif params is not None:
            raise ControllerError(f"{type(self).__name__} takes no parameters; got {params!r}")
        self.params = params
        self.setup = setup
        self._stance = np.zeros(2, dtype=bool)
        self._switch_t = np.full(2, -np.inf)

    # -- what a subclass may override --------------------------------------------------------
    def build_physics(self, worn_masses=()):
        """The body it drives: the walker of ``setup.walker`` with ``worn_masses``, PD servo
        gains zero (a controller that drives the ``"pd"`` group sets its own gains)."""
        from afo_mj.human.walker import WalkerPhysics, build_walker
        walker = self.walker_params()
        zero = {"hip": 0.0, "knee": 0.0, "ankle": 0.0}
        return WalkerPhysics(build_walker(walker, worn_masses, kp=zero, kv=zero))

    def start(self, phys) -> None:
        """Posture and velocity at ``t = 0`` and the controller's own state: the reference's
        angles at the right leg's heel strike (left leg half a cycle on), the pelvis moving at
        the reference's speed (1.2 m/s without one) scaled by √(stature / 1.75 m), the lowest
        contact point on the floor."""
        import math

        import mujoco
        m, d = phys.model, phys.data
        q = d.qpos
        height = float(self.walker_params().height_m)
        ref = getattr(self.setup, "reference", None)
        if ref is not None:
            ang = np.asarray(ref.angles_rad(np.array([0.0, 0.5])), float).reshape(2, 3)
            speed = float(ref.speed_m_s or 1.2)
        else:
            ang, speed = np.zeros((2, 3)), 1.2
        for s in range(2):
            q[phys.leg_qpos[s]] = ang[s]
        d.qvel[phys.pelvis_dof[0]] = speed * math.sqrt(height / 1.75)
        mujoco.mj_kinematics(m, d)
        q[phys.pelvis_qpos[1]] -= phys.contact_point_heights_m().min() - 0.0005
        mujoco.mj_forward(m, d)
        self._stance[:] = phys.contact_normal_forces_n().sum(axis=1) > 0.0

    @abc.abstractmethod
    def step(self, t: float, phys) -> tuple[int, int]:
        """One step at time ``t`` (s): write the ``ctrl`` of its actuators in
        ``phys.data`` and return the gait event per side (``EV_NONE``, ``EV_HEEL_STRIKE``,
        ``EV_TOE_OFF``), right then left."""

    @property
    def stance(self) -> np.ndarray:
        """(2,) bool: the controller's stance state per leg (the foot switch a worn device
        reads)."""
        return self._stance.copy()

    def joint_moments_nm(self, phys) -> np.ndarray:
        """(2, 3) the human net joint moment of the step just taken (N·m, + in the angle's
        direction): by default what MuJoCo's actuators applied to the leg joints."""
        return phys.data.qfrc_actuator[phys.leg_dof].copy()

    def joint_damping_nm_s_per_rad(self, phys) -> np.ndarray | None:
        """(2, 2) extra damping on the [knee, ankle] joints per side that MuJoCo should
        integrate implicitly this step (N·m·s/rad), or None for none (the default)."""
        return None

    def answer_device(self, phys, torque_nm: np.ndarray) -> None:
        """Called each step a device is worn, after the device's torque is applied and before
        ``mj_step``, with the torque it is expected to deliver this step per side (N·m, the
        end-of-step torque of a coupled device at the present ankle velocity): a controller
        with a written-in answer to the device changes its ``ctrl`` here. Default: none."""

    def fall_limits(self, phys) -> tuple[float, float]:
        """``(pelvis_z_min, tilt_max_rad)``, called after :meth:`start`: the walk is a fall
        once the pelvis height coordinate (``qpos`` of ``pelvis_tz``) is below
        ``pelvis_z_min`` or the trunk pitch beyond ``tilt_max_rad``. Default: the torque
        walker's — the hip below 55 % of its start height above the floor, or 1 rad."""
        z0 = float(phys.data.qpos[phys.pelvis_qpos[1]])
        return -(1.0 - 0.55) * (phys.pelvis_height_offset_m + z0), 1.0

    def signal_values(self) -> Mapping[str, np.ndarray]:
        """This step's values of :attr:`signals` (arrays of the declared shapes)."""
        return {}

    def state_array(self) -> np.ndarray | None:
        """Its state as one float64 array (its compiled step's ``state``), checked for
        finiteness after each step (a non-finite state ends the walk with
        FloatingPointError); None (the default): none to check."""
        return None

    def compiled(self, phys) -> CompiledStep | None:
        """Its compiled step, called after :meth:`start` (None: it has none, the default;
        it is then stepped in Python). A compiled step must compute what :meth:`step` and the
        other hooks compute, on the same arrays (the walk may switch between them, e.g. for a
        step with an external action), so that the walk is the same in either loop."""
        return None

    # -- helpers ----------------------------------------------------------------------------
    def walker_params(self):
        """The walker of :attr:`setup` (the default :class:`~afo_mj.human.walker.WalkerParams`
        without one)."""
        from afo_mj.human.walker import WalkerParams
        w = getattr(self.setup, "walker", None)
        return WalkerParams() if w is None else w

    def contact_events(self, t: float, phys) -> tuple[int, int]:
        """Stance per leg from its foot's heel and ball contact sensors, with hysteresis (on
        above :attr:`stance_on_fraction` of body weight, off below
        :attr:`stance_off_fraction`, each phase lasting at least :attr:`min_phase_s`, as the
        reflex controller detects stance); returns the events: stance onset = heel strike,
        stance end = toe off."""
        load = phys.contact_normal_forces_n().sum(axis=1) / (phys.body_mass_kg * 9.81)
        out = [EV_NONE, EV_NONE]
        for s in range(2):
            if t - self._switch_t[s] < self.min_phase_s:
                continue
            if not self._stance[s] and load[s] > self.stance_on_fraction:
                self._stance[s] = True
                self._switch_t[s] = t
                out[s] = EV_HEEL_STRIKE
            elif self._stance[s] and load[s] < self.stance_off_fraction:
                self._stance[s] = False
                self._switch_t[s] = t
                out[s] = EV_TOE_OFF
        return out[0], out[1]


#: registered controllers by name (the built-in ones are resolved lazily: their steppers
#: live in modules that import this one)
_REGISTRY: dict[str, type[HumanController]] = {}


def _check_declaration(cls) -> None:
    where = getattr(cls, "__name__", repr(cls))
    if not (isinstance(cls, type) and issubclass(cls, HumanController)):
        raise ControllerError(f"register_controller({where}): allowed: a HumanController "
                              f"subclass")
    if getattr(cls, "__abstractmethods__", None):
        missing = ", ".join(sorted(cls.__abstractmethods__))
        raise ControllerError(f"{where}: does not implement {missing}")
    name = cls.name
    if not isinstance(name, str) or not name or not name.replace("_", "").isalnum():
        raise ControllerError(f"{where}.name = {name!r}; allowed: a non-empty name of "
                              f"letters, digits and _")
    bad = [a for a in cls.actuators if a not in ACTUATOR_GROUPS]
    if bad or not cls.actuators:
        raise ControllerError(f"{where}.actuators = {cls.actuators!r}; allowed: one or more "
                              f"of {', '.join(ACTUATOR_GROUPS)}")
    bad = [r for r in cls.reads if r not in READS]
    if bad:
        raise ControllerError(f"{where}.reads = {cls.reads!r}; allowed: any of "
                              f"{', '.join(READS)}")
    if cls.Params is not None and not (dataclasses.is_dataclass(cls.Params)
                                       and cls.Params.__dataclass_params__.frozen):
        raise ControllerError(f"{where}.Params = {cls.Params!r}; allowed: a frozen dataclass "
                              f"or None")
    for sig, spec in cls.signals.items():
        ok = (isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], str)
              and isinstance(spec[1], tuple) and all(isinstance(n, int) and n > 0
                                                     for n in spec[1]))
        if not ok:
            raise ControllerError(f"{where}.signals[{sig!r}] = {spec!r}; allowed: "
                                  f"(unit, shape tuple of positive ints)")


def register_controller(cls: type[HumanController], *, replace: bool = False):
    """Register a controller class under its ``name`` (usable as a decorator). A built-in
    name, or a name taken by another class without ``replace``, raises ControllerError."""
    _check_declaration(cls)
    if cls.name in BUILTIN:
        raise ControllerError(f"controller name {cls.name!r} is built in; allowed: a name "
                              f"other than {', '.join(BUILTIN)}")
    old = _REGISTRY.get(cls.name)
    if old is not None and old is not cls and not replace:
        raise ControllerError(f"controller name {cls.name!r} is already registered by "
                              f"{old.__module__}.{old.__qualname__}; allowed: another name, or "
                              f"replace=True")
    _REGISTRY[cls.name] = cls
    return cls


def unregister_controller(name: str) -> None:
    """Remove a registered (not built-in) controller; an unknown name raises ControllerError."""
    if name not in _REGISTRY:
        raise ControllerError(f"controller {name!r} is not registered; registered: "
                              f"{', '.join(_REGISTRY) or 'none'}")
    del _REGISTRY[name]


def controller_names() -> tuple[str, ...]:
    """Every walker model a scenario may name: the built-in ones, then the registered."""
    return BUILTIN + tuple(_REGISTRY)


def controller_class(name: str) -> type[HumanController]:
    """The registered controller class ``name`` (not a built-in: those have their own
    steppers); an unknown name raises ControllerError naming the allowed ones."""
    cls = _REGISTRY.get(name)
    if cls is None:
        raise ControllerError(f"walker.model = {name!r} is not a registered controller; "
                              f"allowed: {', '.join(repr(n) for n in controller_names())}")
    return cls
