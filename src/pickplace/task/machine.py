"""The pick-and-place state machine of one episode: an arm and one pick-and-place skill on it.

The phases, their checks and recoveries live in :mod:`pickplace.task.skill`; executing motions under the
per-step monitor in :mod:`pickplace.task.arm`; the phase names, settings and record in
:mod:`pickplace.task.phases`; the recovery table in :mod:`pickplace.task.recovery`. This module puts one arm
and one skill together for the scene's object, as :func:`~pickplace.task.episode.run_episode` runs it.
"""

from __future__ import annotations

import mujoco
import numpy as np

from pickplace.motion.control import ControlConfig
from pickplace.motion.loop import ControlLoop
from pickplace.motion.planning import PlannerConfig
from pickplace.motion.timing import TimingConfig
from pickplace.robot.ik import IKConfig
from pickplace.robot.model import Robot
from pickplace.task.arm import Arm
from pickplace.task.faults import FaultConfig
from pickplace.task.observe import Observer
from pickplace.task.phases import (
    CollisionPredicted,
    MachineConfig,
    MachineOutcome,
    Phase,
    PhaseFailed,
    SegmentPlan,
)
from pickplace.task.skill import PickPlaceSkill
from pickplace.task.telemetry import TelemetryRecorder


class PickPlaceMachine:
    """Runs one pick and place of the scene's object in a MuJoCo simulation, phase by phase.

    Args:
        robot: The models (the scene gives the object and the goal).
        data: The simulation state, advanced in place.
        machine: Tolerances and timeouts.
        control_config: Controller gains and straight-move profile.
        planner: RRT* settings (its seed is the episode's).
        timing: TOPP-RA limits.
        ik: IK settings.
        recorder: Optional telemetry (plots, video).
        faults: Faults to inject (the model faults must already be applied, see
            :func:`pickplace.task.faults.apply_model_faults`).
        rng: Seeded generator for the sensor noise fault.
        observer: What the robot knows about the object; default: the simulator's truth (ideal profile).
        loop: The control loop (rate, latency, encoders); default: the ideal loop.

    Attributes:
        arm: The arm (its monitor keeps the clock: ``arm.monitor.t``).
        skill: The pick and place.
    """

    def __init__(
        self,
        robot: Robot,
        data: mujoco.MjData,
        machine: MachineConfig,
        control_config: ControlConfig,
        planner: PlannerConfig,
        timing: TimingConfig,
        ik: IKConfig,
        recorder: TelemetryRecorder | None = None,
        faults: FaultConfig | None = None,
        rng: np.random.Generator | None = None,
        observer: Observer | None = None,
        loop: ControlLoop | None = None,
    ) -> None:
        self.arm = Arm(robot, data, machine, control_config, planner, timing, recorder, faults, rng,
                       observer=observer, loop=loop)
        self.skill = PickPlaceSkill(self.arm, ik)
        self.monitor = self.arm.monitor

    @property
    def out(self) -> MachineOutcome:
        """Everything measured so far."""
        return self.arm.out

    def run(self) -> MachineOutcome:
        """Run the phases to DONE or FAILED; never raises for a failure of the task itself."""
        return self.skill.run()


__all__ = [
    "CollisionPredicted",
    "MachineConfig",
    "MachineOutcome",
    "Phase",
    "PhaseFailed",
    "PickPlaceMachine",
    "SegmentPlan",
]
