"""What the robot knows about the world: one interface, through which a skill learns everything about the object.

A skill never reads the simulator's object state itself. It asks an :class:`Observer` where the object is
(resting, or in the hand), how fast it moves, and what the pads feel. :class:`SimulatorObserver` answers from
the simulation, exactly and at once: the ideal profile, which isolates the algorithms' own error.
:class:`SensorObserver` answers from sensors (a depth camera, the gripper, a wrist force/torque sensor) and
has no path to the simulator's object state: the realistic profile.

The code that *measures* an episode (the place error in the result, the check 1 s after the release) reads the
truth on purpose; it uses a :class:`SimulatorObserver` of its own, kept apart from the robot's.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Protocol

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.perception.camera import CameraConfig
from pickplace.perception.obstacles import ObstacleCamera
from pickplace.perception.pose import ObjectNotSeen
from pickplace.robot import gripper
from pickplace.robot.model import Robot
from pickplace.world.config import check_int, check_range
from pickplace.world.contact import Contact

log = logging.getLogger(__name__)

#: The camera measures a resting object against the hand when the tcp is this close to it (m).
HAND_NEAR_M = 0.1

#: The open pads reach around a resting object, and hide the sides a fit needs, once the tcp is closer to it
#: than half its largest extent plus this (m): the "moved" watch stops looking then.
PADS_AROUND_M = 0.04


class Observer(Protocol):
    """Everything a skill may know about the object and the grip (SI units, world frame).

    The skill tells the observer what happens (:meth:`observe` a resting object, :meth:`closing`,
    :meth:`grasped`, :meth:`look_in_hand`, :meth:`released`); between those it asks for the robot's current
    belief (:meth:`object_pose`) and, at every step, for what its sensors say (:meth:`moved_m`,
    :meth:`slip_m`, :meth:`grip_lost`, :meth:`load_sample`).
    """

    def observe(self, near: pin.SE3 | None = None) -> pin.SE3:
        """Look at the resting object (anywhere on the table, or near ``near``, where the hand may be too) and
        return its pose."""
        ...

    def look_from_hand(self) -> bool:
        """Measure the resting object again against the hand above it (at the pregrasp, before the approach
        commits the pads): whether the belief changed (an exact observer has nothing to refine)."""
        ...

    def object_pose(self) -> pin.SE3:
        """The robot's belief of the object's pose, resting or held."""
        ...

    def object_position(self) -> np.ndarray:
        """The object's origin (3,) (m) as believed: cheaper than :meth:`object_pose`, for every step."""
        ...

    def moved_m(self) -> float:
        """How far the resting object has moved since it was last observed (m), as sensed now."""
        ...

    def object_velocity(self) -> np.ndarray:
        """The resting (or falling) object's linear and angular velocity (6,) (m/s, rad/s), as sensed."""
        ...

    def closing(self) -> None:
        """The gripper starts to close on the object (a wrist sensor is zeroed now)."""
        ...

    def grasped(self, T_tcp_object_model: pin.SE3) -> None:
        """The pads hold the object; ``T_tcp_object_model`` is where the grasp model puts it in the hand."""
        ...

    def look_in_hand(self) -> None:
        """Measure the held object's pose in the hand again."""
        ...

    def released(self) -> None:
        """The gripper let go of the object."""
        ...

    def pad_forces(self) -> np.ndarray:
        """The normal force of each pad on the object (2,) (N)."""
        ...

    def pad_contacts(self) -> list[Contact]:
        """The pad-object contacts (points, normals, friction), for the force-closure test."""
        ...

    def load_sample(self) -> tuple[float, float, float]:
        """While lifting: the pads' total normal force (N), the vertical force the hand carries the object with
        (N), and ``g`` plus the object's vertical acceleration (m/s^2): the mass is the ratio of the sums."""
        ...

    def airborne(self, z0_m: float, mass_kg: float) -> bool:
        """Whether the object of ``mass_kg``, held, has left the table (its origin was at height ``z0_m``)."""
        ...

    def touched_down(self, mass_kg: float) -> bool:
        """Whether the table now carries the held object of ``mass_kg`` (a set-down can stop): never for a
        sensor that knows the object's height exactly (the set-down goes to it)."""
        ...

    def start_holding(self) -> None:
        """Take the grip as it is now as the reference for :meth:`slip_m`."""
        ...

    def slip_m(self) -> float:
        """How far the object has moved in the grip since :meth:`start_holding` (m), as sensed."""
        ...

    def expect_load(self, mass_kg: float | None) -> None:
        """The hand carries an object of this mass off the table from now on (None: not any more)."""
        ...

    def payload_mass_kg(self, modelled_kg: float, weighed_kg: float) -> float:
        """The held object's mass the controllers compensate once it is lifted (kg): the object model's
        (``modelled_kg``) where that is the truth, else what the lift weighed (``weighed_kg``, nan if not)."""
        ...

    def grip_lost(self) -> str | None:
        """Why the sensors say the object is no longer held, or None."""
        ...

    def world(self) -> mujoco.MjData:
        """The world the planners check paths and grasps against (a simulation state of the robot's model:
        the object's pose, the obstacles' mocap bodies; the arm's joints in it mean nothing): the world as the
        robot believes it is. Valid until the next call."""
        ...

    def close(self) -> None:
        """Release the sensors' resources."""
        ...


