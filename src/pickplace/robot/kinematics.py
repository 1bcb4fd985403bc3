"""Forward kinematics, Jacobians and pose errors, on the Pinocchio model.

Conventions: poses are :class:`pinocchio.SE3` named ``T_world_<frame>``; Jacobians are 6 x 6 for the arm
joints (the finger slides are not moved by IK), rows ``[linear; angular]`` in the world-aligned frame at
the frame's origin (Pinocchio's ``LOCAL_WORLD_ALIGNED``), so ``[v; w] = J @ qd``.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

ARM_DOF = 6


def frame_pose(model: pin.Model, data: pin.Data, q: np.ndarray, frame_id: int) -> pin.SE3:
    """Pose of a frame in the world.

    Args:
        model: Pinocchio model (arm + gripper).
        data: Its data (overwritten).
        q: Full configuration (model.nq,): 6 arm joints (rad) then 2 finger slides (m).
        frame_id: Pinocchio frame id.

    Returns:
        ``T_world_frame`` (a copy).
    """
    pin.framesForwardKinematics(model, data, q)
    return pin.SE3(data.oMf[frame_id])


def frame_jacobian(model: pin.Model, data: pin.Data, q: np.ndarray, frame_id: int) -> np.ndarray:
    """World-aligned 6 x 6 Jacobian of a frame with respect to the arm joints.

    Returns:
        (6, 6) array; rows ``[v (m/s); w (rad/s)]`` per rad/s of each arm joint.
    """
    J = pin.computeFrameJacobian(model, data, q, frame_id, pin.LOCAL_WORLD_ALIGNED)
    return J[:, :ARM_DOF].copy()


def pose_error(T_current: pin.SE3, T_target: pin.SE3) -> np.ndarray:
    """6D error that drives ``T_current`` to ``T_target``, world-aligned.

    Returns:
        (6,) array ``[p_target - p_current (m); log3(R_target R_current^T) (rad)]``: the translation error
        and the rotation vector (SO(3) log) of the remaining rotation, both in world axes.
    """
    e = np.empty(6)
    e[:3] = T_target.translation - T_current.translation
    e[3:] = pin.log3(T_target.rotation @ T_current.rotation.T)
    return e


def rotation_distance(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Geodesic angle between two rotations (rad), in [0, pi]."""
    return float(np.linalg.norm(pin.log3(R_a.T @ R_b)))


def yaw_of(R: np.ndarray) -> float:
    """Rotation about world z of a frame's x axis (rad), in (-pi, pi]."""
    return float(np.arctan2(R[1, 0], R[0, 0]))


def rot_z(yaw: float) -> np.ndarray:
    """Rotation matrix (3, 3) of ``yaw`` rad about z."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ik_branch(J: np.ndarray, q: np.ndarray) -> tuple[int, int, int]:
    """Which of the UR arm's eight IK branches the configuration ``q`` (6,) (rad) is on, from its 6 x 6 Jacobian
    ``J`` there (:func:`frame_jacobian`, at any frame rigid with the flange): ``(shoulder, elbow, wrist)``, each
    +1 or -1.

    The Jacobian's determinant of this kinematic structure is ``a2 a3 sin(q3) sin(q5) s(q)``, ``s`` the wrist's
    reach from the shoulder's axis in the arm's plane; each factor changes sign exactly at one of the three
    singularities (shoulder, elbow stretched, wrist 1 and 3 aligned) that a path must cross to change branch.
    """
    elbow = 1 if math.sin(float(q[2])) >= 0.0 else -1
    wrist = 1 if math.sin(float(q[4])) >= 0.0 else -1
    shoulder = (1 if np.linalg.det(J[:, :6]) >= 0.0 else -1) * elbow * wrist
    return shoulder, elbow, wrist


def wrap_to_pi(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi
