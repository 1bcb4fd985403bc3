"""The parallel-jaw gripper: geometry, commands, contact state and grip force.

How well it holds is measured by the hold test, :mod:`pickplace.grasping.hold`.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np

from pickplace.robot.model import Robot
from pickplace.world.contact import Contact

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- #
# geometry and commands
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class GripperGeometry:
    """Gripper dimensions measured on the compiled model (m, in the tcp frame).

    Attributes:
        open_inner_face_y_m: Distance from the tcp to each pad's inner face, fully open.
        closed_inner_face_y_m: The same, fully closed (the actuator's closed target).
        open_width_m: Gap between the pads, fully open.
        pad_half_height_m: Half the pads' height along the tcp z axis.
        travel_m: Finger slide travel (0 = open).
        tcp_offset_m: Distance from ``tool0`` to the tcp along the flange axis.
    """

    open_inner_face_y_m: float
    closed_inner_face_y_m: float
    open_width_m: float
    pad_half_height_m: float
    travel_m: float
    tcp_offset_m: float

    @classmethod
    def measure(cls, robot: Robot) -> GripperGeometry:
        """Measure the pads' faces by forward kinematics at both ends of the finger travel."""
        m, h = robot.mj, robot.handles
        d = mujoco.MjData(m)
        pad = int(h.pad_geoms[0])
        travel = float(m.jnt_range[m.actuator_trnid[h.gripper_actuator, 0], 1])

        def inner_face(q: float) -> float:
            d.qpos[h.finger_qpos] = q
            mujoco.mj_kinematics(m, d)
            R = d.site_xmat[h.tcp_site].reshape(3, 3)
            local = R.T @ (d.geom_xpos[pad] - d.site_xpos[h.tcp_site])
            return float(abs(local[1]) - m.geom_size[pad, 1])

        mujoco.mj_kinematics(m, d)
        tcp_offset = float(np.linalg.norm(d.site_xpos[h.tcp_site] - d.xpos[h.tool0_body]))
        open_face = inner_face(0.0)
        return cls(
            open_inner_face_y_m=open_face,
            closed_inner_face_y_m=inner_face(travel),
            open_width_m=2 * open_face,
            pad_half_height_m=float(m.geom_size[pad, 2]),
            travel_m=travel,
            tcp_offset_m=tcp_offset,
        )

    def contact_travel_m(self, cube_size_m: float) -> float:
        """Finger travel (m) at which the pads touch a cube of this size."""
        return self.open_inner_face_y_m - cube_size_m / 2


def command(robot: Robot, d: mujoco.MjData, closed: bool) -> None:
    """Command the gripper fully open or fully closed (the closed target lies far past any object)."""
    lo, hi = robot.mj.actuator_ctrlrange[robot.handles.gripper_actuator]
    d.ctrl[robot.handles.gripper_actuator] = hi if closed else lo


def finger_travel(robot: Robot, d: mujoco.MjData) -> float:
    """Current finger travel (m), 0 = open."""
    return float(d.qpos[robot.handles.finger_qpos[0]])


def is_settled(robot: Robot, d: mujoco.MjData, speed_tol_m_s: float = 1e-3) -> bool:
    """True when both fingers move slower than ``speed_tol_m_s``."""
    return bool(np.all(np.abs(d.qvel[robot.handles.finger_dof]) < speed_tol_m_s))


def _pad_cube_contacts(robot: Robot, d: mujoco.MjData) -> Iterator[tuple[int, int, bool]]:
    """``(contact index, pad 0 left / 1 right, whether the cube is geom2)`` of every pad-cube contact."""
    h = robot.handles
    left, right = int(h.pad_geoms[0]), int(h.pad_geoms[1])
    for i in range(d.ncon):
        c = d.contact[i]
        g1, g2 = int(c.geom1), int(c.geom2)
        if h.cube_geom == g2 and g1 in (left, right):
            yield i, int(g1 == right), True
        elif h.cube_geom == g1 and g2 in (left, right):
            yield i, int(g2 == right), False


def pad_load(robot: Robot, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """The pads' normal forces and their total force on the cube, as the simulation has them now.

    Returns:
        ``(normal, force_on_cube)``: the normal force of the cube on the left and right pad (2,) (N), and
        the total force the pads exert on the cube (3,) in the world (N).
    """
    normal, total, f = np.zeros(2), np.zeros(3), np.zeros(6)
    for i, pad, cube_is_geom2 in _pad_cube_contacts(robot, d):
        mujoco.mj_contactForce(robot.mj, d, i, f)
        normal[pad] += f[0]
        force_on_geom2 = d.contact[i].frame.reshape(3, 3).T @ f[:3]  # frame rows: normal, tangent 1, tangent 2
        total += force_on_geom2 if cube_is_geom2 else -force_on_geom2
    return normal, total


def pad_forces(robot: Robot, d: mujoco.MjData) -> np.ndarray:
    """Normal force (N) of the cube on the left and right pad, (2,)."""
    f, out = np.zeros(6), np.zeros(2)
    for i, pad, _ in _pad_cube_contacts(robot, d):
        mujoco.mj_contactForce(robot.mj, d, i, f)
        out[pad] += f[0]
    return out


def pad_contacts(robot: Robot, d: mujoco.MjData) -> list[Contact]:
    """The pad-cube contacts as the simulation has them now, for the force-closure test: one
    :class:`~pickplace.grasping.closure.Contact` per MuJoCo contact point (world frame, normal pointing into the cube,
    the contact's own friction coefficients)."""
    contacts: list[Contact] = []
    for i, _, cube_is_geom2 in _pad_cube_contacts(robot, d):
        c = d.contact[i]
        normal = c.frame[:3] if cube_is_geom2 else -c.frame[:3]  # the frame's normal points from geom1 to geom2
        contacts.append(Contact(c.pos.copy(), normal.copy(), float(c.friction[0]), float(c.friction[2])))
    return contacts


def in_contact(robot: Robot, d: mujoco.MjData, min_force_n: float = 0.5) -> bool:
    """True when both pads press on the cube with at least ``min_force_n``."""
    return bool(np.all(pad_forces(robot, d) >= min_force_n))
