"""The per-step monitor's contact rules: only the robot's own unexpected contacts are faults."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from pickplace.robot.model import Robot
from pickplace.task.faults import FaultConfig, FaultInjector
from pickplace.task.monitor import StepMonitor, UnexpectedContact


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


def _resting_on_the_table(robot: Robot) -> mujoco.MjData:
    """The default scene with the object settled on the table (object-table contacts, nothing else)."""
    d = robot.make_data()
    for _ in range(50):
        mujoco.mj_step(robot.mj, d)
    return d


def test_a_flag_change_makes_the_monitor_look_at_unchanged_contacts_again(robot: Robot) -> None:
    """The monitor looks at the contacts only when they or its flags change: the same object-table contacts,
    allowed while the object rests, are a fault as soon as it is held (and the same contacts again are not)."""
    d = _resting_on_the_table(robot)
    assert d.ncon > 0
    mon = StepMonitor(robot, None, slip_tolerance_m=0.005)
    mon.allow_object_table = False
    mon(d)  # not held: allowed
    mon(d)  # the same contacts: not looked at again
    mon.holding = True  # looked at again, and now a fault
    with pytest.raises(UnexpectedContact, match="unexpected contact"):
        mon(d)
    mon.holding = False
    mon(d)


def test_a_fault_injector_without_a_push_is_not_called(robot: Robot) -> None:
    """Without a push configured, the injector would only write a zero force every step: the monitor skips it."""
    quiet = FaultInjector(robot, FaultConfig())
    pushing = FaultInjector(robot, FaultConfig(transport_push_n=(0.0, 0.0, -40.0), transport_push_s=0.05))
    assert not quiet.pushes and pushing.pushes
    assert not StepMonitor(robot, None, 0.005, quiet)._inject
    assert StepMonitor(robot, None, 0.005, pushing)._inject
    mon = StepMonitor(robot, None, 0.005)
    mon.injector = pushing  # as task_episode wraps it: set later
    assert mon._inject
    d = robot.make_data()
    d.xfrc_applied[robot.handles.object_body, :3] = 1.0
    StepMonitor(robot, None, 0.005, quiet)(d)
    assert np.array_equal(d.xfrc_applied[robot.handles.object_body, :3], np.ones(3))  # not touched