#: The ideal observer's set-down guard: the surface carries this fraction of the held object's weight. Its contact
#: forces are exact, so a fifth of the weight is a clear signal (the realistic wrist sensor's 0.1 N noise needs half:
#: :attr:`SensingConfig.load_lost_fraction`).
TOUCH_DOWN_FRACTION = 0.2


class SimulatorObserver:
    """The ideal observer: the simulation's own state, exact and without delay.

    Args:
        robot: The models (the object's body and joint).
        data: The simulation state.
    """

    def __init__(self, robot: Robot, data: mujoco.MjData) -> None:
        self.robot, self.d = robot, data
        h = robot.handles
        self._body = h.object_body
        self._dof = h.object_dof
        self._tcp = h.tcp_site
        self._observed_at = np.zeros(3)
        self._p_tcp_object0 = np.zeros(3)
        self._in_tcp_now = np.zeros(3)
        # MuJoCo's sensors of the object, computed in every step (robot.model): its origin in the tcp frame, and the
        # net force of each pad on it (world axes); the left finger's slide axis (the pads' normal)
        a = h.object_in_tcp_sensor
        self._in_tcp = slice(a, a + 3)
        b = h.object_position_sensor
        self._position = data.sensordata[b : b + 3]  # a view: it follows the simulation
        left, right = (int(b) + 1 for b in h.pad_sensors)
        self._left, self._right = data.sensordata[left : left + 3], data.sensordata[right : right + 3]  # views
        self._load_z = (left + 2, right + 2)
        self._axis = data.xaxis[int(h.finger_joints[0])]  # a view
        self._g = float(-robot.mj.opt.gravity[2])

    def observe(self, near: pin.SE3 | None = None) -> pin.SE3:
        """The object's pose (exact, wherever it is)."""
        T = self.object_pose()
        self._observed_at = T.translation.copy()
        return T

    def look_from_hand(self) -> bool:
        """Nothing to refine: the pose is exact."""
        return False

    def object_pose(self) -> pin.SE3:
        """The object's pose (its body frame)."""
        return pin.SE3(self.d.xmat[self._body].reshape(3, 3).copy(), self.d.xpos[self._body].copy())

    def object_position(self) -> np.ndarray:
        """The object's origin (3,) (m)."""
        return self.d.xpos[self._body].copy()

    def moved_m(self) -> float:
        """Distance of the object's origin from where it was observed (m)."""
        e = self._position - self._observed_at
        return math.sqrt(e.dot(e))

    def object_velocity(self) -> np.ndarray:
        """The free joint's velocity (6,): linear (world) then angular (m/s, rad/s)."""
        return self.d.qvel[self._dof:self._dof + 6].copy()

    def closing(self) -> None:
        """Nothing to zero."""

    def grasped(self, T_tcp_object_model: pin.SE3) -> None:
        """Nothing to do: the held object's pose is read from the simulation."""

    def look_in_hand(self) -> None:
        """Nothing to do: the held object's pose is read from the simulation."""

    def released(self) -> None:
        """Nothing to do."""

    def pad_forces(self) -> np.ndarray:
        """Normal force of each pad (2,) (N)."""
        return gripper.pad_forces(self.robot, self.d)

    def pad_contacts(self) -> list[Contact]:
        """The pad-object contacts as the simulation has them."""
        return gripper.pad_contacts(self.robot, self.d)

    def load_sample(self) -> tuple[float, float, float]:
        """The pads' normal forces and vertical force on the object, and g plus its vertical acceleration.

        Read from MuJoCo's contact sensors of the pads (the net force of each pad's contacts with the object): a
        pad's normal force is its net force along the fingers' axis (the pads' faces are normal to it).
        """
        normal = abs(float(self._left.dot(self._axis))) + abs(float(self._right.dot(self._axis)))
        return normal, self._load_z_n(), self._g + float(self.d.qacc[self._dof + 2])

    def _load_z_n(self) -> float:
        """The vertical force of the pads on the object (N)."""
        sd, (left, right) = self.d.sensordata, self._load_z
        return float(sd[left] + sd[right])

    def airborne(self, z0_m: float, mass_kg: float) -> bool:
        """The object's origin is 3 mm above where it rested."""
        return bool(self._position[2] > z0_m + 0.003)

    def touched_down(self, mass_kg: float) -> bool:
        """Whether something below the held object of ``mass_kg`` carries at least :data:`TOUCH_DOWN_FRACTION` of
        its weight (the pads' exact vertical force against its weight and vertical acceleration).

        The set-down goes to the object's resting height as it sat in the hand when the descent was aimed; an
        object that turned in the grip since then (a long one held off its centre of mass creeps about the grip
        axis) touches down a millimetre or so early, and the stiff arm would press it into the surface short of
        its target instead of stopping there.
        """
        g_plus_a = self._g + float(self.d.qacc[self._dof + 2])
        return self._load_z_n() < (1.0 - TOUCH_DOWN_FRACTION) * mass_kg * g_plus_a

    def _p_tcp_object(self) -> np.ndarray:
        """The object's origin in the tcp frame (3,) (m): MuJoCo's sensor of it (robot.model)."""
        return self.d.sensordata[self._in_tcp]

    def start_holding(self) -> None:
        """The object's position in the tcp frame now is the reference."""
        self._in_tcp_now = self._p_tcp_object()  # a view of the sensor: it follows the simulation
        self._p_tcp_object0 = self._in_tcp_now.copy()

    def slip_m(self) -> float:
        """Motion of the object's origin in the tcp frame since :meth:`start_holding` (m)."""
        e = self._in_tcp_now - self._p_tcp_object0
        return math.sqrt(e.dot(e))

    def expect_load(self, mass_kg: float | None) -> None:
        """Nothing to do: slip is measured on the object itself."""

    def payload_mass_kg(self, modelled_kg: float, weighed_kg: float) -> float:
        """The model's mass: it is the object's."""
        return modelled_kg

    def grip_lost(self) -> str | None:
        """Never: a lost grip shows as slip."""
        return None

    def world(self) -> mujoco.MjData:
        """The simulation itself: everything where it is (an obstacle that appears included)."""
        return self.d

    def close(self) -> None:
        """Nothing to release."""


