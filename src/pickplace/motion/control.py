"""Joint and Cartesian impedance control of the UR5e, and the loops that run them in MuJoCo.

Control laws (pure functions of the measured state and a reference, returning arm torques (6,) in N m):

* :func:`joint_impedance`: ``tau = Kp (q_d - q) + Kd (qd_d - qd) + g(q)``, plus, with feedforward, the
  inverse dynamics of the reference ``M(q) qdd_d + C(q, qd_d) qd_d`` (one ``pin.rnea`` call) and the
  joints' viscous damping ``D qd_d``.
* :func:`cartesian_impedance`: operational-space impedance of the tcp,
  ``tau = J^T [Lambda (a_d - Jdot qd) + K e + D edot] + C(q, qd) qd + g(q) + D_joint qd + N^T tau_posture``,
  with the 6D pose error ``e`` (world-aligned, SO(3) log), the task-space inertia ``Lambda = (J M^-1 J^T)^-1``
  and the dynamically consistent null-space projector ``N^T = I - J^T Lambda J M^-1``.

Both laws run on :class:`ArmModel`, the controller's own copy of the Pinocchio model. Two things make it
match what MuJoCo integrates, so that feedforward is exact and feedback only mops up:

* Pinocchio's MJCF parser keeps the joints' ``armature`` (``pin.Model.armature``) and ``crba``/``rnea``
  include it (``M`` agrees with MuJoCo's to 1e-15); the joints' ``damping`` is parsed too
  (``pin.Model.damping``) but no Pinocchio algorithm applies it, so the laws add ``D qd`` themselves.
* MuJoCo's Euler and implicit integrators treat joint damping implicitly: the velocity update solves
  ``(M + h D) dv = h f``. The controller's model therefore carries an *effective* armature
  ``armature + h * damping`` (h the timestep), so ``rnea`` and ``crba`` return the inertia the step really
  applies (about 1 % on the wrists).

A held object is unknown to the robot model: :class:`Payload` (mass, centre of mass and inertia in the tcp
frame) is added rigidly to the tcp's parent joint (wrist 3) of the controller's model.

Loops (:func:`track`, :func:`hold`, :func:`stop`, :func:`move_linear`, :func:`move_vertical`) run their law
through a :class:`~pickplace.motion.loop.ControlLoop` (``loop=``): by default the ideal loop, which reads the
exact state and applies the torque every physics step (``mujoco.mj_step``, the model's timestep); a realistic
one (:meth:`~pickplace.motion.loop.LoopConfig.realistic`) reads encoders at 500 Hz and applies each torque one
period later, held.

In the ideal loop, joint impedance with feedforward (the default gains) runs on *position servos*: the arm's
actuators take ``kp`` for the loop (:class:`~pickplace.motion.loop.ServoGains`) and MuJoCo applies ``kp (u - q)``
at every physics step; the control sent each step is ``u = u_ref - (kd / kp) qd``, the velocities read at the
step, with the setpoint ``u_ref = q_ref + (kd qd_ref + tau_ff) / kp`` computed for the whole reference ahead
(:func:`servo_setpoints`) and the feedforward evaluated on the reference, ``tau_ff = M(q_ref) qdd_ref + C(q_ref,
qd_ref) qd_ref + g(q_ref) + D qd_ref``. It differs from :func:`joint_impedance` only in where the feedforward's
model terms are evaluated (the reference instead of the measured state: ``dg/dq e``, the tracking error times
gravity's gradient, micro-newton-metres at the micro-radian errors the arm tracks with). The damping stays
explicit (:meth:`~pickplace.motion.loop.ControlLoop.run_servo` says why). The Python around the physics is then
two numpy calls for the control, the error check and the monitor (``pickplace bench loop``). Loops whose law needs
the state in Python run it there: Cartesian impedance, computed-torque or integral gains, holds that comply along
an axis, a sensor fault's noise, and every realistic loop (500 Hz, latency, encoders).

The loops write the six arm actuators' controls only (never the gripper's), keep the torques within
``robot.torque_limits_nm`` (clipped by the law, or by the actuators' force range) and count the clipped ticks, call
an optional ``hook(data)`` after every physics step (it may raise a :class:`~pickplace.errors.PickPlaceError` to
abort; it propagates), and return frozen records with figures and time series, one row per control tick. For the
realistic profile, :meth:`ControlConfig.realistic` has the gains (inertia-scaled joint damping, modal Cartesian
damping, integral action) and its docstring the reasons.

References are made consistent with MuJoCo's semi-implicit Euler step (``v' = v + h a``, ``q' = q + h v'``):
positions are sampled on the step grid, the velocity reference is their backward difference and the
acceleration reference their second difference. A state that matches the reference then stays on it
exactly; with ``qd_d = qd(t)`` instead, the simulated arm would lag the reference by ``h/2 * qd`` (about
1.5 mrad at full speed).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import mujoco
import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dgetrf as _getrf
from scipy.linalg.lapack import dgetri as _getri

from pickplace.errors import ConfigError, ControlError
from pickplace.motion.loop import IDEAL, ControlLoop, Measured
from pickplace.motion.timing import Trajectory
from pickplace.robot.kinematics import frame_jacobian
from pickplace.robot.model import Robot
from pickplace.world.config import check_range, check_vector
from pickplace.world.mass import mass_properties
from pickplace.world.objects import ObjectConfig

log = logging.getLogger(__name__)

N_ARM = 6
#: Peak speed of a minimum-jerk profile over a distance d in a time T is 1.875 d / T.
_MIN_JERK_PEAK_SPEED = 1.875
#: Peak acceleration of a minimum-jerk profile is 10 / sqrt(3) d / T^2.
_MIN_JERK_PEAK_ACCEL = 10.0 / math.sqrt(3.0)

#: Armature (kg) given to the finger slides in the controller's model, so that ``computeMinverse``'s arm block
#: is the inverse of the arm's inertia with the fingers locked (they are held by their servo or squeezed on
#: the object). The laws themselves use the arm block of ``M`` (``crba``), which is that inertia whatever the
#: fingers' armature, and zero finger accelerations: it changes nothing they compute.
LOCKED_FINGER_ARMATURE = 1e9

#: Window (s) over which a realistic loop measures the tcp's speed for the settle test of a straight move: the
#: mean speed ``|p(t) - p(t - window)| / window`` of the positions read. The filtered velocity the law uses is
#: dominated by the encoders there: a change of one count (2.4e-5 rad) between two 2 ms ticks is 0.012 rad/s, 5 mm/s
#: at the tcp, and half a count of noise per reading as much again. Measured with the arm held at the pregrasp
#: pose of the realistic profile (true tcp speed 0.55 mm/s): the filtered velocity reads a median 4.5 mm/s and is
#: above the 2 mm/s settle speed in 92 % of the ticks; the 20 ms window reads a median 0.74 mm/s, above it in 0.2 %.
SETTLE_SPEED_WINDOW_S = 0.02

Hook = Callable[[mujoco.MjData], None]
#: The torques' columns in a row of the arm's state tape (robot.model.ARM_STATE_FIELDS).
_TAU = slice(12, 18)


# --------------------------------------------------------------------------- #
# configuration
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class ControlConfig:
    """Gains and motion parameters of the controllers (SI units).

    Attributes:
        joint_kp_nm_rad: Joint stiffness per arm joint (6,) (N m/rad).
        joint_damping_ratio: Joint damping ratio; ``kd = 2 * ratio * sqrt(kp)`` (N m s/rad).
        feedforward: Add the inverse dynamics of the reference (and the joints' damping) to joint control.
        cartesian_stiffness_n_m: Translational stiffness of the tcp (N/m).
        cartesian_rot_stiffness_nm_rad: Rotational stiffness of the tcp (N m/rad).
        cartesian_damping_ratio: Damping ratio of each task axis, ``d_i = 2 * ratio * sqrt(k_i * Lambda_ii)``
            with Lambda the task-space inertia; also used for the posture gain.
        posture_kp_nm_rad: Null-space posture stiffness (N m/rad), towards q at the start of a Cartesian
            move. The UR5e has 6 joints and the tcp task has 6 axes, so the null space is empty away from
            singularities and this term is projected to ~0; it only acts if the arm is redundant.
        vertical_speed_m_s: Peak tcp speed of a vertical move (m/s), minimum-jerk profile.
        vertical_accel_m_s2: Peak tcp acceleration of a vertical move (m/s^2).
        vertical_min_duration_s: Shortest vertical move (s).
        height_tolerance_m: A vertical move ends when the tcp is this close to the target height (m) ...
        settle_speed_m_s: ... and the tcp moves slower than this (m/s), after the profile has ended.
        settle_timeout_s: Time allowed after the profile's end to meet both (s); then it times out.
        max_joint_error_rad: Joint tracking error (any joint) beyond which a joint loop aborts (rad).
        max_tcp_error_m: Tcp position error beyond which a Cartesian move aborts (m).
        joint_kd_nm_s_rad: Joint damping per joint (6,) (N m s/rad), replacing ``joint_damping_ratio``'s
            ``2 * ratio * sqrt(kp)`` (which assumes a unit inertia) on each joint where it is > 0; 0 (the
            default): that formula.
        joint_ki_nm_rad_s: Integral gain of the joint loops per joint (6,) (N m per rad s); 0 (the default):
            no integral action. It removes what the model does not know and the feedback would otherwise
            have to hold with an error: unknown friction, model error in gravity.
        joint_integral_limit_nm: Bound of the joint integral torque per joint (6,) (N m) (anti-windup).
        cartesian_modal_damping: Damp each mode of ``Lambda e'' + K e = 0`` at ``cartesian_damping_ratio``
            (double diagonalization: ``Lambda = Q Q^T``, ``K = Q K0 Q^T``, ``D = Q 2 zeta sqrt(K0) Q^T``) instead of
            each axis by its diagonal ``Lambda_ii``. The diagonal overdamps the light modes (the wrist's rotations
            couple with the translations: ``Lambda_ii`` of a rotation is ~5 times the lightest modal inertia), which
            is harmless with exact, instant feedback and unstable with a few milliseconds of loop delay.
        cartesian_ki_n_m_s: Integral gain of the Cartesian loop on the tcp position error (N per m s); 0: none.
        cartesian_rot_ki_nm_rad_s: Integral gain on the tcp orientation error (N m per rad s); 0: none.
        cartesian_integral_limit_n: Bound of the integral force per axis (N).
        cartesian_integral_limit_nm: Bound of the integral torque per axis (N m).
        cartesian_bandwidth_rad_s: > 0: shape the Cartesian gains by the task-space inertia ``Lambda(q)`` so that
            every mode of the tcp error has this bandwidth (rad/s): ``K = w^2 Lambda``, ``D = 2 zeta w Lambda``
            (Khatib's operational-space law, ``F = Lambda (a_d - Jdot qd + w^2 e + 2 zeta w edot)``); for the
            UR5e's square Jacobian that is the joint stiffness ``w^2 M(q)``, the joint loops' design. It replaces
            ``cartesian_stiffness_n_m``, ``cartesian_rot_stiffness_nm_rad``, ``cartesian_modal_damping`` and the
            Cartesian ``ki``. 0 (the default): the fixed diagonal stiffness.
        cartesian_integral_zero_rad_s: With ``cartesian_bandwidth_rad_s``: the zero of the Cartesian integral
            action (rad/s), ``ki = zero * K = zero * w^2 Lambda(q)``, integrated tick by tick; 0: no integral.
        joint_bandwidth_rad_s: > 0: shape the joint gains by the arm's inertia ``M(q)`` (computed torque) so that
            every mode of the joint error has this bandwidth (rad/s): ``Kp = w^2 M(q)``, ``Kd = 2 zeta w M(q)`` with
            ``zeta = joint_damping_ratio``. A diagonal ``kp_j = w^2 M_jj`` puts the coupled modes of the shoulder,
            elbow and wrists above ``w`` (the lightest eigen-inertia is smaller than any ``M_jj``), and only at the
            pose it was computed for. It replaces ``joint_kp_nm_rad``, ``joint_kd_nm_s_rad`` and
            ``joint_ki_nm_rad_s``; 0 (the default): those diagonal gains.
        joint_integral_zero_rad_s: With ``joint_bandwidth_rad_s``: the zero of the joint integral action (rad/s),
            ``Ki = zero * w^2 M(q)``, integrated tick by tick; 0: no integral.
        comply_while_closing: While the gripper closes on the object, the arm yields along the pads' closing
            axis (the hold's reference follows the tcp along it every control period: an admittance whose force
            sensor is the arm's own deflection) and holds stiffly in the other five directions. A hand off the
            object's centre by the pose estimate's error is then centred by the first pad to touch, instead of
            that pad pushing the arm (and the object) until the second arrives. The ideal robot knows the
            object's pose exactly and holds rigidly (default off); :meth:`realistic` turns it on.
        blend_approach: The approach runs into the straight descent to the grasp without stopping at the pregrasp:
            one trajectory, the planned path and the descent's IK waypoints timed together
            (:func:`~pickplace.motion.timing.retime_parts`), the tcp on the descent's line from the pregrasp on.
            Off: the arm stops at the pregrasp and descends by a Cartesian move. A robot that looks at the object
            from there stops whatever this says (only one that reads the object's pose from the simulation, the
            ideal profile's, runs through): :meth:`realistic` turns it off.
        blend_lift: The lift runs into the transport (planned before the lift, from the grip as it settled).
        blend_set_down: The transport runs into the set-down, re-aimed while it runs from the object's pose in
            the hand as it passes the preplace. Off: the arm stops above the goal, re-aims and sets the object
            down by a guarded Cartesian move (a robot that looks at the object in its hand there always does).
        blend_retract: The back-off from the released object runs into the way home.
    """

    joint_kp_nm_rad: tuple[float, ...] = (200.0, 200.0, 200.0, 100.0, 100.0, 100.0)
    joint_damping_ratio: float = 1.0
    feedforward: bool = True
    cartesian_stiffness_n_m: float = 3000.0
    cartesian_rot_stiffness_nm_rad: float = 300.0
    cartesian_damping_ratio: float = 1.0
    posture_kp_nm_rad: float = 10.0
    vertical_speed_m_s: float = 0.6
    vertical_accel_m_s2: float = 4.0
    vertical_min_duration_s: float = 0.3
    height_tolerance_m: float = 2e-4
    settle_speed_m_s: float = 2e-3
    settle_timeout_s: float = 1.0
    max_joint_error_rad: float = 0.1
    max_tcp_error_m: float = 0.02
    joint_kd_nm_s_rad: tuple[float, ...] = (0.0,) * N_ARM
    joint_ki_nm_rad_s: tuple[float, ...] = (0.0,) * N_ARM
    joint_integral_limit_nm: tuple[float, ...] = (30.0, 30.0, 30.0, 6.0, 6.0, 6.0)
    cartesian_modal_damping: bool = False
    cartesian_ki_n_m_s: float = 0.0
    cartesian_rot_ki_nm_rad_s: float = 0.0
    cartesian_integral_limit_n: float = 30.0
    cartesian_integral_limit_nm: float = 5.0
    cartesian_bandwidth_rad_s: float = 0.0
    cartesian_integral_zero_rad_s: float = 0.0
    joint_bandwidth_rad_s: float = 0.0
    joint_integral_zero_rad_s: float = 0.0
    comply_while_closing: bool = False
    blend_approach: bool = True
    blend_lift: bool = True
    blend_set_down: bool = True
    blend_retract: bool = True

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        for name in ("blend_approach", "blend_lift", "blend_set_down", "blend_retract"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"control.{name}", getattr(self, name), "must be true or false")
        set_(self, "joint_kp_nm_rad", check_vector("control.joint_kp_nm_rad", self.joint_kp_nm_rad, N_ARM,
                                                   0.0, 1e5, lo_open=True, unit="N m/rad"))
        set_(self, "joint_damping_ratio", check_range("control.joint_damping_ratio", self.joint_damping_ratio,
                                                      0.0, 10.0, lo_open=True))
        if not isinstance(self.cartesian_modal_damping, bool):
            raise ConfigError("control.cartesian_modal_damping", self.cartesian_modal_damping, "must be true or false")
        if not isinstance(self.feedforward, bool):
            raise ConfigError("control.feedforward", self.feedforward, "must be true or false")
        if not isinstance(self.comply_while_closing, bool):
            raise ConfigError("control.comply_while_closing", self.comply_while_closing, "must be true or false")
        set_(self, "cartesian_stiffness_n_m", check_range(
            "control.cartesian_stiffness_n_m", self.cartesian_stiffness_n_m, 0.0, 1e6, lo_open=True, unit="N/m"))
        set_(self, "cartesian_rot_stiffness_nm_rad", check_range(
            "control.cartesian_rot_stiffness_nm_rad", self.cartesian_rot_stiffness_nm_rad, 0.0, 1e5, lo_open=True,
            unit="N m/rad"))
        set_(self, "cartesian_damping_ratio", check_range(
            "control.cartesian_damping_ratio", self.cartesian_damping_ratio, 0.0, 10.0, lo_open=True))
        set_(self, "posture_kp_nm_rad", check_range("control.posture_kp_nm_rad", self.posture_kp_nm_rad,
                                                    0.0, 1e4, unit="N m/rad"))
        set_(self, "vertical_speed_m_s", check_range("control.vertical_speed_m_s", self.vertical_speed_m_s,
                                                     0.0, 2.0, lo_open=True, unit="m/s"))
        set_(self, "vertical_accel_m_s2", check_range("control.vertical_accel_m_s2", self.vertical_accel_m_s2,
                                                      0.0, 20.0, lo_open=True, unit="m/s^2"))
        set_(self, "vertical_min_duration_s", check_range(
            "control.vertical_min_duration_s", self.vertical_min_duration_s, 0.0, 10.0, unit="s"))
        set_(self, "height_tolerance_m", check_range("control.height_tolerance_m", self.height_tolerance_m,
                                                     0.0, 0.01, lo_open=True, unit="m"))
        set_(self, "settle_speed_m_s", check_range("control.settle_speed_m_s", self.settle_speed_m_s,
                                                   0.0, 0.1, lo_open=True, unit="m/s"))
        set_(self, "settle_timeout_s", check_range("control.settle_timeout_s", self.settle_timeout_s,
                                                   0.0, 10.0, unit="s"))
        set_(self, "max_joint_error_rad", check_range("control.max_joint_error_rad", self.max_joint_error_rad,
                                                      0.0, math.pi, lo_open=True, unit="rad"))
        set_(self, "max_tcp_error_m", check_range("control.max_tcp_error_m", self.max_tcp_error_m,
                                                  0.0, 1.0, lo_open=True, unit="m"))
        set_(self, "joint_kd_nm_s_rad", check_vector("control.joint_kd_nm_s_rad", self.joint_kd_nm_s_rad, N_ARM,
                                                     0.0, 1e5, unit="N m s/rad"))
        set_(self, "joint_ki_nm_rad_s", check_vector("control.joint_ki_nm_rad_s", self.joint_ki_nm_rad_s, N_ARM,
                                                     0.0, 1e6, unit="N m/(rad s)"))
        set_(self, "joint_integral_limit_nm", check_vector(
            "control.joint_integral_limit_nm", self.joint_integral_limit_nm, N_ARM, 0.0, 150.0, unit="N m"))
        set_(self, "cartesian_ki_n_m_s", check_range("control.cartesian_ki_n_m_s", self.cartesian_ki_n_m_s,
                                                     0.0, 1e7, unit="N/(m s)"))
        set_(self, "cartesian_rot_ki_nm_rad_s", check_range(
            "control.cartesian_rot_ki_nm_rad_s", self.cartesian_rot_ki_nm_rad_s, 0.0, 1e6, unit="N m/(rad s)"))
        set_(self, "cartesian_integral_limit_n", check_range(
            "control.cartesian_integral_limit_n", self.cartesian_integral_limit_n, 0.0, 1000.0, unit="N"))
        set_(self, "cartesian_integral_limit_nm", check_range(
            "control.cartesian_integral_limit_nm", self.cartesian_integral_limit_nm, 0.0, 100.0, unit="N m"))
        set_(self, "cartesian_bandwidth_rad_s", check_range(
            "control.cartesian_bandwidth_rad_s", self.cartesian_bandwidth_rad_s, 0.0, 1000.0, unit="rad/s"))
        set_(self, "cartesian_integral_zero_rad_s", check_range(
            "control.cartesian_integral_zero_rad_s", self.cartesian_integral_zero_rad_s, 0.0, 1000.0, unit="rad/s"))
        set_(self, "joint_bandwidth_rad_s", check_range(
            "control.joint_bandwidth_rad_s", self.joint_bandwidth_rad_s, 0.0, 1000.0, unit="rad/s"))
        set_(self, "joint_integral_zero_rad_s", check_range(
            "control.joint_integral_zero_rad_s", self.joint_integral_zero_rad_s, 0.0, 1000.0, unit="rad/s"))
        if self.joint_integral_zero_rad_s > 0.0 and self.joint_bandwidth_rad_s == 0.0:
            raise ConfigError("control.joint_integral_zero_rad_s", self.joint_integral_zero_rad_s,
                              "needs control.joint_bandwidth_rad_s > 0 (use joint_ki_nm_rad_s otherwise)")
        if self.cartesian_integral_zero_rad_s > 0.0 and self.cartesian_bandwidth_rad_s == 0.0:
            raise ConfigError("control.cartesian_integral_zero_rad_s", self.cartesian_integral_zero_rad_s,
                              "needs control.cartesian_bandwidth_rad_s > 0 (use cartesian_ki_n_m_s otherwise)")

    @classmethod
    def realistic(cls) -> ControlConfig:
        """Gains for the realistic profile: :meth:`LoopConfig.realistic` (500 Hz, 2 ms latency, filtered
        velocity), :meth:`~pickplace.robot.model_error.ModelErrorConfig.realistic` (inertial error, friction
        unknown to the controller).

        Why the ideal gains do not do there (measured in ``tests/test_loop.py``):

        * ``kd = 2 zeta sqrt(kp)`` assumes a unit inertia. On the wrists (about 0.05-0.09 kg m^2 with the rotors'
          armature) it is a damping bandwidth ``kd / M`` of 220-390 1/s, past what a loop delay of about 5 ms
          (2 ms latency + 1 ms zero-order hold + 1 ms of backward difference + 1.6 ms of velocity filter) keeps
          stable (``kd / M < pi / (2 delay)``): here the damping is set per joint from its inertia.
        * Friction (a few N m) and gravity error (10 % of ~60 N m) against kp = 200 N m/rad leave 15-30 mrad: the
          stiffness must be raised, and integral action added.
        * Gains fixed per joint or per Cartesian axis give the arm's modes bandwidths spread by their inertias. The
          tcp's translations weigh 6-13 kg and its rotations 0.05-0.09 kg m^2, so 8000 N/m and 200 N m/rad (with
          modal damping) put the translations at 15-35 rad/s and the rotations at 64-89 rad/s; with an integral
          zero (ki / K = 19 rad/s) above the slowest modes, against 3 N m of Coulomb friction, the tcp hunted
          0.2-0.6 mm about its set-down target for over a second (5 of seeds 0-19 timed out in DESCEND_PLACE) and
          every straight move waited 0.7 s to settle. In joint space, ``kp_j = w^2 M_jj`` (diagonal) leaves the
          coupled modes above ``w`` (the smallest eigen-inertia is below every ``M_jj``): at ``w = 80 rad/s`` that
          saturated the motors, at 60 rad/s it left 4.2 mrad on wrist 3 (1 N m of friction against 190 N m/rad).

        Both loops therefore shape their gains by the controller's inertia (computed torque): joint
        ``Kp = w^2 M(q)``, ``Kd = 2 zeta w M(q)``, ``Ki = z Kp`` (:attr:`joint_bandwidth_rad_s`), Cartesian
        ``K = w^2 Lambda(q)``, ``D = 2 zeta w Lambda(q)``, ``Ki = z K`` (:attr:`cartesian_bandwidth_rad_s`); for the
        UR5e's square Jacobian the two are the same stiffness ``w^2 M(q)``. Every mode then has the bandwidth ``w``
        at every pose and with any payload (the inertia error, +/- 10 %, moves it by +/- 5 %).

        ``w = 80 rad/s``, ``zeta = 1``, ``z = 0.4 w = 32 rad/s``. Measured by replaying the moves of seeds 0-19 from
        their start states: both loops limit-cycle (motor torques at their limits) at 200 rad/s and are stable at
        150 rad/s, so 80 rad/s keeps a gain margin of about 2. Against Coulomb friction a stiffer loop has a
        narrower stick band (``F_c / (w^2 M)``): at 80 rad/s the straight moves settle within their 0.2 mm about
        20 ms after the profile (60 rad/s: 0.3 s) and the joint moves stay within 2 mrad (the diagonal gains: 4.2).

        The approach stops at the pregrasp and the transport above the goal (``blend_approach`` and
        ``blend_set_down`` off): the robot looks at the object from the hand at both, and sets it down by a guarded
        move that stops when the wrist feels the table take the weight.
        """
        return cls(joint_bandwidth_rad_s=80.0, joint_damping_ratio=1.0, joint_integral_zero_rad_s=32.0,
                   cartesian_bandwidth_rad_s=80.0, cartesian_damping_ratio=1.0, cartesian_integral_zero_rad_s=32.0,
                   comply_while_closing=True, blend_approach=False, blend_set_down=False)

    @property
    def joint_kp(self) -> np.ndarray:
        """Joint stiffness (6,) (N m/rad)."""
        return np.array(self.joint_kp_nm_rad)

    @property
    def joint_ki(self) -> np.ndarray:
        """Joint integral gains (6,) (N m per rad s)."""
        return np.array(self.joint_ki_nm_rad_s)

    @property
    def joint_integral(self) -> bool:
        """Whether the joint loops have integral action."""
        if self.joint_bandwidth_rad_s > 0.0:
            return self.joint_integral_zero_rad_s > 0.0
        return any(k > 0.0 for k in self.joint_ki_nm_rad_s)

    @property
    def cartesian_ki(self) -> np.ndarray:
        """Cartesian integral gains (6,): position (N per m s) then orientation (N m per rad s)."""
        return np.array([self.cartesian_ki_n_m_s] * 3 + [self.cartesian_rot_ki_nm_rad_s] * 3)

    @property
    def cartesian_integral_limit(self) -> np.ndarray:
        """Bounds (6,) of the Cartesian integral term: force (N) then torque (N m)."""
        return np.array([self.cartesian_integral_limit_n] * 3 + [self.cartesian_integral_limit_nm] * 3)

    @property
    def cartesian_integral(self) -> bool:
        """Whether the Cartesian loop has integral action."""
        if self.cartesian_bandwidth_rad_s > 0.0:
            return self.cartesian_integral_zero_rad_s > 0.0
        return self.cartesian_ki_n_m_s > 0.0 or self.cartesian_rot_ki_nm_rad_s > 0.0

    @property
    def joint_kd(self) -> np.ndarray:
        """Joint damping (6,) (N m s/rad): ``joint_kd_nm_s_rad`` where > 0, else ``2 * ratio * sqrt(kp)``."""
        kd = 2.0 * self.joint_damping_ratio * np.sqrt(self.joint_kp)
        if any(v > 0.0 for v in self.joint_kd_nm_s_rad):
            given = np.array(self.joint_kd_nm_s_rad)
            kd = np.where(given > 0.0, given, kd)
        return kd

    @property
    def cartesian_stiffness(self) -> np.ndarray:
        """Task stiffness (6,): translational (N/m) then rotational (N m/rad)."""
        return np.array([self.cartesian_stiffness_n_m] * 3 + [self.cartesian_rot_stiffness_nm_rad] * 3)

    @property
    def posture_kd(self) -> float:
        """Null-space posture damping (N m s/rad): ``2 * cartesian_damping_ratio * sqrt(posture_kp)``."""
        return 2.0 * self.cartesian_damping_ratio * math.sqrt(self.posture_kp_nm_rad)

    def vertical_duration_s(self, distance_m: float) -> float:
        """Duration (s) of a minimum-jerk vertical move over ``distance_m`` within the speed/accel limits."""
        d = abs(distance_m)
        return max(self.vertical_min_duration_s, _MIN_JERK_PEAK_SPEED * d / self.vertical_speed_m_s,
                   math.sqrt(_MIN_JERK_PEAK_ACCEL * d / self.vertical_accel_m_s2))


@dataclass(frozen=True)
class Payload:
    """An object held rigidly at the tcp, unknown to the robot model.

    Attributes:
        mass_kg: Mass (kg).
        com_tcp_m: Centre of mass in the tcp frame (3,) (m).
        inertia_kg_m2: Inertia about the centre of mass, tcp axes (kg m^2): three principal moments along the
            tcp axes, or six values ``(xx, yy, zz, xy, xz, yz)`` of the tensor.
    """

    mass_kg: float
    com_tcp_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia_kg_m2: tuple[float, ...] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "mass_kg", check_range("payload.mass_kg", self.mass_kg, 0.0, 5.0, unit="kg"))
        set_(self, "com_tcp_m", check_vector("payload.com_tcp_m", self.com_tcp_m, 3, -0.5, 0.5, unit="m"))
        n = len(self.inertia_kg_m2) if isinstance(self.inertia_kg_m2, (tuple, list)) else 0
        set_(self, "inertia_kg_m2", check_vector("payload.inertia_kg_m2", self.inertia_kg_m2, 6 if n == 6 else 3,
                                                 -1.0, 1.0, unit="kg m^2"))

    @property
    def inertia_tensor(self) -> np.ndarray:
        """The inertia (3, 3) about the centre of mass, tcp axes (kg m^2)."""
        i = self.inertia_kg_m2
        if len(i) == 3:
            return np.diag(i)
        xx, yy, zz, xy, xz, yz = i
        return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])

    @classmethod
    def held(cls, obj: ObjectConfig, T_tcp_object: pin.SE3, mass_kg: float | None = None) -> Payload:
        """The object as the robot believes it (:func:`~pickplace.world.mass.mass_properties`), held with its
        frame at ``T_tcp_object``; ``mass_kg`` replaces the believed mass (e.g. after weighing it)."""
        props = mass_properties(obj)
        scale = 1.0 if mass_kg is None else mass_kg / props.mass_kg
        R = T_tcp_object.rotation
        com = T_tcp_object.act(props.com_m)
        inertia = scale * (R @ props.inertia_kg_m2 @ R.T)
        return cls(props.mass_kg * scale, (float(com[0]), float(com[1]), float(com[2])),
                   tuple(float(inertia[i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))))


# --------------------------------------------------------------------------- #
# the controller's model
# --------------------------------------------------------------------------- #


@dataclass(frozen=True, eq=False)
class ArmModel:
    """The controller's view of the arm: its own Pinocchio model (plus payload) and scratch buffers.

    Build it with :func:`arm_model` once per motion, not per step. The laws write into ``data`` and the
    scratch arrays; nothing else is kept between calls.

    Attributes:
        model: Pinocchio model (6 arm joints + 2 finger slides): arm armature = MuJoCo armature + h * damping
            (implicit damping), finger armature :data:`LOCKED_FINGER_ARMATURE`, payload added to the tcp's
            parent joint.
        data: Its data (scratch).
        tcp_frame: Frame id of the tcp.
        damping: Viscous damping of the arm joints (6,) (N m s/rad).
        torque_limits_nm: Actuator limits (6,) (N m).
        timestep_s: Simulation (= control) step (s).
        payload: The payload included, or None.
    """

    model: pin.Model
    data: pin.Data
    tcp_frame: int
    damping: np.ndarray
    torque_limits_nm: np.ndarray
    timestep_s: float
    payload: Payload | None
    _q: np.ndarray = field(repr=False)  # (nq,) scratch
    _v: np.ndarray = field(repr=False)  # (nv,) scratch
    _a: np.ndarray = field(repr=False)  # (nv,) scratch
    _zero: np.ndarray = field(repr=False)  # (nv,) zeros


def implicit_damping(m: mujoco.MjModel) -> bool:
    """Whether MuJoCo's integrator treats joint damping implicitly (``(M + h D) dv = h f``).

    True for ``implicit`` and ``implicitfast``, and for ``Euler`` unless ``eulerdamp`` is disabled; False
    for RK4.
    """
    integ = mujoco.mjtIntegrator(m.opt.integrator)
    if integ == mujoco.mjtIntegrator.mjINT_RK4:
        return False
    if integ == mujoco.mjtIntegrator.mjINT_EULER:
        return not (m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP)
    return True


def arm_model(robot: Robot, payload: Payload | None = None) -> ArmModel:
    """The controller's model of ``robot``'s arm, holding ``payload`` (if any) at the tcp.

    Args:
        robot: The models.
        payload: An object held at the tcp, added rigidly to the tcp's parent joint.

    Returns:
        A fresh :class:`ArmModel` (its own model copy and data).
    """
    model = robot.pin.copy()
    dt = float(robot.mj.opt.timestep)
    damping = np.array(model.damping[:N_ARM])
    armature = np.array(model.armature)
    if implicit_damping(robot.mj):
        armature[:N_ARM] += dt * damping
    armature[N_ARM:] = LOCKED_FINGER_ARMATURE
    model.armature = armature
    if payload is not None and payload.mass_kg > 0.0:
        frame = model.frames[robot.pin_tcp_frame]
        inertia = pin.Inertia(payload.mass_kg, np.array(payload.com_tcp_m), payload.inertia_tensor)
        model.inertias[frame.parentJoint] = model.inertias[frame.parentJoint] + frame.placement.act(inertia)
    nv = model.nv
    return ArmModel(model=model, data=model.createData(), tcp_frame=robot.pin_tcp_frame, damping=damping,
                    torque_limits_nm=np.array(robot.torque_limits_nm, dtype=float), timestep_s=dt,
                    payload=payload, _q=np.zeros(model.nq), _v=np.zeros(nv), _a=np.zeros(nv),
                    _zero=np.zeros(nv))


# --------------------------------------------------------------------------- #
# control laws
# --------------------------------------------------------------------------- #


def arm_inertia(arm: ArmModel, q: np.ndarray, finger_m: float = 0.0) -> np.ndarray:
    """The arm's joint-space inertia ``M(q)`` (6, 6) (kg m^2) in the controller's model (payload and effective
    armature included, fingers at ``finger_m``)."""
    qp = arm._q
    qp[:N_ARM] = q
    qp[N_ARM:] = finger_m
    M = pin.crba(arm.model, arm.data, qp)[:N_ARM, :N_ARM]
    return np.where(_UPPER, M, M.T)  # crba fills the upper triangle


def joint_impedance(
    arm: ArmModel,
    q: np.ndarray,
    qd: np.ndarray,
    q_ref: np.ndarray,
    qd_ref: np.ndarray,
    qdd_ref: np.ndarray,
    kp: np.ndarray,
    kd: np.ndarray,
    *,
    feedforward: bool = True,
    finger_m: float = 0.0,
    bandwidth_rad_s: float = 0.0,
    damping_ratio: float = 1.0,
    inertia: np.ndarray | None = None,
) -> np.ndarray:
    """Joint impedance with gravity compensation and optional inverse-dynamics feedforward.

    ``tau = kp (q_ref - q) + kd (qd_ref - qd) + g(q)`` and, with ``feedforward``,
    ``+ M(q) qdd_ref + C(q, qd_ref) qd_ref + D qd_ref`` (D the joints' viscous damping).

    Args:
        arm: The controller's model.
        q, qd: Measured arm positions (6,) (rad) and velocities (6,) (rad/s).
        q_ref, qd_ref, qdd_ref: Reference positions (rad), velocities (rad/s), accelerations (rad/s^2) (6,).
        kp, kd: Stiffness (6,) (N m/rad) and damping (6,) (N m s/rad).
        feedforward: Include the reference's inverse dynamics.
        finger_m: Finger slide travel (m), for the fingers' contribution to the dynamics.
        bandwidth_rad_s: > 0: ignore ``kp`` and ``kd``; the feedback is ``M(q) (w^2 (q_ref - q) + 2 zeta w
            (qd_ref - qd))`` (computed torque: every mode of the error at bandwidth ``w``, rad/s).
        damping_ratio: ``zeta`` of ``bandwidth_rad_s``.
        inertia: With ``bandwidth_rad_s``: ``M(q)`` (6, 6) if the caller has it (:func:`arm_inertia`); None:
            computed here.

    Returns:
        Unclipped arm torques (6,) (N m).
    """
    qp = arm._q
    qp[:N_ARM] = q
    qp[N_ARM:] = finger_m
    if bandwidth_rad_s > 0.0:
        w = bandwidth_rad_s
        acc = (w * w) * (q_ref - q) + (2.0 * damping_ratio * w) * (qd_ref - qd)
        tau = (arm_inertia(arm, q, finger_m) if inertia is None else inertia).dot(acc)
        if feedforward:
            arm._v[:N_ARM] = qd_ref
            arm._a[:N_ARM] = qdd_ref
            tau += pin.rnea(arm.model, arm.data, qp, arm._v, arm._a)[:N_ARM]
            tau += arm.damping * qd_ref
        else:
            tau += pin.computeGeneralizedGravity(arm.model, arm.data, qp)[:N_ARM]
        return tau
    if feedforward:
        arm._v[:N_ARM] = qd_ref
        arm._a[:N_ARM] = qdd_ref
        tau = pin.rnea(arm.model, arm.data, qp, arm._v, arm._a)[:N_ARM] + arm.damping * qd_ref
    else:
        tau = pin.computeGeneralizedGravity(arm.model, arm.data, qp)[:N_ARM].copy()
    tau += kp * (q_ref - q)
    tau += kd * (qd_ref - qd)
    return tau


class CartesianCommand(NamedTuple):
    """What :func:`cartesian_impedance` computed.

    Attributes:
        tau: Unclipped arm torques (6,) (N m).
        error: Pose error (6,) ``[p_ref - p (m); log3(R_ref R^T) (rad)]``, world axes.
        twist: Measured tcp twist (6,) ``[v (m/s); w (rad/s)]``, world axes.
        position: Measured tcp position (3,) (m).
        task_inertia: The task-space inertia ``Lambda`` (6, 6) the law used (kg, kg m, kg m^2).
    """

    tau: np.ndarray
    error: np.ndarray
    twist: np.ndarray
    position: np.ndarray
    task_inertia: np.ndarray | None = None


def cartesian_impedance(
    arm: ArmModel,
    q: np.ndarray,
    qd: np.ndarray,
    p_ref: np.ndarray,
    v_ref: np.ndarray,
    a_ref: np.ndarray,
    R_ref: np.ndarray,
    stiffness: np.ndarray,
    damping_ratio: float,
    q_posture: np.ndarray,
    posture_kp: float,
    posture_kd: float,
    *,
    finger_m: float = 0.0,
    integral: np.ndarray | None = None,
    modal_damping: bool = False,
    bandwidth_rad_s: float = 0.0,
) -> CartesianCommand:
    """Operational-space impedance of the tcp with gravity compensation and null-space posture control.

    ``F = Lambda (a_d - Jdot qd) + K e + D edot`` with ``a_d = [a_ref; 0]``, ``D_ii = 2 zeta sqrt(K_ii Lambda_ii)``;
    ``tau = J^T F + C(q, qd) qd + g(q) + D_joint qd + N^T (posture_kp (q_posture - q) - posture_kd qd)``.
    With an exact model the tcp error obeys ``Lambda e'' + D e' + K e = 0`` (the orientation reference is
    fixed).

    The UR5e's tcp Jacobian is square (6 joints, 6 task axes), so the law is evaluated through ``J^-1``:
    ``Lambda = (J M^-1 J^T)^-1 = J^-T M J^-1``, ``J^T Lambda = M J^-1``, and the null space is empty:
    ``N^T = I - J^T Lambda J M^-1 = I - M J^-1 J M^-1 = 0``, so the posture term is exactly zero and is not
    computed (``q_posture``, ``posture_kp`` and ``posture_kd`` are kept for a redundant arm). One 6 x 6 LU
    inverse and ``M`` from ``crba`` replace ``M^-1`` and the inverse of ``J M^-1 J^T``; the torques agree with
    that form to rounding (about 1e-9 relative at the worst-conditioned poses, ``tests/test_control.py``).

    Args:
        arm: The controller's model.
        q, qd: Measured arm positions (6,) (rad) and velocities (6,) (rad/s).
        p_ref, v_ref, a_ref: Reference tcp position (m), velocity (m/s), acceleration (m/s^2) (3,), world.
        R_ref: Reference tcp orientation (3, 3) in the world (held fixed: zero angular velocity).
        stiffness: Task stiffness (6,): translational (N/m), rotational (N m/rad).
        damping_ratio: Damping ratio of each task axis.
        q_posture: Posture (6,) (rad) regulated in the null space.
        posture_kp, posture_kd: Posture stiffness (N m/rad) and damping (N m s/rad).
        finger_m: Finger slide travel (m).
        integral: Integral action (6,) added to ``F``: force (N) then torque (N m), world axes; None: none.
        modal_damping: Damp each mode of ``Lambda e'' + K e = 0`` at ``damping_ratio`` (a full matrix ``D``,
            see :attr:`ControlConfig.cartesian_modal_damping`) instead of ``D_ii = 2 zeta sqrt(K_ii Lambda_ii)``.
        bandwidth_rad_s: > 0: ignore ``stiffness`` and ``modal_damping`` and give every mode of the tcp error this
            bandwidth ``w`` (rad/s): ``F = Lambda (a_d - Jdot qd + w^2 e + 2 zeta w edot)``, i.e. ``K = w^2 Lambda``,
            ``D = 2 zeta w Lambda`` (see :attr:`ControlConfig.cartesian_bandwidth_rad_s`).

    Returns:
        The torques and the measured tcp error, twist and position.

    Raises:
        numpy.linalg.LinAlgError: ``J`` is singular (the arm is at a kinematic singularity).
    """
    v6, a6 = np.zeros(6), np.zeros(6)
    v6[:3] = v_ref
    a6[:3] = a_ref
    return _cartesian_law(arm, q, qd, p_ref, v6, a6, R_ref, stiffness, damping_ratio, finger_m, integral, modal_damping,
                          bandwidth_rad_s)


def _cartesian_law(arm: ArmModel, q: np.ndarray, qd: np.ndarray, p_ref: np.ndarray, v6_ref: np.ndarray,
                   a6_ref: np.ndarray, R_ref: np.ndarray, stiffness: np.ndarray, damping_ratio: float,
                   finger_m: float, integral: np.ndarray | None, modal_damping: bool,
                   bandwidth_rad_s: float) -> CartesianCommand:
    """:func:`cartesian_impedance` with the reference twist and acceleration as 6-vectors (rotation parts 0)."""
    model, data, fid = arm.model, arm.data, arm.tcp_frame
    qp, vp = arm._q, arm._v  # vp[N_ARM:] (the fingers) stays 0: no law writes it
    qp[:N_ARM] = q
    qp[N_ARM:] = finger_m
    vp[:N_ARM] = qd
    # what the law needs and nothing more: kinematics with zero joint acceleration (so the frame's classical
    # acceleration is Jdot qd), the joint Jacobians from them, M (upper triangle) and C(q, qd) qd + g(q)
    pin.forwardKinematics(model, data, qp, vp, arm._zero)
    jdot_qd = pin.getFrameClassicalAcceleration(model, data, fid, _LWA).vector
    pin.computeJointJacobians(model, data)
    J = pin.getFrameJacobian(model, data, fid, _LWA)[:, :N_ARM]
    T = pin.updateFramePlacement(model, data, fid)
    M = pin.crba(model, data, qp)[:N_ARM, :N_ARM]
    nle = pin.nonLinearEffects(model, data, qp, vp)[:N_ARM]
    X = _inverse(J)  # J^-1; raises LinAlgError at a singularity
    MX = np.where(_UPPER, M, M.T).dot(X)  # crba fills the upper triangle: M J^-1 = J^T Lambda
    Lam = X.T.dot(MX)

    position = T.translation.copy()
    error = np.concatenate((p_ref - position, pin.log3(R_ref.dot(T.rotation.T))))
    twist = J.dot(qd)
    edot = v6_ref - twist
    acc = a6_ref - jdot_qd

    # J^T F with F = Lambda (a_d - Jdot qd) + ...: J^T Lambda = M J^-1; the null-space term N^T tau_posture is 0
    if bandwidth_rad_s > 0.0:
        w = bandwidth_rad_s
        tau = MX.dot(acc + (w * w) * error + (2.0 * damping_ratio * w) * edot)
        if integral is not None:
            tau += integral.dot(J)  # J^T integral
    else:
        if modal_damping:
            F = stiffness * error + modal_damping_matrix(Lam, stiffness, damping_ratio).dot(edot)
        else:
            F = stiffness * error + (2.0 * damping_ratio * np.sqrt(stiffness * np.abs(Lam.diagonal()))) * edot
        if integral is not None:
            F += integral
        tau = MX.dot(acc)
        tau += F.dot(J)  # J^T F
    tau += nle
    tau += arm.damping * qd
    return CartesianCommand(tau, error, twist, position, Lam)


_LWA = pin.LOCAL_WORLD_ALIGNED
#: The upper triangle of a 6 x 6 matrix (with the diagonal): where ``pin.crba`` writes ``M``.
_UPPER = np.triu(np.ones((N_ARM, N_ARM), dtype=bool))


def _inverse(a: np.ndarray) -> np.ndarray:
    """The inverse of a small square matrix by LAPACK's LU (``getrf``/``getri``), without the checks and the
    broadcasting of ``numpy.linalg.inv`` (a third of its cost at 6 x 6).

    Raises:
        numpy.linalg.LinAlgError: ``a`` is singular.
    """
    lu, piv, info = _getrf(a)
    if info != 0:
        raise np.linalg.LinAlgError("singular matrix")
    inv, info = _getri(lu, piv)
    if info != 0:
        raise np.linalg.LinAlgError("singular matrix")
    return inv


def modal_damping_matrix(inertia: np.ndarray, stiffness: np.ndarray, damping_ratio: float) -> np.ndarray:
    """Damping ``D`` (k, k) that gives every mode of ``inertia e'' + D e' + diag(stiffness) e = 0`` the damping
    ratio ``damping_ratio`` (double diagonalization, Albu-Schaeffer et al., ICRA 2003).

    With ``inertia = L L^T`` (Cholesky) and ``L^-1 K L^-T = V diag(k0) V^T``, ``Q = L V`` gives ``inertia = Q Q^T``,
    ``K = Q diag(k0) Q^T`` and ``D = Q diag(2 zeta sqrt(k0)) Q^T``; the modes' frequencies are ``sqrt(k0)`` (rad/s).

    Args:
        inertia: Symmetric positive definite inertia (k, k).
        stiffness: Diagonal stiffness (k,), > 0.
        damping_ratio: Damping ratio of every mode.

    Returns:
        The symmetric damping matrix (k, k).
    """
    L = np.linalg.cholesky(0.5 * (inertia + inertia.T))
    Linv = np.linalg.inv(L)
    k0, V = np.linalg.eigh((Linv * stiffness) @ Linv.T)
    Q = L @ V
    return (Q * (2.0 * damping_ratio * np.sqrt(np.maximum(k0, 0.0)))) @ Q.T


#: Below ``1 - 1e-9`` times its bound, a sum of squares guarantees every term is within it (rounding aside by far):
#: the loops test ``e @ e`` (one call) before looking at each joint's error, and at each torque against its limit.
_FILTER = 1.0 - 1e-9


def saturate(tau: np.ndarray, limits: np.ndarray) -> bool:
    """Clip ``tau`` (6,) (N m) in place to ``±limits`` (6,); return whether any entry was clipped."""
    if (abs(tau) > limits).any():
        tau.clip(-limits, limits, out=tau)
        return True
    return False


def _selector(idx: np.ndarray) -> slice | np.ndarray:
    """A slice for consecutive indices (a view, cheaper than fancy indexing every step), else the indices."""
    idx = np.asarray(idx)
    if idx.size and (np.diff(idx) == 1).all():
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


def min_jerk(t: np.ndarray, duration_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk (quintic) profile from 0 to 1 over ``duration_s``, at rest outside it.

    Args:
        t: Times (N,) (s).
        duration_s: Profile duration (s), > 0.

    Returns:
        Position s (N,) (1), velocity (N,) (1/s) and acceleration (N,) (1/s^2).
    """
    tau = np.clip(np.asarray(t, dtype=float) / duration_s, 0.0, 1.0)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    sd = 30.0 * tau**2 * (1.0 - tau) ** 2 / duration_s
    sdd = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / duration_s**2
    return s, sd, sdd


# --------------------------------------------------------------------------- #
# records
# --------------------------------------------------------------------------- #


@dataclass(frozen=True, eq=False)
class TrackingRecord:
    """What a joint-space loop (:func:`track`, :func:`hold`) measured.

    Errors are ``|q_ref - q|`` per joint, at every control tick (the state the controller read before the step)
    and at the end; in the ideal loop a tick is a physics step.

    Attributes:
        max_error_rad: Largest joint error over joints and time (rad).
        rms_error_rad: RMS joint error over joints and time (rad).
        final_error_rad: Largest joint error at the end (rad).
        saturation_events: Control steps in which at least one torque was clipped.
        duration_s: Simulated time (s).
        steps: Physics steps taken.
        t: Times of the control ticks (ticks + 1,) (s) from the start of the loop (ideal loop: every step).
        q: Arm positions as the controller read them at each tick (ticks + 1, 6) (rad): exact in the ideal loop
            (plus the JointNoise fault's noise, if any), encoder readings in a realistic one.
        q_ref: Reference positions at the ticks (ticks + 1, 6) (rad).
        tau: Commanded (clipped) torques, one per tick (ticks, 6) (N m); a realistic loop applies each one
            latency later.
    """

    max_error_rad: float
    rms_error_rad: float
    final_error_rad: float
    saturation_events: int
    duration_s: float
    steps: int
    t: np.ndarray = field(repr=False)
    q: np.ndarray = field(repr=False)
    q_ref: np.ndarray = field(repr=False)
    tau: np.ndarray = field(repr=False)


@dataclass(frozen=True, eq=False)
class CartesianRecord:
    """What :func:`move_linear` (and :func:`move_vertical`) measured.

    Errors are measured at every control step (the state before the step) and at the end, against the
    reference: the minimum-jerk position along the straight line and the start orientation.

    Attributes:
        reached: The tcp came within the tolerance of its target at below the settle speed after the profile.
        final_height_error_m: Tcp height minus target height at the end (m), signed.
        final_error_m: Distance of the tcp from its target at the end (m).
        lateral_drift_max_m: Largest distance of the tcp from the move's straight line (m) (for a vertical
            move: the horizontal drift from its start).
        orientation_error_max_rad: Largest rotation of the tcp away from its start orientation (rad), which is
            the orientation reference.
        position_error_max_m: Largest distance of the tcp from its reference position (m).
        position_error_rms_m: RMS distance of the tcp from its reference position (m).
        saturation_events: Control steps in which at least one torque was clipped.
        duration_s: Simulated time (s).
        steps: Physics steps taken.
        profile_duration_s: Duration of the minimum-jerk height profile (s).
        t: Times of the control ticks (ticks + 1,) (s) (ideal loop: every step).
        z: Tcp height from the positions read at each tick (ticks + 1,) (m).
        z_ref: Reference tcp height (ticks + 1,) (m).
        q: Arm positions as read at each tick (ticks + 1, 6) (rad).
        tau: Commanded (clipped) torques, one per tick (ticks, 6) (N m).
    """

    reached: bool
    final_height_error_m: float
    final_error_m: float
    lateral_drift_max_m: float
    orientation_error_max_rad: float
    position_error_max_m: float
    position_error_rms_m: float
    saturation_events: int
    duration_s: float
    steps: int
    profile_duration_s: float
    t: np.ndarray = field(repr=False)
    z: np.ndarray = field(repr=False)
    z_ref: np.ndarray = field(repr=False)
    q: np.ndarray = field(repr=False)
    tau: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class PhaseTracking:
    """Tracking errors of every control loop that ran in one phase (or in a whole episode).

    Joint-space loops (trajectories and holds) are measured in joint space, Cartesian moves at the tcp; a
    figure is NaN when no loop of its kind ran.

    Attributes:
        joint_error_max_rad: Largest ``|q_ref - q|`` over joints and steps of the joint-space loops (rad).
        joint_error_rms_rad: RMS of ``q_ref - q`` over joints and steps of those loops (rad).
        tcp_position_error_max_m: Largest distance of the tcp from its reference in the Cartesian moves (m).
        tcp_orientation_error_max_rad: Largest rotation of the tcp away from its reference orientation in the
            Cartesian moves (rad).
        joint_steps: Control steps of joint-space loops.
        cartesian_steps: Control steps of Cartesian moves.
    """

    joint_error_max_rad: float = math.nan
    joint_error_rms_rad: float = math.nan
    tcp_position_error_max_m: float = math.nan
    tcp_orientation_error_max_rad: float = math.nan
    joint_steps: int = 0
    cartesian_steps: int = 0


class TrackingTally:
    """Adds up the records of control loops into a :class:`PhaseTracking` (the one mutable piece)."""

    def __init__(self) -> None:
        self._joint_max = self._tcp_max = self._rot_max = -math.inf
        self._joint_sq = 0.0
        self._joint_n = 0
        self._joint_steps = self._cartesian_steps = 0

    def add(self, rec: TrackingRecord | CartesianRecord) -> None:
        """Count one loop's record."""
        if isinstance(rec, TrackingRecord):
            samples = len(rec.t) * N_ARM
            self._joint_max = max(self._joint_max, rec.max_error_rad)
            self._joint_sq += rec.rms_error_rad**2 * samples
            self._joint_n += samples
            self._joint_steps += rec.steps
        else:
            self._tcp_max = max(self._tcp_max, rec.position_error_max_m)
            self._rot_max = max(self._rot_max, rec.orientation_error_max_rad)
            self._cartesian_steps += rec.steps

    def result(self) -> PhaseTracking:
        """The errors so far."""
        def finite(v: float) -> float:
            return v if math.isfinite(v) else math.nan

        return PhaseTracking(
            joint_error_max_rad=finite(self._joint_max),
            joint_error_rms_rad=math.sqrt(self._joint_sq / self._joint_n) if self._joint_n else math.nan,
            tcp_position_error_max_m=finite(self._tcp_max), tcp_orientation_error_max_rad=finite(self._rot_max),
            joint_steps=self._joint_steps, cartesian_steps=self._cartesian_steps)


# --------------------------------------------------------------------------- #
# loops
# --------------------------------------------------------------------------- #


@dataclass(frozen=True, eq=False)
class JointNoise:
    """Gaussian noise on the joint positions the controller reads (a sensor fault).

    Attributes:
        std_rad: Standard deviation per joint (rad).
        rng: The seeded generator the noise is drawn from.
    """

    std_rad: float
    rng: np.random.Generator

    def sample(self) -> np.ndarray:
        """One draw (6,) (rad)."""
        return self.rng.normal(0.0, self.std_rad, N_ARM)


def _grid_reference(q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step-consistent reference from positions q (n + 2, k) sampled at t = -dt, 0, dt, ..., n dt.

    Returns:
        Positions, backward-difference velocities and second-difference accelerations, each (n + 1, k), at
        t = 0, dt, ..., n dt (the last acceleration assumes the reference is at rest after n dt).
    """
    q = np.vstack([q, q[-1:]])
    pos = q[1:-1]
    vel = (q[1:-1] - q[:-2]) / dt
    acc = (q[2:] - 2.0 * q[1:-1] + q[:-2]) / dt**2
    return pos, vel, acc


def _period(robot: Robot, loop: ControlLoop | None) -> int:
    """The control period of ``loop`` in physics steps (1 for the ideal loop)."""
    return 1 if loop is None else loop.config.steps(float(robot.mj.opt.timestep))[0]


def _whole_periods(n: int, period: int) -> int:
    """``n`` physics steps rounded up to a whole number of control periods (so the last tick is at step n)."""
    return n if period == 1 else -(-n // period) * period


class _Integral:
    """Integral action ``clip(sum ki e T, -limit, limit)`` over the control ticks (the one mutable piece of a
    loop's law; clamping the sum is the anti-windup).

    Args:
        ki: Integral gains (k,) (torque or force per unit error and second).
        limit: Bound of the integral term (k,) (its output unit).
        period_s: Control period T (s).
    """

    def __init__(self, ki: np.ndarray, limit: np.ndarray, period_s: float) -> None:
        self.gain = np.asarray(ki, dtype=float) * period_s
        self.limit = np.broadcast_to(np.asarray(limit, dtype=float), self.gain.shape).copy()
        self._lower = -self.limit
        self.current = np.zeros_like(self.gain)

    def update(self, error: np.ndarray) -> np.ndarray:
        """Add one tick's error (k,); return the integral term (k,) now in force."""
        current = self.current
        current += self.gain * error
        np.maximum(current, self._lower, out=current)  # np.clip's numbers, without its Python wrapper
        np.minimum(current, self.limit, out=current)
        return current


def servo_setpoints(arm: ArmModel, q_ref: np.ndarray, qd_ref: np.ndarray, qdd_ref: np.ndarray, kp: np.ndarray,
                    kd: np.ndarray, finger_m: float = 0.0) -> np.ndarray:
    """The setpoints (n, 6) that make position servos (:class:`~pickplace.motion.loop.ServoGains`: MuJoCo applies
    ``kp (u - q)``) apply joint impedance with the reference's inverse dynamics, the control of each step being the
    setpoint less ``kd / kp`` times the velocities then (:meth:`~pickplace.motion.loop.ControlLoop.run_servo`).

    ``u_ref = q_ref + (kd qd_ref + tau_ff) / kp``, so that the torque applied is
    ``kp (q_ref - q) + kd (qd_ref - qd) + tau_ff`` with ``tau_ff = M(q_ref) qdd_ref + C(q_ref, qd_ref) qd_ref +
    g(q_ref) + D qd_ref``: :func:`joint_impedance`'s feedforward evaluated on the reference instead of the measured
    state (they differ by ``dg/dq e``, the tracking error times gravity's gradient). A row equal to the one before
    it (a hold, the settling at a trajectory's end) reuses its feedforward.

    Args:
        arm: The controller's model.
        q_ref, qd_ref, qdd_ref: Reference positions (rad), velocities (rad/s), accelerations (rad/s^2) (n, 6).
        kp, kd: Stiffness (6,) (N m/rad), > 0, and damping (6,) (N m s/rad).
        finger_m: Finger slide travel (m).

    Returns:
        The setpoints (n, 6) (rad).
    """
    model, data = arm.model, arm.data
    n = len(q_ref)
    if n == 0:
        return np.empty((0, N_ARM))
    vel = np.zeros((n, model.nv))
    vel[:, :N_ARM] = qd_ref
    acc = np.zeros((n, model.nv))
    acc[:, :N_ARM] = qdd_ref
    pos = np.empty((n, model.nq))
    pos[:, :N_ARM] = q_ref
    pos[:, N_ARM:] = finger_m
    rnea = pin.rnea
    # a row equal to the one before it (a hold, the settling at a trajectory's end) has its feedforward: computed once
    new = np.ones(n, dtype=bool)
    new[1:] = ((q_ref[1:] != q_ref[:-1]) | (qd_ref[1:] != qd_ref[:-1]) | (qdd_ref[1:] != qdd_ref[:-1])).any(axis=1)
    rows = np.flatnonzero(new)
    ff = np.array([rnea(model, data, pos[i], vel[i], acc[i]) for i in rows])[:, :N_ARM]
    if len(rows) < n:
        ff = ff[np.cumsum(new) - 1]
    ff += arm.damping * qd_ref
    ff += kd * qd_ref
    return q_ref + ff / kp


def _run_joint(
    robot: Robot,
    d: mujoco.MjData,
    phase: str,
    q_ref: np.ndarray,
    qd_ref: np.ndarray,
    qdd_ref: np.ndarray,
    config: ControlConfig,
    payload: Payload | None,
    hook: Hook | Measured | None,
    noise: JointNoise | None = None,
    loop: ControlLoop | None = None,
    yielding: np.ndarray | None = None,
) -> TrackingRecord:
    """Run joint impedance along a step-grid reference (n + 1, 6) for n physics steps, through ``loop``.

    ``yielding`` (6, 6): at every tick the reference from then on moves by ``yielding @ (q - q_ref)`` (the arm
    yields in that subspace: :func:`hold`'s ``comply_along``); it is edited in place."""
    loop = loop if loop is not None else IDEAL
    h = robot.handles
    arm = arm_model(robot, payload)
    n = len(q_ref) - 1
    dt = arm.timestep_s
    kp, kd, ff = config.joint_kp, config.joint_kd, config.feedforward
    qpos = d.qpos
    finger = int(h.finger_qpos[0])
    q_log = np.empty((n + 1, N_ARM))
    k_log = np.empty(n + 1, dtype=np.int64)  # the physics step of each tick
    taus: list[np.ndarray] = []
    bandwidth, zeta_j = config.joint_bandwidth_rad_s, config.joint_damping_ratio
    if not config.joint_integral:
        integral = None
    elif bandwidth > 0.0:  # Ki = zero * w^2 M(q): the integral of zero * w^2 M(q) e, tick by tick
        integral = _Integral(np.full(N_ARM, config.joint_integral_zero_rad_s * bandwidth**2),
                             config.joint_integral_limit_nm, loop.period_s(robot))
    else:
        integral = _Integral(config.joint_ki, config.joint_integral_limit_nm, loop.period_s(robot))
    j = -1  # the last row logged
    saturated = 0
    limits = arm.torque_limits_nm

    def record(last: int, steps: int, tau: np.ndarray | None = None) -> TrackingRecord:
        idx = k_log[: last + 1]
        ref = q_ref[idx]
        err = np.abs(ref - q_log[: last + 1])
        if tau is None:
            tau = np.array(taus[:last]) if last > 0 else np.empty((0, N_ARM))
        return TrackingRecord(
            max_error_rad=float(err.max()), rms_error_rad=float(np.sqrt(np.mean(err**2))),
            final_error_rad=float(err[-1].max()), saturation_events=saturated, duration_s=steps * dt,
            steps=steps, t=idx * dt, q=q_log[: last + 1].copy(), q_ref=ref, tau=tau)

    max_err = config.max_joint_error_rad
    err_filter = max_err * max_err * _FILTER  # e @ e below it: every |e_i| <= max_err (no need to look closer)
    inv_limits = 1.0 / limits
    fast = bandwidth == 0.0 and ff and integral is None

    def check(k: int, e: np.ndarray, tau: np.ndarray | None = None) -> None:
        """Raise if the joint error ``e`` (6,) exceeds the limit (or is not finite)."""
        err = float(abs(e).max())
        if not err <= max_err:  # also catches NaN
            raise ControlError(phase, f"joint error {err:.4g} rad exceeds {max_err:g} rad at t = {k * dt:.3f} s",
                               record(j, k, tau))

    if fast and noise is None and yielding is None and loop.ideal:
        # position servos (see the module's docstring): MuJoCo's actuators apply the position feedback at every physics
        # step; the controller sends each step's setpoint, with the reference's feedforward, less the damping's share
        setpoints = servo_setpoints(arm, q_ref[:n], qd_ref[:n], qdd_ref[:n], kp, kd, float(qpos[finger]))

        def logged(rows: np.ndarray, q_last: np.ndarray) -> np.ndarray:
            """Log the ticks the tape covers and the state ``q_last`` after them; return the torques applied."""
            nonlocal j
            k = j = len(rows)
            q_log[:k] = rows[:, :N_ARM]
            q_log[k] = q_last
            k_log[: k + 1] = np.arange(k + 1)
            return rows[:, _TAU].copy()

        def on_error(k: int, e: np.ndarray, rows: np.ndarray, q_k: np.ndarray) -> None:
            check(k, e, logged(rows, q_k))

        rows = loop.run_servo(robot, d, setpoints, kp, kd, q_ref, max_err, on_error, hook)
        tau = logged(rows, qpos[h.arm_qpos])
        saturated = int(np.count_nonzero((np.abs(tau) >= limits * (1.0 - 1e-12)).any(axis=1)))
        rec = record(j, len(rows), tau)
        log.debug("%s: %d steps on the joint servos, max error %.3g rad, rms %.3g rad, final %.3g rad, %d saturated "
                  "steps", phase, rec.steps, rec.max_error_rad, rec.rms_error_rad, rec.final_error_rad,
                  rec.saturation_events)
        return rec

    computed_torque = bandwidth > 0.0 and ff
    if fast or computed_torque:  # the reference's terms of the law, for every tick at once (elementwise: the same)
        model, data, qp = arm.model, arm.data, arm._q
        vel = np.zeros((n + 1, model.nv))
        vel[:, :N_ARM] = qd_ref
        accel = np.zeros((n + 1, model.nv))
        accel[:, :N_ARM] = qdd_ref
        damp_ref = arm.damping * qd_ref
        rnea = pin.rnea
        w2, w_damp = bandwidth * bandwidth, 2.0 * zeta_j * bandwidth

    def law(k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray | None:
        nonlocal j, saturated
        i = k if k < n else n
        j += 1
        q_log[j] = q
        k_log[j] = i
        if yielding is not None:
            q_ref[i:] += yielding.dot(q - q_ref[i])
        e = q_ref[i] - q
        if not e.dot(e) <= err_filter:  # (ndarray.dot: a quarter of the cost of @ on these small arrays)
            check(k, e)
        if k >= n:
            return None
        if fast:  # joint_impedance(feedforward=True), operation for operation
            qp[:N_ARM] = q
            qp[N_ARM:] = qpos[finger]
            tau = rnea(model, data, qp, vel[i], accel[i])[:N_ARM] + damp_ref[i]
            tau += kp * e
            tau += kd * (qd_ref[i] - qd)
        elif computed_torque:  # joint_impedance(bandwidth_rad_s=w, feedforward=True), operation for operation
            inertia = arm_inertia(arm, q, qpos[finger])  # (it sets the configuration rnea reads below)
            acc = w2 * e
            acc += w_damp * (qd_ref[i] - qd)
            tau = inertia.dot(acc)
            tau += rnea(model, data, qp, vel[i], accel[i])[:N_ARM]
            tau += damp_ref[i]
            if integral is not None:
                tau += integral.update(inertia.dot(e))
        elif bandwidth > 0.0:
            finger_m = float(qpos[finger])
            inertia = arm_inertia(arm, q, finger_m)
            tau = joint_impedance(arm, q, qd, q_ref[i], qd_ref[i], qdd_ref[i], kp, kd, feedforward=ff,
                                  finger_m=finger_m, bandwidth_rad_s=bandwidth, damping_ratio=zeta_j, inertia=inertia)
            if integral is not None:
                tau += integral.update(inertia.dot(e))
        else:
            tau = joint_impedance(arm, q, qd, q_ref[i], qd_ref[i], qdd_ref[i], kp, kd, feedforward=ff,
                                  finger_m=qpos[finger])
            if integral is not None:
                tau += integral.update(e)
        scaled = tau * inv_limits
        if not scaled.dot(scaled) <= _FILTER and saturate(tau, limits):
            saturated += 1
        taus.append(tau)
        return tau

    stats = loop.run(robot, d, law, hook, noise)
    rec = record(j, stats.steps)
    log.debug("%s: %d steps, max error %.3g rad, rms %.3g rad, final %.3g rad, %d saturated steps", phase,
              rec.steps, rec.max_error_rad, rec.rms_error_rad, rec.final_error_rad, rec.saturation_events)
    return rec


def track(
    robot: Robot,
    data: mujoco.MjData,
    trajectory: Trajectory,
    config: ControlConfig,
    *,
    payload: Payload | None = None,
    hook: Hook | Measured | None = None,
    noise: JointNoise | None = None,
    loop: ControlLoop | None = None,
    settle_s: float = 0.1,
    start_s: float = 0.0,
    stop_s: float | None = None,
) -> TrackingRecord:
    """Track a joint trajectory with joint impedance, then hold its final point for ``settle_s``.

    ``start_s`` and ``stop_s`` track only a part of it (times on the physics step grid, s): the arm is on the
    trajectory at ``start_s`` (a previous call tracked it up to there) and the loop ends at ``stop_s`` without
    holding anything (the next call goes on from there), so that a motion that does not stop can be run phase
    by phase. The reference keeps the same step grid from the trajectory's start, whatever the part.

    Args:
        robot: The models.
        data: MuJoCo data, advanced in place. The arm should start near ``trajectory.sample(0)``.
        trajectory: The reference (rad, rad/s, rad/s^2), from :func:`pickplace.motion.timing.retime`.
        config: Gains.
        payload: An object held at the tcp (compensated in gravity and feedforward).
        hook: Called with ``data`` after every simulation step; may raise to abort (a
            :class:`~pickplace.motion.loop.Measured` hook also gets the tape of the arm's state).
        noise: Noise added to the joint positions the controller reads (a sensor fault), or None.
        loop: The control loop (rate, latency, encoders: :class:`~pickplace.motion.loop.ControlLoop`); None:
            the ideal loop (exact state, every physics step).
        settle_s: Time to hold the final point after the trajectory ends (s).

    Returns:
        The :class:`TrackingRecord`.

    Raises:
        ConfigError: ``settle_s`` is negative or not finite, or ``start_s`` and ``stop_s`` are not a part of the
            trajectory (``stop_s`` after ``start_s``).
        ControlError: the joint error exceeds ``config.max_joint_error_rad`` (or the state is not finite).
    """
    settle_s = check_range("track.settle_s", settle_s, 0.0, 60.0, unit="s")
    dt = float(robot.mj.opt.timestep)
    period = _period(robot, loop)
    k0 = round(check_range("track.start_s", start_s, 0.0, trajectory.duration_s, unit="s") / dt)
    end = math.ceil(trajectory.duration_s / dt - 1e-9)
    if stop_s is None:
        n = _whole_periods(end - k0 + round(settle_s / dt), period)
    else:
        stop_s = check_range("track.stop_s", stop_s, start_s, trajectory.duration_s + dt, unit="s")
        n = _whole_periods(max(1, math.ceil(stop_s / dt - 1e-9) - k0), period)
    qs, _, _ = trajectory.sample_many((k0 + np.arange(-1, n + 1)) * dt)
    q_ref, qd_ref, qdd_ref = _grid_reference(qs, dt)
    return _run_joint(robot, data, "track", q_ref, qd_ref, qdd_ref, config, payload, hook, noise, loop)


def hold(
    robot: Robot,
    data: mujoco.MjData,
    q: np.ndarray,
    duration_s: float,
    config: ControlConfig,
    *,
    payload: Payload | None = None,
    hook: Hook | Measured | None = None,
    noise: JointNoise | None = None,
    loop: ControlLoop | None = None,
    comply_along: np.ndarray | None = None,
) -> TrackingRecord:
    """Regulate the arm to a fixed configuration for ``duration_s`` (e.g. while the gripper closes).

    Args:
        robot: The models.
        data: MuJoCo data, advanced in place.
        q: Configuration to hold (6,) (rad).
        duration_s: How long (s).
        config: Gains.
        payload: An object held at the tcp.
        hook: Called with ``data`` after every simulation step; may raise to abort (a
            :class:`~pickplace.motion.loop.Measured` hook also gets the tape of the arm's state).
        noise: Noise added to the joint positions the controller reads (a sensor fault), or None.
        loop: The control loop (rate, latency, encoders: :class:`~pickplace.motion.loop.ControlLoop`); None:
            the ideal loop (exact state, every physics step).
        comply_along: A world direction (3,): the arm yields along it. At every control tick the reference moves
            by the joint motion of the tcp's displacement along it (measured from the joints read, to first
            order: ``J^-1 [a a^T 0; 0 0] J``, ``J`` the tcp's Jacobian at ``q``), so the arm is stiff in the
            other five directions (three turns, two translations) and only damped along it. None: stiff in all.

    Returns:
        The :class:`TrackingRecord` (errors relative to ``q``, or to the reference as it yielded).

    Raises:
        ConfigError: ``q`` is not 6 finite numbers, ``duration_s`` is negative, or ``comply_along`` is not a
            non-zero 3-vector.
        ControlError: the joint error exceeds ``config.max_joint_error_rad``.
    """
    target = np.array(check_vector("hold.q", q, N_ARM, unit="rad"))
    duration_s = check_range("hold.duration_s", duration_s, 0.0, 3600.0, unit="s")
    n = _whole_periods(round(duration_s / float(robot.mj.opt.timestep)), _period(robot, loop))
    q_ref = np.repeat(target[None], n + 1, axis=0)
    zeros = np.zeros_like(q_ref)
    yielding = None if comply_along is None else _yielding(robot, target, comply_along)
    return _run_joint(robot, data, "hold", q_ref, zeros, zeros, config, payload, hook, noise, loop, yielding)


def _yielding(robot: Robot, q: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The joint-space projector (6, 6) onto the tcp's translation along ``direction`` (3,) at ``q`` (6,)."""
    a = np.array(check_vector("hold.comply_along", direction, 3))
    norm = float(np.linalg.norm(a))
    if not norm > 1e-9:
        raise ConfigError("hold.comply_along", direction, "must be a non-zero direction (3,)")
    a /= norm
    pdata = robot.pin.createData()
    J = frame_jacobian(robot.pin, pdata, robot.pin_q(q), robot.pin_tcp_frame)
    select = np.zeros((6, 6))
    select[:3, :3] = np.outer(a, a)
    return np.linalg.solve(J, select @ J)


def stop(
    robot: Robot,
    data: mujoco.MjData,
    decel_rad_s2: np.ndarray | tuple[float, ...],
    config: ControlConfig,
    *,
    payload: Payload | None = None,
    hook: Hook | Measured | None = None,
    noise: JointNoise | None = None,
    loop: ControlLoop | None = None,
    settle_s: float = 0.1,
) -> TrackingRecord:
    """Bring a moving arm to rest along its direction of motion, then hold it (a category-2 stop).

    The reference starts at the measured state and decelerates every joint uniformly, all reaching rest at the
    same time ``T = max_j |qd_j| / decel_j``: ``q(t) = q0 + qd0 (t - t^2 / (2 T))``, so it ends at
    ``q0 + qd0 T / 2``. Holding the current position instead would ask a fast arm to reverse at once: the
    impedance overshoots by ``qd / omega`` and, at full speed, past ``config.max_joint_error_rad``.

    Args:
        robot: The models.
        data: MuJoCo data, advanced in place.
        decel_rad_s2: Deceleration limits per joint (6,) (rad/s^2), e.g. the trajectory's acceleration limits.
        config: Gains.
        payload: An object held at the tcp.
        hook: Called with ``data`` after every simulation step; may raise to abort (a
            :class:`~pickplace.motion.loop.Measured` hook also gets the tape of the arm's state).
        noise: Noise added to the joint positions the controller reads (a sensor fault), or None.
        loop: The control loop (rate, latency, encoders: :class:`~pickplace.motion.loop.ControlLoop`); None:
            the ideal loop (exact state, every physics step).
        settle_s: Time to hold the rest position after the deceleration (s).

    Returns:
        The :class:`TrackingRecord` of the deceleration and the hold.

    Raises:
        ConfigError: a deceleration limit is not a positive finite number or ``settle_s`` is negative.
        ControlError: the joint error exceeds ``config.max_joint_error_rad``.
    """
    decel = np.array(check_vector("stop.decel_rad_s2", decel_rad_s2, N_ARM, 0.0, 1e4, lo_open=True,
                                  unit="rad/s^2"))
    settle_s = check_range("stop.settle_s", settle_s, 0.0, 60.0, unit="s")
    h = robot.handles
    dt = float(robot.mj.opt.timestep)
    q0 = data.qpos[h.arm_qpos].copy()
    v0 = data.qvel[h.arm_dof].copy()
    T = float(np.max(np.abs(v0) / decel))
    n = _whole_periods(math.ceil(T / dt - 1e-9) + round(settle_s / dt), _period(robot, loop))
    t = np.clip(np.arange(-1, n + 1) * dt, None, T)
    s = t - t**2 / (2.0 * T) if T > 0.0 else np.zeros_like(t)  # distance travelled per unit initial velocity
    q_ref, qd_ref, qdd_ref = _grid_reference(q0 + np.outer(s, v0), dt)
    return _run_joint(robot, data, "stop", q_ref, qd_ref, qdd_ref, config, payload, hook, noise, loop)


def move_vertical(
    robot: Robot,
    data: mujoco.MjData,
    target_z_m: float,
    config: ControlConfig,
    *,
    payload: Payload | None = None,
    hook: Hook | Measured | None = None,
    noise: JointNoise | None = None,
    loop: ControlLoop | None = None,
    duration_s: float | None = None,
    raise_on_timeout: bool = True,
    joint_limits: tuple[np.ndarray, np.ndarray] | None = None,
) -> CartesianRecord:
    """Move the tcp vertically to ``target_z_m`` (m), holding x, y and the orientation: :func:`move_linear` to
    the point straight above or below the tcp's position now.

    Raises:
        ConfigError: ``target_z_m`` or ``duration_s`` is invalid.
        ControlError: timeout (if ``raise_on_timeout``), or a tcp error beyond ``config.max_tcp_error_m``.
    """
    target_z_m = check_range("move_vertical.target_z_m", target_z_m, -2.0, 2.0, unit="m")
    start = _tcp_now(robot, data)
    return move_linear(robot, data, np.array([start[0], start[1], target_z_m]), config, payload=payload, hook=hook,
                       noise=noise, loop=loop, duration_s=duration_s, raise_on_timeout=raise_on_timeout,
                       joint_limits=joint_limits)


def _tcp_now(robot: Robot, data: mujoco.MjData) -> np.ndarray:
    """The tcp position (3,) (m) of ``data``'s arm configuration, by Pinocchio's kinematics."""
    h = robot.handles
    q = robot.pin_q(data.qpos[h.arm_qpos], float(data.qpos[h.finger_qpos[0]]))
    pdata = robot.pin.createData()
    pin.framesForwardKinematics(robot.pin, pdata, q)
    return pdata.oMf[robot.pin_tcp_frame].translation.copy()


#: Integration steps of the joint path along a straight tcp move (:func:`line_duration_s`).
_LINE_STEPS = 16


def line_duration_s(arm: ArmModel, q0: np.ndarray, finger_m: float, delta_m: np.ndarray,
                    velocity_limits: np.ndarray, acceleration_limits: np.ndarray) -> float:
    """The shortest minimum-jerk profile (s) of a straight tcp move by ``delta_m`` (3,) (m) from ``q0`` (6,),
    orientation held, whose joint speeds and accelerations stay within the limits (6,) (rad/s, rad/s^2).

    Along the line ``p(sigma) = p0 + sigma delta`` the joints move by ``q' = J^-1 [delta; 0]`` and
    ``q'' = -J^-1 Jdot(q, q') q'`` per unit of ``sigma`` (integrated from ``q0`` by the midpoint rule); with
    ``sigma(tau)`` the minimum-jerk profile over ``T``, ``qd = q' sigma_tau / T`` and ``qdd = (q'' sigma_tau^2 +
    q' sigma_tautau) / T^2``, so the shortest ``T`` is their largest ratio to the limits (speed) or its square root
    (acceleration). A move near a singularity asks the joints for much more than the tcp's limits suggest: the
    min-jerk profile of the tcp's limits alone asked the UR5e's elbow for 11.7 rad/s^2 (limit 8) on the default
    scene's 15 cm descent.
    """
    model, data, fid = arm.model, arm.data, arm.tcp_frame
    qp, vp = arm._q.copy(), np.zeros(model.nv)
    qp[N_ARM:] = finger_m
    twist = np.zeros(6)
    twist[:3] = delta_m

    def rates(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        qp[:N_ARM] = q
        pin.computeJointJacobians(model, data, qp)
        J = pin.getFrameJacobian(model, data, fid, _LWA)[:, :N_ARM]
        dq = np.linalg.solve(J, twist)
        vp[:N_ARM] = dq
        pin.forwardKinematics(model, data, qp, vp, arm._zero)
        jdot = pin.getFrameClassicalAcceleration(model, data, fid, _LWA).vector
        return dq, -np.linalg.solve(J, jdot)

    sig = np.linspace(0.0, 1.0, _LINE_STEPS + 1)
    d1 = np.empty((sig.size, N_ARM))
    d2 = np.empty((sig.size, N_ARM))
    q = np.asarray(q0, dtype=float).copy()
    h = 1.0 / _LINE_STEPS
    for k in range(sig.size):
        d1[k], d2[k] = rates(q)
        if k < _LINE_STEPS:
            q = q + h * rates(q + 0.5 * h * d1[k])[0]
    tau = np.linspace(0.0, 1.0, 201)
    s_tau, sd_tau, sdd_tau = min_jerk(tau, 1.0)
    q1 = np.stack([np.interp(s_tau, sig, d1[:, j]) for j in range(N_ARM)], axis=1)
    q2 = np.stack([np.interp(s_tau, sig, d2[:, j]) for j in range(N_ARM)], axis=1)
    speed = np.abs(q1 * sd_tau[:, None]) / np.asarray(velocity_limits, dtype=float)
    accel = np.abs(q2 * sd_tau[:, None] ** 2 + q1 * sdd_tau[:, None]) / np.asarray(acceleration_limits, dtype=float)
    return max(float(speed.max()), math.sqrt(float(accel.max())))


def move_linear(
    robot: Robot,
    data: mujoco.MjData,
    target_m: np.ndarray,
    config: ControlConfig,
    *,
    payload: Payload | None = None,
    hook: Hook | Measured | None = None,
    noise: JointNoise | None = None,
    loop: ControlLoop | None = None,
    duration_s: float | None = None,
    raise_on_timeout: bool = True,
    joint_limits: tuple[np.ndarray, np.ndarray] | None = None,
) -> CartesianRecord:
    """Move the tcp along a straight line to ``target_m`` with Cartesian impedance, holding its orientation.

    The position follows a minimum-jerk profile along the segment from the current position (duration from
    :meth:`ControlConfig.vertical_duration_s` for its length unless given, and with ``joint_limits`` at least
    :func:`line_duration_s`: long enough for the joints too); the orientation is regulated to
    the one at the start (the UR5e has no null space left to regulate a posture in). The move ends once the
    profile is over and the tcp is within ``config.height_tolerance_m`` of the target, moving slower than
    ``config.settle_speed_m_s`` (in a realistic loop: its mean speed over :data:`SETTLE_SPEED_WINDOW_S`); it times
    out ``config.settle_timeout_s`` after the profile's end.

    Args:
        robot: The models.
        data: MuJoCo data, advanced in place.
        target_m: Target tcp position (3,) in the world (m).
        config: Gains and motion parameters.
        payload: An object held at the tcp.
        hook: Called with ``data`` after every simulation step; may raise to abort (a
            :class:`~pickplace.motion.loop.Measured` hook also gets the tape of the arm's state).
        noise: Noise added to the joint positions the controller reads (a sensor fault), or None.
        loop: The control loop (rate, latency, encoders: :class:`~pickplace.motion.loop.ControlLoop`); None:
            the ideal loop (exact state, every physics step).
        duration_s: Profile duration (s), overriding the config's speed and acceleration limits.
        raise_on_timeout: Raise :class:`ControlError` on timeout; otherwise return with ``reached=False``.
        joint_limits: Joint speed (6,) (rad/s) and acceleration (6,) (rad/s^2) limits the profile must keep
            (:func:`line_duration_s`), or None (the tcp's limits only). Ignored with ``duration_s``.

    Returns:
        The :class:`CartesianRecord`.

    Raises:
        ConfigError: ``target_m`` or ``duration_s`` is invalid.
        ControlError: timeout (if ``raise_on_timeout``), or a tcp error beyond ``config.max_tcp_error_m``.
    """
    target = np.array(check_vector("move_linear.target_m", target_m, 3, -2.0, 2.0, unit="m"))
    loop = loop if loop is not None else IDEAL
    h = robot.handles
    arm = arm_model(robot, payload)
    dt = arm.timestep_s
    period = loop.config.steps(dt)[0]
    qpos = data.qpos  # aliasing data's memory
    finger = int(h.finger_qpos[0])

    q0 = qpos[_selector(h.arm_qpos)].copy()
    qp0 = robot.pin_q(q0, float(qpos[finger]))
    pin.framesForwardKinematics(arm.model, arm.data, qp0)
    T0 = pin.SE3(arm.data.oMf[arm.tcp_frame])
    R_ref, p0 = T0.rotation.copy(), T0.translation.copy()
    delta = target - p0
    length = float(np.linalg.norm(delta))
    direction = delta / length if length > 0.0 else np.array([0.0, 0.0, 1.0])
    if duration_s is not None:
        T = check_range("move_linear.duration_s", duration_s, dt, 60.0, unit="s")
    else:
        T = max(config.vertical_duration_s(length), dt)
        if joint_limits is not None and length > 0.0:
            T = max(T, line_duration_s(arm, q0, float(qpos[finger]), delta, *joint_limits))
    n_profile = math.ceil(T / dt - 1e-9)
    n_max = _whole_periods(n_profile + round(config.settle_timeout_s / dt), period)
    s, _, _ = min_jerk(np.arange(-1, n_max + 1) * dt, T)
    p_grid = p0 + np.outer(s, delta)
    p_refs, v_refs, a_refs = _grid_reference(p_grid, dt)
    v6_refs, a6_refs = np.zeros((n_max + 1, 6)), np.zeros((n_max + 1, 6))  # the twist's and acceleration's
    v6_refs[:, :3] = v_refs
    a6_refs[:, :3] = a_refs

    stiffness, zeta = config.cartesian_stiffness, config.cartesian_damping_ratio
    limits = arm.torque_limits_nm
    pos_err_log = np.empty(n_max + 1)
    q_log = np.empty((n_max + 1, N_ARM))
    p_log = np.empty((n_max + 1, 3))  # the tcp position read at each tick (m)
    e_log = np.empty((n_max + 1, 6))  # the pose error at each tick
    k_log = np.empty(n_max + 1, dtype=np.int64)  # the physics step of each tick
    taus: list[np.ndarray] = []
    bandwidth = config.cartesian_bandwidth_rad_s
    if not config.cartesian_integral:
        integral = None
    elif bandwidth > 0.0:  # ki = zero * w^2 Lambda(q): the integral of w^2 zero Lambda e, tick by tick
        integral = _Integral(np.full(6, config.cartesian_integral_zero_rad_s * bandwidth**2),
                             config.cartesian_integral_limit, loop.period_s(robot))
    else:
        integral = _Integral(config.cartesian_ki, config.cartesian_integral_limit, loop.period_s(robot))
    inv_limits = 1.0 / limits
    modal = config.cartesian_modal_damping
    saturated = 0
    reached = False
    j = -1  # the last row logged
    p = p0.copy()

    def record(last: int, steps: int, p_now: np.ndarray) -> CartesianRecord:
        pos = pos_err_log[: last + 1]
        idx = k_log[: last + 1]
        off = p_log[: last + 1] - p0
        side = off - np.outer(off @ direction, direction)  # off the line
        r = e_log[: last + 1, 3:]
        rot = np.sqrt(r[:, 0] * r[:, 0] + r[:, 1] * r[:, 1] + r[:, 2] * r[:, 2])
        return CartesianRecord(
            reached=reached, final_height_error_m=float(p_now[2] - target[2]),
            final_error_m=float(np.linalg.norm(p_now - target)),
            lateral_drift_max_m=float(np.sqrt((side * side).sum(axis=1)).max()) if last >= 0 else 0.0,
            orientation_error_max_rad=float(rot.max()) if last >= 0 else 0.0, position_error_max_m=float(pos.max()),
            position_error_rms_m=float(np.sqrt(np.mean(pos**2))), saturation_events=saturated,
            duration_s=steps * dt, steps=steps, profile_duration_s=float(T), t=idx * dt,
            z=p_log[: last + 1, 2].copy(), z_ref=p_refs[idx, 2], q=q_log[: last + 1].copy(),
            tau=np.array(taus[:last]) if last > 0 else np.empty((0, N_ARM)))

    tol_p, tol_v, tol_e = config.height_tolerance_m, config.settle_speed_m_s, config.max_tcp_error_m
    # a realistic loop judges the settle speed from the tcp's displacement over SETTLE_SPEED_WINDOW_S (ticks)
    period_s = loop.period_s(robot)
    window = 0 if loop.ideal else max(1, round(SETTLE_SPEED_WINDOW_S / period_s))

    def law(k: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray | None:
        nonlocal j, p, reached, saturated
        i = k if k < n_max else n_max
        try:
            cmd = _cartesian_law(arm, q, qd, p_refs[i], v6_refs[i], a6_refs[i], R_ref, stiffness, zeta,
                                 qpos[finger], None if integral is None else integral.current, modal, bandwidth)
        except np.linalg.LinAlgError as exc:  # J is singular: the arm is at a kinematic singularity
            raise ControlError("move_linear", f"singular tcp Jacobian at q = {np.round(q, 4).tolist()} rad",
                               record(j, k - 1, p) if j >= 0 else None) from exc
        j += 1
        p = cmd.position
        error = cmd.error
        q_log[j] = q
        p_log[j] = p
        e_log[j] = error
        k_log[j] = i
        ex, ey, ez = error[:3].tolist()
        pos_err = math.sqrt(ex * ex + ey * ey + ez * ez)
        pos_err_log[j] = pos_err
        if not pos_err <= tol_e:  # also catches NaN
            raise ControlError("move_linear", f"tcp error {pos_err * 1e3:.3g} mm exceeds {tol_e * 1e3:.3g} mm "
                                              f"at t = {k * dt:.3f} s", record(j, k, p))
        if k >= n_profile and float(np.linalg.norm(p - target)) <= tol_p:
            if window:  # the mean speed over the window: the filtered velocity is the encoders' noise here
                speed = float(np.linalg.norm(p - p_log[j - window])) / (window * period_s) if j >= window \
                    else math.inf
            else:
                vx, vy, vz = cmd.twist[:3].tolist()
                speed = math.sqrt(vx * vx + vy * vy + vz * vz)
            if speed <= tol_v:
                reached = True
                return None
        if k >= n_max:
            return None
        tau = cmd.tau
        if integral is not None:
            integral.update(error if bandwidth == 0.0 else cmd.task_inertia.dot(error))
        scaled = tau * inv_limits
        if not scaled.dot(scaled) <= _FILTER and saturate(tau, limits):
            saturated += 1
        taus.append(tau)
        return tau

    k = loop.run(robot, data, law, hook, noise).steps
    rec = record(j, k, p)
    log.debug("move_linear to %s m: reached %s after %.3f s (profile %.3f s), error %.3g mm, drift %.3g mm, "
              "orientation %.3g rad, %d saturated steps", np.round(target, 4).tolist(), rec.reached, rec.duration_s,
              T, rec.final_error_m * 1e3, rec.lateral_drift_max_m * 1e3, rec.orientation_error_max_rad,
              rec.saturation_events)
    if not reached and raise_on_timeout:
        raise ControlError("move_linear", f"tcp not settled at {np.round(target, 4).tolist()} m within "
                                          f"{config.settle_timeout_s:g} s after the {T:.3f} s profile: "
                                          f"{rec.final_error_m * 1e3:.3g} mm from it (tolerance "
                                          f"{config.height_tolerance_m * 1e3:.3g} mm)", rec)
    return rec


__all__ = [
    "SETTLE_SPEED_WINDOW_S",
    "ArmModel",
    "CartesianCommand",
    "CartesianRecord",
    "ControlConfig",
    "Hook",
    "Payload",
    "PhaseTracking",
    "TrackingRecord",
    "TrackingTally",
    "arm_inertia",
    "arm_model",
    "cartesian_impedance",
    "hold",
    "implicit_damping",
    "joint_impedance",
    "line_duration_s",
    "min_jerk",
    "modal_damping_matrix",
    "move_linear",
    "move_vertical",
    "saturate",
    "stop",
    "track",
]
