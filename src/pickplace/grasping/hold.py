"""The hold test: how well the gripper holds the object, measured before any arm control is involved.

The arm is driven *kinematically* along a Cartesian tcp path (its joints are set to the IK reference every
step, with the inverse-dynamics torque applied so the bodies feel the right accelerations), the gripper closes
on the object with its real actuator, lifts it 0.15 m and carries it 0.40 m sideways with a peak acceleration
above 3 m/s^2, and the object's slip relative to the pads and the grip normal force are measured.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from pickplace.grasping.configurations import solve_grasp_configurations
from pickplace.robot.gripper import command, finger_travel, in_contact, pad_forces
from pickplace.robot.ik import IKConfig, dls_iterate, solve_ik
from pickplace.robot.kinematics import rotation_distance
from pickplace.robot.model import Robot, build
from pickplace.world.config import SceneConfig, check_range

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- #
# hold test
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class HoldTestConfig:
    """The hold test's motion (SI units).

    Attributes:
        descend_time_s: Kinematic descent from pregrasp to grasp (s).
        close_time_s: Time given to the gripper to close and settle (s).
        lift_m: Lift height (m).
        lift_time_s: Duration of the (minimum-jerk) lift (s).
        carry_m: Sideways carry distance, towards the goal (m).
        carry_time_s: Duration of the (minimum-jerk) carry (s); 0.8 s over 0.40 m peaks at 3.6 m/s^2.
        dwell_s: Hold still at the end (s).
        slip_tolerance_m: Slip beyond which the object counts as not held (m).
    """

    descend_time_s: float = 0.5
    close_time_s: float = 0.5
    lift_m: float = 0.15
    lift_time_s: float = 0.5
    carry_m: float = 0.40
    carry_time_s: float = 0.8
    dwell_s: float = 0.3
    slip_tolerance_m: float = 0.001

    def __post_init__(self) -> None:
        for name in ("descend_time_s", "close_time_s", "lift_time_s", "carry_time_s"):
            check_range(f"hold.{name}", getattr(self, name), 0.05, 10.0, unit="s")
        check_range("hold.dwell_s", self.dwell_s, 0.0, 10.0, unit="s")
        check_range("hold.lift_m", self.lift_m, 0.0, 0.5, unit="m")
        check_range("hold.carry_m", self.carry_m, 0.0, 1.0, unit="m")
        check_range("hold.slip_tolerance_m", self.slip_tolerance_m, 0.0, 0.05, lo_open=True, unit="m")


@dataclass(frozen=True)
class HoldResult:
    """What the hold test measured.

    Attributes:
        mass_kg: Mass of the object held (kg).
        held: True when the slip stayed below tolerance and both pads still squeeze the object at the end.
        slip_m: Largest displacement of the object relative to the tcp after closing (m).
        slip_rad: Largest rotation of the object relative to the tcp after closing (rad).
        grip_force_n: Mean normal force per pad during the lift and carry (N).
        min_grip_force_n: Smallest per-pad normal force during the lift and carry (N).
        peak_acceleration_m_s2: Peak tcp acceleration of the motion (m/s^2).
        load_n: The largest force the grip must transmit, m (g + a_peak) (N).
    """

    mass_kg: float
    held: bool
    slip_m: float
    slip_rad: float
    grip_force_n: float
    min_grip_force_n: float
    peak_acceleration_m_s2: float
    load_n: float


def _min_jerk(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s**2)


def _tcp_path(robot: Robot, cfg: HoldTestConfig, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Reference tcp positions (N, 3), orientation (3, 3), phase labels (N,) and the close-end index."""
    scene = robot.scene
    tg = solve_grasp_configurations(robot).targets  # the grasp an episode would take
    top, bottom = tg.pregrasp.translation, tg.grasp.translation
    direction = np.append(scene.goal_pos_m[:2] - scene.start_pos_m[:2], 0.0)
    direction /= max(np.linalg.norm(direction), 1e-9)
    lifted = bottom + np.array([0.0, 0.0, cfg.lift_m])
    segments = [  # (start, end, duration, label)
        (top, bottom, cfg.descend_time_s, 0),
        (bottom, bottom, cfg.close_time_s, 1),
        (bottom, lifted, cfg.lift_time_s, 2),
        (lifted, lifted + cfg.carry_m * direction, cfg.carry_time_s, 3),
        (lifted + cfg.carry_m * direction, lifted + cfg.carry_m * direction, cfg.dwell_s, 4),
    ]
    pos, labels = [], []
    for a, b, duration, label in segments:
        n = round(duration / dt)
        s = _min_jerk(np.arange(1, n + 1) / n)
        pos.append(a + s[:, None] * (b - a))
        labels.append(np.full(n, label))
    close_end = round((cfg.descend_time_s + cfg.close_time_s) / dt)
    return np.vstack(pos), tg.grasp.rotation, np.concatenate(labels), close_end