@dataclass(frozen=True)
class SensingConfig:
    """The realistic robot's sensors besides its camera, and how often it looks (SI units).

    Attributes:
        wrist_force_noise_n: RMS noise of each force reading of the wrist force/torque sensor (N). Default: a
            Robotiq FT 300-S, a common wrist sensor for UR arms (datasheet: "signal noise 0.1 N" in Fx, Fy,
            Fz). Its readings are taken at every physics step here (the sensor streams at 100 Hz): the
            weighing averages them, so the noise matters less than its level says.
        load_filter_s: Time constant of the low-pass on the wrist force for the "object lost" check (s).
        load_lost_fraction: The object counts as lost when the wrist carries less than this fraction of its
            weight (times ``g`` plus the hand's vertical acceleration).
        lifted_fraction: The object counts as off the table once the hand has risen and the wrist carries this
            fraction of its weight (pads sliding along an object that stays put carry a part: twice their
            friction force).
        watch_period_s: Period of the camera's re-checks of a resting object (moved? at rest?) (s): a depth
            camera streams at 30-90 Hz, but each re-check renders, segments and fits (tens of ms of
            processing), so the robot re-checks at 10 Hz.
        rest_window_s: The object's velocity is the slope of the re-checks over at least this long and at most
            twice as long (s): over a shorter time the fit's sub-millimetre scatter would read as motion.
        views_per_look: Depth frames fitted together at each look that decides something (the observation
            before the pick, the look from the hand above it, the place check; 3 frames: 0.1 s of a 30 Hz
            stream): their noise averages (the re-checks take one).
        obstacle_period_s: Period of the camera's looks for unknown obstacles while the robot plans and moves
            along a planned path (s) (:mod:`pickplace.perception.obstacles`): each renders, filters and bins
            an image (about 12 ms here, two renders), so 10 Hz; the predictor checks the rest of the path
            against the latest.
    """

    wrist_force_noise_n: float = 0.1
    load_filter_s: float = 0.02
    load_lost_fraction: float = 0.5
    lifted_fraction: float = 0.8
    watch_period_s: float = 0.1
    rest_window_s: float = 0.2
    views_per_look: int = 3
    obstacle_period_s: float = 0.1

    def __post_init__(self) -> None:
        check_range("sensing.wrist_force_noise_n", self.wrist_force_noise_n, 0.0, 10.0, unit="N")
        check_range("sensing.load_filter_s", self.load_filter_s, 0.0, 1.0, unit="s")
        check_range("sensing.load_lost_fraction", self.load_lost_fraction, 0.0, 1.0, lo_open=True)
        check_range("sensing.lifted_fraction", self.lifted_fraction, 0.0, 1.0, lo_open=True)
        check_range("sensing.watch_period_s", self.watch_period_s, 0.001, 1.0, unit="s")
        check_range("sensing.rest_window_s", self.rest_window_s, 0.01, 2.0, unit="s")
        check_int("sensing.views_per_look", self.views_per_look, 1, 30)
        check_range("sensing.obstacle_period_s", self.obstacle_period_s, 0.01, 2.0, unit="s")


