"""The per-step monitor's contact rules: only the robot's own unexpected contacts are faults."""

from __future__ import annotations

import mujoco

from pickplace.robot.model import Robot
from pickplace.task.monitor import StepMonitor


def _ids(robot: Robot) -> dict[str, int]:
    m, h = robot.mj, robot.handles
    table = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "table")
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    arm = next(g for g in range(m.ngeom) if m.geom_bodyid[g] in h.robot_bodies)
    table_geom = next(g for g in range(m.ngeom) if m.geom_bodyid[g] == table)
    return {"object": int(h.object_geoms[0]), "table": int(table_geom), "floor": floor,
            "pad": int(h.pad_geoms[0]), "arm": arm}


def test_a_dropped_object_may_touch_the_table_and_the_floor(robot: Robot) -> None:
    mon = StepMonitor(robot, None, slip_tolerance_m=0.005)
    g = _ids(robot)
    mon.allow_object_table = False
    mon.holding = False
    for other in ("table", "floor"):
        assert mon.allowed(mon.cls[g["object"]], mon.cls[g[other]]), other


def test_a_held_object_touching_the_floor_or_table_is_a_fault(robot: Robot) -> None:
    mon = StepMonitor(robot, None, slip_tolerance_m=0.005)
    g = _ids(robot)
    mon.allow_object_table = False
    mon.holding = True
    for other in ("table", "floor"):
        assert not mon.allowed(mon.cls[g["object"]], mon.cls[g[other]]), other
    mon.allow_object_table = True  # setting it down
    assert mon.allowed(mon.cls[g["object"]], mon.cls[g["table"]])


def test_the_robot_touching_the_world_is_always_a_fault(robot: Robot) -> None:
    mon = StepMonitor(robot, None, slip_tolerance_m=0.005)
    g = _ids(robot)
    for holding in (False, True):
        mon.holding = holding
        for other in ("table", "floor"):
            assert not mon.allowed(mon.cls[g["arm"]], mon.cls[g[other]])
    mon.allow_hand_object = False
    assert not mon.allowed(mon.cls[g["pad"]], mon.cls[g["object"]])
    mon.allow_hand_object = True
    assert mon.allowed(mon.cls[g["pad"]], mon.cls[g["object"]])


def test_a_falling_object_may_land_on_the_arm_only_while_it_falls(robot: Robot) -> None:
    """During a recovery the arm stands still while the dropped object comes to rest: landing on the arm is the
    object's doing. Otherwise the arm touching the object is a fault."""
    mon = StepMonitor(robot, None, slip_tolerance_m=0.005)
    g = _ids(robot)
    assert not mon.allowed(mon.cls[g["arm"]], mon.cls[g["object"]])
    mon.object_falling = True
    assert mon.allowed(mon.cls[g["arm"]], mon.cls[g["object"]])
    assert mon.allowed(mon.cls[g["pad"]], mon.cls[g["object"]])
    assert not mon.allowed(mon.cls[g["arm"]], mon.cls[g["table"]])  # the arm itself still touches nothing
