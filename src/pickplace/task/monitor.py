"""The per-step monitor of an episode: unexpected contacts, slip in the grip, a resting object that moves.

Manipulation fails quietly, so these checks run after *every* simulation step of every phase (the control
loops call the monitor as their hook) and raise the moment something is wrong, naming what they saw.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from pickplace.errors import GraspFailed, PickPlaceError
from pickplace.robot.model import Robot, object_body_name, surface_geoms
from pickplace.task.faults import FaultInjector
from pickplace.task.observe import Observer, SimulatorObserver
from pickplace.task.telemetry import TelemetryRecorder


class UnexpectedContact(PickPlaceError):
    """A contact that the running phase does not allow (the geoms are named).

    Attributes:
        pairs: The offending geom pairs.
    """

    def __init__(self, pairs: list[tuple[str, str]], t_s: float) -> None:
        self.pairs = pairs
        names = ", ".join(f"{a} <-> {b}" for a, b in pairs)
        super().__init__(f"unexpected contact at t = {t_s:.3f} s: {names}")


class ObjectMoved(PickPlaceError):
    """The resting object is no longer where it was observed (it was pushed, or knocked)."""


# Contact classes of the simulation's geoms, for the per-step contact monitor: _OTHER are the objects a task
# has besides the one being picked (and the bin's walls and the obstacles are _ENV).
_ARM, _GRIPPER, _PAD, _OBJECT, _TABLE, _ENV, _OTHER = range(7)
_N_CLASSES = 7


class _ContactFlag:
    """A flag of :class:`StepMonitor` that decides which contacts are allowed: setting it to a new value forgets
    the verdicts found under the old one (the per-step check looks at the contacts again only when they or the
    flags change). Stored in the instance as ``_<name>``."""

    def __init__(self, doc: str) -> None:
        self.__doc__ = doc

    def __set_name__(self, owner: type, name: str) -> None:
        self._attr = "_" + name

    def __get__(self, monitor: StepMonitor | None, owner: type | None = None) -> bool:
        if monitor is None:
            return self  # type: ignore[return-value]  # the class attribute: the descriptor itself
        return getattr(monitor, self._attr)

    def __set__(self, monitor: StepMonitor, value: bool) -> None:
        if getattr(monitor, self._attr) != value:
            setattr(monitor, self._attr, value)
            monitor._allowed_table = None
            monitor._ok_contacts = b""


class StepMonitor:
    """The checks run after every simulation step, and the episode clock.

    Called as the control loops' hook. It advances the episode time, records telemetry, and raises as soon
    as something is wrong: :class:`UnexpectedContact`, :class:`~pickplace.errors.GraspFailed` (slip),
    :class:`ObjectMoved`, or whatever the trajectory predictor raises. The state machine switches the
    checks on and off as the phases require (``allow_*``, ``holding``, ``watching``, ``predictor``).

    The contact check runs every step. It reads MuJoCo's contact counts first (the robot's, the object's and the
    gripper's with the object: :mod:`pickplace.robot.model`): when every contact of the robot is the gripper's with
    the object while that is allowed (or there is none), and a held object touches nothing but the gripper, every
    contact is allowed. Otherwise it looks at the contacts, but only when their geom pairs differ from those it
    last found allowed, or a flag that decides what is allowed (``allow_hand_object``, ``object_falling``,
    ``allow_object_table``, ``holding``) was set to a new value since; it then compares each pair's classes against
    a table of :meth:`allowed` made once per change of the flags.

    Args:
        robot: The models.
        recorder: Telemetry, or None.
        slip_tolerance_m: Largest allowed motion of the held object in the tcp frame (m).
        injector: Timed faults to apply after each step, or None.
        observer: What the slip, "object lost" and "the object moved" checks read (what the robot senses);
            default: the simulator. The contact checks referee the episode and read the simulator.
    """

    def __init__(self, robot: Robot, recorder: TelemetryRecorder | None, slip_tolerance_m: float,
                 injector: FaultInjector | None = None, observer: Observer | None = None) -> None:
        m, h = robot.mj, robot.handles
        self.robot = robot
        self.observer = observer
        self.recorder = recorder
        self.predictor: Callable[[mujoco.MjData, float], None] | None = None  # set while a trajectory runs
        self.predict_every = 50
        self._steps = 0
        self.dt = float(m.opt.timestep)
        self.t = 0.0
        self.phase = "IDLE"  # name of the running phase
        self.slip_tolerance_m = slip_tolerance_m
        self.name = robot.scene.object.name  # how the object is called in failure messages
        table = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "table")
        cls = np.full(m.ngeom, _ENV)
        cls[np.isin(m.geom_bodyid, list(h.robot_bodies))] = _ARM
        cls[np.isin(m.geom_bodyid, list(h.gripper_bodies))] = _GRIPPER
        cls[h.pad_geoms] = _PAD
        cls[m.geom_bodyid == table] = _TABLE
        world = robot.world_scene
        for other in world.objects:  # every object of the world, then the one being picked
            body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, object_body_name(world, other.name))
            cls[m.geom_bodyid == body] = _OTHER
        cls[surface_geoms(m, world, robot.scene)] = _TABLE  # the bin's floor, a tower's top: like the table
        cls[h.object_geoms] = _OBJECT
        self.cls = cls
        self._count_robot, self._count_object, self._count_hand = (int(a) for a in h.contact_count_sensors)
        self._allowed_table: np.ndarray | None = None  # allowed(a, b) for every pair of classes, under the flags now
        self._ok_contacts = b""  # the contacts' geom pairs last found allowed under the flags now
        self._allow_hand_object = False  # gripper/pads touching the object
        self._object_falling = False  # a dropped object on its way down may land on the arm too
        self._allow_object_table = True
        self._holding = False  # slip is checked
        self.tolerate_contacts = False  # backing off a collision: contacts are expected until clear
        self.watching = False  # whether the resting object must stay where it was observed
        self.watch_tolerance_m = 0.005
        self.slip_max_m = 0.0
        self.slip_now_m = 0.0
        self._inject = True  # whether the injector has anything to do (set with it)
        self.injector = injector

    # The flags that decide which contacts are allowed (see _ContactFlag).
    allow_hand_object = _ContactFlag("Whether the gripper and its pads may touch the object.")
    object_falling = _ContactFlag("Whether a dropped object is on its way down (it may land on the arm too).")
    allow_object_table = _ContactFlag("Whether the object may touch the table while it is held (setting it down).")
    holding = _ContactFlag("Whether the object is held (slip is checked, and it may touch nothing but the robot's "
                           "hand).")

    @property
    def injector(self) -> FaultInjector | None:
        """The timed faults applied after each step, or None."""
        return self._injector

    @injector.setter
    def injector(self, value: FaultInjector | None) -> None:
        self._injector = value
        # a FaultInjector without a push only ever writes a zero force: nothing to do then
        self._inject = value is not None and (not isinstance(value, FaultInjector) or value.pushes)

    def start_holding(self, d: mujoco.MjData) -> None:
        """Take the grip as it is now as the reference for slip."""
        self._sense(d).start_holding()
        self.holding = True

    def _sense(self, d: mujoco.MjData) -> Observer:
        if self.observer is None:
            self.observer = SimulatorObserver(self.robot, d)
        return self.observer

    def allowed(self, a: int, b: int) -> bool:
        """Whether a contact between geom classes a and b is allowed now.

        The robot touching anything but the object (when allowed) is a fault. The object touching the table,
        a wall or the floor is a fault only while the robot holds it (it carried the object into them); an
        object that is not held (resting, or dropped) may touch whatever it falls on, including the arm while
        it falls (``object_falling``: the arm stands still, the object came to it). The other objects of a task
        may touch anything but the robot and the object while it is held (a tower's top is a surface, the table's
        class); whether one of them was knocked is the task's check.
        """
        lo, hi = min(a, b), max(a, b)
        if lo >= _TABLE:  # neither the robot nor the object: things resting on each other (a tower, the bin)
            return True
        if hi == _OTHER:  # with the robot never; with the object only when it is not held
            return lo == _OBJECT and not self.holding
        if hi == _OBJECT and lo in (_GRIPPER, _PAD):
            return self.allow_hand_object or self.object_falling
        if (lo, hi) == (_ARM, _OBJECT):
            return self.object_falling
        if (lo, hi) == (_OBJECT, _TABLE):
            return self.allow_object_table or not self.holding
        if (lo, hi) == (_OBJECT, _ENV):
            return not self.holding
        return False

    def _check_contacts(self, geoms: np.ndarray) -> None:
        """Raise :class:`UnexpectedContact` if a contact between the geom pairs (n, 2) is not allowed now."""
        table = self._allowed_table
        if table is None:  # the flags changed: allowed() for every pair of classes, once
            table = self._allowed_table = np.array([[self.allowed(a, b) for b in range(_N_CLASSES)]
                                                    for a in range(_N_CLASSES)])
        classes = self.cls[geoms]
        ok = table[classes[:, 0], classes[:, 1]]
        if not ok.all():
            m = self.robot.mj
            pairs = sorted({tuple(sorted((m.geom(int(a)).name or f"geom{a}", m.geom(int(b)).name or f"geom{b}")))
                            for a, b in geoms[~ok]})
            raise UnexpectedContact(pairs, self.t)  # type: ignore[arg-type]

    def __call__(self, d: mujoco.MjData) -> None:
        self.t += self.dt
        if self.recorder is not None:
            self.recorder.record(d, self.t, self.phase)
        n = d.ncon
        if n and not self.tolerate_contacts:
            # MuJoCo's contact counts first (robot.model): every contact of the robot is the gripper's with the object
            # and that is allowed, or there is none; the held object touches nothing but the gripper (the usual case)
            sd = d.sensordata
            hand = sd[self._count_hand]
            if not (sd[self._count_robot] == (hand if self._allow_hand_object else 0.0)
                    and (not self._holding or sd[self._count_object] == hand) and not self._object_falling):
                key = d.contact.geom[:n].tobytes()
                if key != self._ok_contacts:  # the contacts changed since they were last found allowed
                    self._check_contacts(d.contact.geom[:n])
                    self._ok_contacts = key
        if self._holding:
            sense = self.observer if self.observer is not None else self._sense(d)
            slip = sense.slip_m()
            self.slip_now_m = slip
            if slip > self.slip_max_m:
                self.slip_max_m = slip
            if slip > self.slip_tolerance_m:
                raise GraspFailed(f"the {self.name} slipped {slip * 1e3:.2f} mm in the grip at t = {self.t:.3f} s "
                                  f"(tolerance {self.slip_tolerance_m * 1e3:.2f} mm)")
            lost = sense.grip_lost()
            if lost is not None:
                raise GraspFailed(f"{lost} at t = {self.t:.3f} s: it is no longer held")
        if self.watching:
            moved = (self.observer if self.observer is not None else self._sense(d)).moved_m()
            if moved > self.watch_tolerance_m:
                self.watching = False
                raise ObjectMoved(f"the {self.name} moved {moved * 1e3:.1f} mm from where it was observed "
                                  f"(t = {self.t:.3f} s)")
        if self.predictor is not None:
            self._steps += 1
            if self._steps % self.predict_every == 0:
                self.predictor(d, self.t)
        if self._inject:
            self._injector.step(d, self.phase, self.t)  # type: ignore[union-attr]


__all__ = ["ObjectMoved", "StepMonitor", "UnexpectedContact"]