class SensorObserver:
    """The realistic observer: what a robot with a depth camera, a gripper and a wrist force/torque sensor
    knows. It has no path to the simulator's object state, contact forces or object accelerations.

    * the resting object's pose: the camera (:class:`~pickplace.perception.view.TableCamera`), when the skill
      observes; a camera re-check every ``watch_period_s`` while it watches (moved? at rest?);
    * the held object's pose: the tcp (the arm's kinematics) times the object's pose in the hand, which is the
      grasp model's when the pads close (the pads centre it along their closing axis; along their faces it sits
      where the camera saw it) and the camera's after :meth:`look_in_hand`;
    * the pads' forces: the gripper's own (its actuator's force, shared by the two coupled fingers), the
      contacts of the force-closure test: the grasp model's (one soft contact per pad face, the object's
      nominal friction);
    * slip: the fingers closing further than where they settled; a lost object: the wrist no longer carrying
      its weight; its weight: the wrist's vertical force (zeroed as the gripper closes) less the hand's own
      weight and inertia, over ``g`` plus the hand's vertical acceleration (the tool's accelerometer; the
      simulated wrist sensor is the force MuJoCo's ``cfrc_int`` gives between the flange and the hand, plus
      the sensor's noise).

    Args:
        robot: The models: the robot's own kinematics and geometry, the object's model, the camera's render.
        data: The simulation: rendered by the camera; the arm's and the gripper's state and the wrist's force
            read as their sensors report them.
        camera: The camera as calibrated (its real pose is drawn from its calibration error).
        sensing: The other sensors.
        rng: Seeded generator of the calibration error and the sensors' noise.
    """

    def __init__(self, robot: Robot, data: mujoco.MjData, camera: CameraConfig, sensing: SensingConfig,
                 rng: np.random.Generator) -> None:
        from pickplace.perception.view import TableCamera

        self.robot, self.d, self.sensing, self.rng = robot, data, sensing, rng
        self.camera = TableCamera(robot, camera, rng)
        # its own noise stream (spawned: the pose fits' stream does not depend on how many obstacle looks ran)
        self.obstacles = ObstacleCamera(self.camera, rng.spawn(1)[0])
        self._world = mujoco.MjData(robot.mj)  # the believed world (:meth:`world`)
        mujoco.mj_resetDataKeyframe(robot.mj, self._world, 0)
        self._obstacles_at = -math.inf  # when the camera last looked for obstacles (s)
        m, h = robot.mj, robot.handles
        self._tcp = h.tcp_site
        self._hand = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "gripper_base")
        self._hand_acc, self._hand_vel = np.zeros(6), np.zeros(6)  # the hand's motion (_read_hand_motion)
        self._hand_mass = float(m.body_subtreemass[self._hand])
        self._gripper = gripper.GripperGeometry.measure(robot)  # its pads, for the grasp model's contacts
        self._pads_around_m = float(np.max(robot.scene.object.geometry().extent_m)) / 2 + PADS_AROUND_M
        self._g = float(-m.opt.gravity[2])
        self._belief = pin.SE3.Identity()  # where the robot believes the resting object is
        self._observed = pin.SE3.Identity()  # where it was when last observed
        self._observed_from_hand = False  # whether that observation was measured against the hand
        self._seen = pin.SE3.Identity()  # where the latest re-check saw it
        self._T_tcp_object: pin.SE3 | None = None
        self._checks: list[tuple[float, np.ndarray, bool]] = []  # (time, position, against the hand) of re-checks
        self._moved = 0.0
        self._looked_at = -math.inf  # when the camera last re-checked (s)
        self._finger0 = 0.0
        self._tare = 0.0
        self._mass: float | None = None
        self._load = math.nan
        self._g_plus_a = math.nan
        self._t_load = math.nan
        self._sample_t = math.nan  # the step of the last load_sample (its inputs unchanged since), and its values
        self._sample = (math.nan, math.nan, math.nan)
        self.observations = 0

    # -- the camera ------------------------------------------------------------------------------------- #

    def observe(self, near: pin.SE3 | None = None) -> pin.SE3:
        """The resting object's pose from a camera image (:class:`ObjectNotSeen` if it is not seen). Near a
        pose (``near``: where the robot has just put it) the fit starts from that pose, so that a symmetry or
        another cluster of points does not read as a place error, and it is measured against the hand when the
        hand is next to it (within reach of the camera's view of the hand)."""
        close = near is not None and self._hand_near(near)
        est = self.camera.locate(self.d, near=near, start=near, from_hand=close, views=self.sensing.views_per_look)
        self._adopt_observation(est.T_world_object, close)
        log.debug("observed the %s at (%.4f, %.4f) m, residual %.2f mm, %d points", self.robot.scene.object.name,
                  *est.T_world_object.translation[:2], est.residual_m * 1e3, est.points)
        return est.T_world_object

    def look_from_hand(self) -> bool:
        """The resting object measured against the hand above it (:meth:`TableCamera.locate` ``from_hand``: the
        camera's calibration error cancels to first order), fitted from the belief, which it replaces. It is the
        new observation: the "moved" re-checks are measured against the hand too from now on (the hand near the
        object hides part of it, which biases a fit that does not register the hand). Not seen (the hand hides
        it): the belief stays.
        """
        try:
            est = self.camera.locate(self.d, near=self._belief, start=self._belief, from_hand=True,
                                     views=self.sensing.views_per_look)
        except ObjectNotSeen as exc:
            log.debug("from the hand: not seen (%s); the belief stays", exc)
            return False
        log.debug("from the hand: the %s is %.1f mm from the belief", self.robot.scene.object.name,
                  np.linalg.norm(est.T_world_object.translation - self._belief.translation) * 1e3)
        self._adopt_observation(est.T_world_object, True)
        return True

    def _adopt_observation(self, T_world_object: pin.SE3, from_hand: bool) -> None:
        """A new observation of the resting object (``from_hand``: measured against the hand): the belief, and
        the reference the "moved" and "at rest" re-checks compare with, measured the same way."""
        self.observations += 1
        self._belief = self._observed = self._seen = T_world_object
        self._observed_from_hand = from_hand
        self._T_tcp_object = None
        self._sample_t = math.nan  # the held object's pose in the hand changed
        t = float(self.d.time)
        self._checks = [(t, T_world_object.translation.copy(), from_hand)]
        self._looked_at = t
        self._moved = 0.0

    def _hand_near(self, T_world_object: pin.SE3) -> bool:
        """Whether the tcp is within ``HAND_NEAR_M`` of the object at this pose (the camera can measure it
        against the hand)."""
        return float(np.linalg.norm(self.d.site_xpos[self._tcp] - T_world_object.translation)) < HAND_NEAR_M

    def _tcp_pose(self) -> pin.SE3:
        return pin.SE3(self.d.site_xmat[self._tcp].reshape(3, 3).copy(), self.d.site_xpos[self._tcp].copy())

    def object_pose(self) -> pin.SE3:
        """The held object: the tcp times its pose in the hand; the resting object: where it was last seen."""
        if self._T_tcp_object is not None:
            return self._tcp_pose() * self._T_tcp_object
        return self._belief

    def object_position(self) -> np.ndarray:
        """The believed pose's origin (3,) (m)."""
        return self.object_pose().translation.copy()

    def _recheck(self, from_hand: bool) -> None:
        """A camera re-check of the resting object, if the last one is ``watch_period_s`` old (``from_hand``:
        measured against the hand next to it). An object the camera does not see (hidden by the hand over it)
        gives no information: neither moved nor at rest."""
        t = float(self.d.time)
        if t - self._looked_at < self.sensing.watch_period_s - 1e-9:
            return
        self._looked_at = t
        try:
            est = self.camera.recheck(self.d, self._seen, from_hand=from_hand)
        except ObjectNotSeen:  # not where it was: look over the whole table
            try:
                est, from_hand = self.camera.locate(self.d), False
            except ObjectNotSeen:  # hidden (by the hand over it, say): this image says nothing
                return
        p = est.T_world_object.translation.copy()
        self._seen = est.T_world_object
        self._checks.append((t, p, from_hand))
        if from_hand == self._observed_from_hand:  # measured as the observation was: comparable with it
            self._moved = float(np.linalg.norm(p - self._observed.translation))

    def moved_m(self) -> float:
        """Distance of the camera's latest re-check from where the object was observed, both measured the same
        way (m): against the hand if the observation was. Once the open pads reach around the object
        (:data:`PADS_AROUND_M`) the camera no longer tells: the latest re-check stands (the grasp's own checks take
        over)."""
        tcp = self.d.site_xpos[self._tcp]
        if float(np.linalg.norm(tcp - self._belief.translation)) >= self._pads_around_m:
            self._recheck(from_hand=self._observed_from_hand)
        return self._moved

    def object_velocity(self) -> np.ndarray:
        """The least-squares slope of the re-checks measured the same way as the latest (against the hand while
        the hand is near) over the last ``2 rest_window_s`` (linear only; inf until they span ``rest_window_s``).
        A line through five re-checks 0.1 s apart has 2.2 times less noise than the difference of two 0.2 s
        apart."""
        near = self._hand_near(self._seen)
        self._recheck(from_hand=near)
        if not self._checks:
            return np.full(6, math.inf)
        t, _, mode = self._checks[-1]
        window = [(tk, pk) for tk, pk, mk in self._checks if mk == mode and t - tk <= 2 * self.sensing.rest_window_s]
        ts = np.array([tk for tk, _ in window])
        if t - ts[0] < self.sensing.rest_window_s - 1e-9:
            return np.full(6, math.inf)
        ps = np.array([pk for _, pk in window])
        dt = ts - ts.mean()
        return np.concatenate([dt @ (ps - ps.mean(axis=0)) / (dt @ dt), np.zeros(3)])

    def look_in_hand(self) -> None:
        """The held object's position along the pads' faces across the approach (tcp x) from a camera image
        (:class:`ObjectNotSeen` if not seen); along the closing axis (the pads centre it) and the approach (as
        deep as the hand went) it stays the grasp model's."""
        est = self.camera.in_hand(self.d, self.object_pose(), free_axes=self._tcp_pose().rotation[:, :1])
        self.observations += 1
        self._T_tcp_object = self._tcp_pose().actInv(est.T_world_object)
        self._sample_t = math.nan  # the held object's pose in the hand changed

    # -- the gripper and the wrist ---------------------------------------------------------------------- #

    def closing(self) -> None:
        """Zero the wrist sensor with the gripper empty: what it reads less the hand's own weight and inertia
        (the hand may still move a little as the arm settles)."""
        f, a = self._wrist()
        self._tare = f - self._hand_mass * (self._g + a)
        self._sample_t = math.nan

    def grasped(self, T_tcp_object_model: pin.SE3) -> None:
        """In the hand where it was seen, centred between the pads along their closing axis (tcp y), turned as
        the grasp model holds it (the pads square it up: the yaw error of the look it was grasped from does not
        carry into the hand)."""
        p = self._tcp_pose().actInv(self._belief).translation.copy()
        p[1] = T_tcp_object_model.translation[1]
        self._T_tcp_object = pin.SE3(T_tcp_object_model.rotation.copy(), p)
        self._sample_t = math.nan  # the held object's pose in the hand changed

    def released(self) -> None:
        """The object stays where it was believed to be when the pads opened."""
        self._belief = self._seen = self.object_pose()
        self._T_tcp_object = None
        self._sample_t = math.nan  # the held object's pose in the hand changed
        self._mass = None
        self._checks = []

    def grip_force(self) -> float:
        """The gripper's force (its actuator's); 0 when it pulls the pads open (N)."""
        return max(0.0, float(self.d.actuator_force[self.robot.handles.gripper_actuator]))

    def pad_forces(self) -> np.ndarray:
        """The gripper's force (:meth:`grip_force`), half on each pad (N)."""
        return np.full(2, self.grip_force() / 2.0)

    def pad_contacts(self) -> list[Contact]:
        """One soft contact at the middle of each pad's face, on the object (the grasp model's)."""
        geom = self._gripper
        obj = self.robot.scene.object
        tcp = self._tcp_pose()
        face = geom.open_inner_face_y_m - gripper.finger_travel(self.robot, self.d)
        centre = np.array(geom.pad_box_m[:3])
        out = []
        for side in (1.0, -1.0):
            local = np.array([centre[0], side * face, centre[2]])
            out.append(Contact(tcp.act(local), tcp.rotation @ np.array([0.0, -side, 0.0]), obj.friction,
                               obj.torsional_friction_m))
        return out

    def _wrist(self) -> tuple[float, float]:
        """The wrist sensor's vertical force on the hand (N), with the sensor's noise, and the tool
        accelerometer's vertical acceleration of the hand's centre of mass (m/s^2), read together."""
        mujoco.mj_rnePostConstraint(self.robot.mj, self.d)  # the forces and accelerations of this state
        f = float(self.d.cfrc_int[self._hand, 5])  # the wrist's force on the hand (world frame)
        self._read_hand_motion()
        a = self._hand_acceleration_z(self.d.subtree_com[self._hand])
        return f + float(self.rng.normal(0.0, self.sensing.wrist_force_noise_n)), a

    def _read_hand_motion(self) -> None:
        """Read the hand's spatial acceleration (of the last ``mj_rnePostConstraint``, :meth:`_wrist`) and velocity
        (world orientation, at its origin) for :meth:`_hand_acceleration_z`."""
        m, d = self.robot.mj, self.d
        mujoco.mj_objectAcceleration(m, d, mujoco.mjtObj.mjOBJ_BODY, self._hand, self._hand_acc, 0)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, self._hand, self._hand_vel, 0)

    def _hand_acceleration_z(self, at: np.ndarray | None = None) -> float:
        """The tool's accelerometer: the hand's vertical acceleration (m/s^2) at its origin, or carried to the
        point ``at`` (3,) (m) of the hand (rigid-body kinematics with the hand's angular velocity and
        acceleration: where the held object is), from the motion :meth:`_read_hand_motion` read."""
        acc = self._hand_acc
        a_z = float(acc[5]) - self._g  # it reads the specific force; less gravity's: the acceleration
        if at is not None:
            rx, ry, rz = (at - self.d.xpos[self._hand]).tolist()
            ax, ay = float(acc[0]), float(acc[1])
            wx, wy, wz = self._hand_vel[:3].tolist()
            # the z components of alpha x r and of w x (w x r) = w (w . r) - r (w . w)
            a_z += ax * ry - ay * rx + wz * (wx * rx + wy * ry + wz * rz) - rz * (wx * wx + wy * wy + wz * wz)
        return a_z

    def load_sample(self) -> tuple[float, float, float]:
        """The gripper's force, the wrist's vertical force less its zero and the hand's own weight and inertia,
        and ``g`` plus the held object's vertical acceleration (where the robot believes it is in the hand).

        The sensors are read once per physics step: the checks that ask again in the same step (the lift's and the
        monitor's) get the same reading."""
        t = float(self.d.time)
        if t == self._sample_t:
            return self._sample
        f, a = self._wrist()
        load = f - self._tare - self._hand_mass * (self._g + a)
        a_object = self._hand_acceleration_z(self.object_position()) if self._T_tcp_object is not None else a
        self._sample_t, self._sample = t, (self.grip_force(), load, self._g + a_object)
        return self._sample

    def airborne(self, z0_m: float, mass_kg: float) -> bool:
        """The hand has risen 3 mm and the wrist carries at least ``lifted_fraction`` of the weight (low-passed
        from the start of the lift: pads sliding along an object that stays on the table drag some of it)."""
        load, expected = self._filtered_load(mass_kg)
        return bool(self.object_position()[2] > z0_m + 0.003) and load >= self.sensing.lifted_fraction * expected

    def touched_down(self, mass_kg: float) -> bool:
        """The wrist carries less than ``load_lost_fraction`` of the weight: the table takes the rest (a guarded
        set-down: the object's height in the hand is known to a millimetre or so, the table's touch exactly)."""
        load, expected = self._filtered_load(mass_kg)
        return load < self.sensing.load_lost_fraction * expected

    def _filtered_load(self, mass_kg: float) -> tuple[float, float]:
        """The wrist's load and what an object of ``mass_kg`` weighs with the accelerations now (N), both
        low-passed alike."""
        _, load, g_plus_a = self.load_sample()
        t = float(self.d.time)
        if math.isnan(self._load):
            self._load, self._g_plus_a, self._t_load = load, g_plus_a, t
        else:
            tau = self.sensing.load_filter_s
            alpha = min(1.0, (t - self._t_load) / tau) if tau > 0 else 1.0
            self._load += alpha * (load - self._load)
            self._g_plus_a += alpha * (g_plus_a - self._g_plus_a)
            self._t_load = t
        return self._load, mass_kg * self._g_plus_a

    def start_holding(self) -> None:
        """The fingers' travel now is the reference."""
        self._load = math.nan
        self._finger0 = gripper.finger_travel(self.robot, self.d)

    def slip_m(self) -> float:
        """How much further the fingers have closed (or opened) since the grip settled (m)."""
        return abs(gripper.finger_travel(self.robot, self.d) - self._finger0)

    def expect_load(self, mass_kg: float | None) -> None:
        """Watch the wrist for this weight from now on."""
        self._mass = mass_kg

    def payload_mass_kg(self, modelled_kg: float, weighed_kg: float) -> float:
        """What the wrist weighed during the lift (the model's mass if it weighed nothing)."""
        return weighed_kg if math.isfinite(weighed_kg) and weighed_kg > 0.0 else modelled_kg

    def grip_lost(self) -> str | None:
        """The wrist carries less than ``load_lost_fraction`` of the weight (low-passed), or None."""
        if self._mass is None:
            return None
        load, expected = self._filtered_load(self._mass)
        if load < self.sensing.load_lost_fraction * expected:
            return (f"the wrist carries {load:.2f} N of the {self.robot.scene.object.name}'s "
                    f"{expected:.2f} N (less than {self.sensing.load_lost_fraction:.0%})")
        return None

    def world(self) -> mujoco.MjData:
        """The believed world: the robot's map (the model's static geometry; the fault intruder parked, as
        the map has it), the object at :meth:`object_pose`, and the unknown obstacles the camera saw at its
        latest look (:class:`~pickplace.perception.obstacles.ObstacleCamera`, a new look when the last is
        ``obstacle_period_s`` old; left out: wherever the object may be, whatever the error of its believed
        yaw, :meth:`TableCamera.object_sphere`)."""
        w, T = self._world, self.object_pose()
        a = self.robot.handles.object_qpos
        w.qpos[a:a + 3] = T.translation
        mujoco.mju_mat2Quat(w.qpos[a + 3:a + 7], T.rotation.ravel())
        t = float(self.d.time)
        if t - self._obstacles_at >= self.sensing.obstacle_period_s:
            self._obstacles_at = t
            held_at = self.d.site_xpos[self._tcp] if self._T_tcp_object is not None else None
            columns = self.obstacles.columns(self.d, [self.camera.object_sphere(T, held_at)])
            self.obstacles.place(w, columns)
            log.debug("t = %.3f s: the camera sees %d cells of unknown obstacles%s", t, len(columns),
                      f", up to {columns[0, 2]:.3f} m" if len(columns) else "")
        return w

    def close(self) -> None:
        """Release the cameras' OpenGL contexts."""
        self.camera.close()
        self.obstacles.close()


__all__ = ["Observer", "SensingConfig", "SensorObserver", "SimulatorObserver"]