def _joint_reference(robot: Robot, positions: np.ndarray, R: np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
    """Joint positions, velocities and accelerations (N, 6) that follow the tcp path (warm-started DLS)."""
    first = solve_ik(robot, pin.SE3(R, positions[0]), robot.home_q, name="hold-test start")
    tight = IKConfig(step=1.0, tolerance=1e-10, max_iterations=50, restarts=0)
    data = robot.pin.createData()
    q = first.q
    qs = np.empty((len(positions), 6))
    for k, p in enumerate(positions):
        q, _, _ = dls_iterate(robot, data, pin.SE3(R, p), q, tight)
        qs[k] = q
    # Differences consistent with MuJoCo's semi-implicit Euler step (v' = v + a dt, q' = q + v' dt): the
    # step from (q_k, v_k) with a_k lands exactly on (q_k+1, v_k+1), so resetting the arm is a no-op and
    # contacts see the same pad velocity as the positions imply.
    qd = np.diff(qs, axis=0, prepend=qs[:1]) / dt
    qdd = np.diff(qd, axis=0, append=qd[-1:]) / dt
    return qs, qd, qdd


def hold_test(
    scene: SceneConfig | None = None,
    config: HoldTestConfig | None = None,
    reference: tuple[np.ndarray, ...] | None = None,
) -> HoldResult:
    """Close on the object, lift it and carry it sideways with the arm driven kinematically; measure the hold.

    Args:
        scene: The scene (its object mass, size and friction are what is tested).
        config: The motion.
        reference: A joint reference from a previous call on the same geometry (reused to save time).

    Returns:
        The measured :class:`HoldResult`.
    """
    scene = scene or SceneConfig()
    cfg = config or HoldTestConfig()
    robot = build(scene)
    m, h = robot.mj, robot.handles
    dt = m.opt.timestep
    positions, R, labels, close_end = _tcp_path(robot, cfg, dt)
    qs, qd, qdd = reference if reference is not None else _joint_reference(robot, positions, R, dt)

    d = robot.make_data()
    d.qpos[h.arm_qpos] = qs[0]
    mujoco.mj_forward(m, d)
    pdata = robot.pin.createData()
    damping = m.dof_damping[h.arm_dof]
    rel0: pin.SE3 | None = None
    slip_m = slip_rad = 0.0
    forces: list[np.ndarray] = []
    tcp = np.empty((len(qs), 3))
    for k in range(len(qs)):
        command(robot, d, closed=labels[k] >= 1)
        # kinematic arm: state set to the reference, inverse dynamics applied so the step accelerates right
        d.qpos[h.arm_qpos], d.qvel[h.arm_dof] = qs[k], qd[k]
        qp = robot.pin_q(qs[k], finger_travel(robot, d))
        vp = np.zeros(robot.pin.nv)
        vp[:6] = qd[k]
        ap = np.zeros(robot.pin.nv)
        ap[:6] = qdd[k]
        tau = pin.rnea(robot.pin, pdata, qp, vp, ap)
        # ... plus the previous step's contact reaction on the arm, as a perfect position controller would
        # apply: otherwise the load pulls the arm within each step, the reset undoes it, and the object
        # appears to creep out of the grip by an artefact of the playback, not of the contacts.
        d.qfrc_applied[h.arm_dof] = tau[:6] + damping * qd[k] - d.qfrc_constraint[h.arm_dof]
        mujoco.mj_step(m, d)
        T_world_tcp = pin.SE3(d.site_xmat[h.tcp_site].reshape(3, 3).copy(), d.site_xpos[h.tcp_site].copy())
        tcp[k] = T_world_tcp.translation
        if k + 1 < close_end:
            continue
        T_world_object = pin.SE3(d.xmat[h.object_body].reshape(3, 3).copy(), d.xpos[h.object_body].copy())
        rel = T_world_tcp.actInv(T_world_object)
        if rel0 is None:
            rel0 = rel
            continue
        slip_m = max(slip_m, float(np.linalg.norm(rel.translation - rel0.translation)))
        slip_rad = max(slip_rad, rotation_distance(rel.rotation, rel0.rotation))
        if labels[k] in (2, 3):
            forces.append(pad_forces(robot, d))

    f = np.array(forces)
    acc = np.linalg.norm(np.diff(tcp, 2, axis=0), axis=1) / dt**2
    peak = float(acc[close_end:].max())
    held = slip_m < cfg.slip_tolerance_m and in_contact(robot, d)
    result = HoldResult(
        mass_kg=scene.object.mass_kg,
        held=bool(held),
        slip_m=slip_m,
        slip_rad=slip_rad,
        grip_force_n=float(f.mean()),
        min_grip_force_n=float(f.min()),
        peak_acceleration_m_s2=peak,
        load_n=scene.object.mass_kg * (9.81 + peak),
    )
    log.info("hold test: %s", result)
    return result


@dataclass(frozen=True)
class HoldMargin:
    """The hold test at the nominal mass and at increasing multiples of it.

    Attributes:
        nominal: The result at the scene's object mass.
        results: Every mass tried, in order.
        safety_factor: Heaviest object held / nominal mass (a lower bound: the multiples tried are discrete).
        friction: The friction coefficient of the test (the object's).
        coulomb_limit_kg: The heaviest object Coulomb friction can carry through the motion,
            ``2 mu F_pad / (g + a_peak)`` with the nominal run's pad force and peak acceleration (kg).
    """

    nominal: HoldResult
    results: tuple[HoldResult, ...]
    safety_factor: float
    friction: float
    coulomb_limit_kg: float


def hold_margin(
    scene: SceneConfig | None = None,
    config: HoldTestConfig | None = None,
    multiples: tuple[float, ...] = (1.0, 3.0, 5.0, 8.0, 12.0, 16.0, 20.0, 25.0, 30.0),
) -> HoldMargin:
    """Run the hold test at ``multiples`` of the object's mass until one fails; return the safety factor.

    Masses above the UR5e's 5 kg payload are not tried.
    """
    scene = scene or SceneConfig()
    cfg = config or HoldTestConfig()
    robot = build(scene)
    positions, R, _, _ = _tcp_path(robot, cfg, robot.mj.opt.timestep)
    reference = _joint_reference(robot, positions, R, robot.mj.opt.timestep)
    results: list[HoldResult] = []
    best = 0.0
    for k in multiples:
        mass = scene.object.mass_kg * k
        if mass > 5.0:
            break
        r = hold_test(scene.with_object(mass_kg=mass), cfg, reference)
        results.append(r)
        if not r.held:
            break
        best = k
    nominal = results[0]
    limit = 2.0 * scene.object.friction * nominal.grip_force_n / (9.81 + nominal.peak_acceleration_m_s2)
    return HoldMargin(nominal=nominal, results=tuple(results), safety_factor=best, friction=scene.object.friction,
                      coulomb_limit_kg=limit)
