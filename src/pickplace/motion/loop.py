"""The control loop as the robot runs it: encoders, control rate, latency and zero-order hold.

Every loop of :mod:`pickplace.motion.control` runs through :meth:`ControlLoop.run`. Physics steps at the
model's timestep ``h`` (1 ms); the controller runs every ``control_period_s`` (a whole number of steps) and
at each *tick*:

1. reads the arm through its encoders (:meth:`ControlLoop` docstring: quantization to the encoder's
   resolution, then Gaussian noise, then the :class:`~pickplace.motion.control.JointNoise` sensor fault if
   any) and estimates the velocity by a first-order low-pass filter of the differences of those readings;
2. evaluates the control law on that state and the reference at the tick;
3. sends the (clipped) torque, which reaches the motors ``latency_s`` later and is held until the next one
   arrives (zero-order hold).

The monitor ``hook(d)`` is called after every physics step, ticks or not. A :class:`Measured` hook also gets the
loop's *tape*: MuJoCo's sensors of the arm (positions, velocities, the torques applied, the tcp; one contiguous block
of ``sensordata``, :data:`~pickplace.robot.model.ARM_STATE_FIELDS`) copied once per step, handed over in blocks, so
that what is measured on every step (the joint limits, the tcp's line) is computed per block in numpy.

:meth:`ControlLoop.run_servo` runs the ideal loop's joint trajectories on the arm's actuators made position servos
(:class:`ServoGains`): the feedforward is computed for the whole reference ahead (:func:`pickplace.motion.control.
servo_setpoints`), MuJoCo applies the position feedback at every step and Python writes one control per step, the
setpoint less the damping's share.

With :class:`LoopConfig`'s defaults (every field 0, :attr:`LoopConfig.ideal`) the loop is today's ideal one:
the law reads MuJoCo's exact ``qpos``/``qvel`` every physics step and its torque is applied in that same step.
The ideal path performs exactly the operations the loops performed before this module existed, in the same
order, so ideal episodes are unchanged bit for bit by it.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import mujoco
import numpy as np

from pickplace.errors import ConfigError
from pickplace.robot.model import ARM_STATE_WIDTH, Robot
from pickplace.world.config import check_range

if TYPE_CHECKING:
    from pickplace.motion.control import JointNoise

log = logging.getLogger(__name__)

N_ARM = 6

#: UR e-Series real-time control rate: the controller's real-time loop, and the RTDE interface that streams
#: the joint state and takes commands, run at 500 Hz (Universal Robots, "Real-Time Data Exchange (RTDE)
#: Guide", e-Series: up to 500 Hz; CB-Series 125 Hz), i.e. a 2 ms control period.
UR_E_SERIES_CONTROL_PERIOD_S = 0.002
#: Encoder resolution of the realistic profile (rad per count): a 18-bit absolute encoder, 2 pi / 2^18 =
#: 2.4e-5 rad. UR does not publish its joints' encoder resolution; what it publishes is the UR5e's pose
#: repeatability, +/- 0.03 mm (ISO 9283; UR5e technical specification). One count at the full 0.85 m reach
#: moves the tcp 0.02 mm, just inside that figure, so the encoders cannot be coarser than about this.
UR5E_ENCODER_RESOLUTION_RAD = 2.0 * math.pi / 2**18
#: Encoder noise of the realistic profile (rad, standard deviation): half a count, 1.2e-5 rad (0.01 mm at
#: the full reach), again bounded by the published +/- 0.03 mm repeatability (not a published noise figure).
UR5E_ENCODER_NOISE_STD_RAD = 0.5 * UR5E_ENCODER_RESOLUTION_RAD
#: Cut-off of the velocity filter of the realistic profile (Hz). A design choice of this controller, not a
#: datasheet value: well below the 250 Hz Nyquist frequency of the 500 Hz loop, so that one encoder count per
#: period (0.012 rad/s of raw difference) is attenuated, and high enough that its lag (1 / (2 pi f_c) = 1.6 ms)
#: stays below the loop's own latency.
VELOCITY_CUTOFF_HZ = 100.0

#: A control law evaluated at a tick: ``law(k, q, qd)`` with ``k`` the physics step of the tick since the
#: loop started (the reference index), ``q``/``qd`` the sensed arm state (6,); returns the unclipped arm
#: torques (6,) (N m), which the loop may clip in place, or None to end the loop before stepping.
Law = Callable[[int, np.ndarray, np.ndarray], "np.ndarray | None"]
Hook = Callable[[mujoco.MjData], None]


@dataclass(frozen=True)
class LoopConfig:
    """How the controller senses the arm and how often it acts (all fields 0: the ideal loop).

    Attributes:
        control_period_s: Control period (s), a whole number of physics steps; 0 runs the law every step.
        latency_s: Delay from reading the encoders to the torque reaching the motors (s), a whole number of
            physics steps; 0 applies it in the step it was computed.
        encoder_resolution_rad: Encoder quantum (rad per count); 0 reads the exact position.
        encoder_noise_std_rad: Standard deviation of Gaussian noise added to each reading (rad); needs a
            seeded generator (:class:`ControlLoop`).
        velocity_cutoff_hz: Cut-off (Hz) of the first-order low-pass filter applied to the differences of the
            readings; 0 reads MuJoCo's exact joint velocities.
    """

    control_period_s: float = 0.0
    latency_s: float = 0.0
    encoder_resolution_rad: float = 0.0
    encoder_noise_std_rad: float = 0.0
    velocity_cutoff_hz: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "control_period_s", check_range("loop.control_period_s", self.control_period_s, 0.0, 0.1,
                                                   unit="s"))
        set_(self, "latency_s", check_range("loop.latency_s", self.latency_s, 0.0, 0.1, unit="s"))
        set_(self, "encoder_resolution_rad", check_range("loop.encoder_resolution_rad", self.encoder_resolution_rad,
                                                         0.0, 0.01, unit="rad"))
        set_(self, "encoder_noise_std_rad", check_range("loop.encoder_noise_std_rad", self.encoder_noise_std_rad,
                                                        0.0, 0.01, unit="rad"))
        set_(self, "velocity_cutoff_hz", check_range("loop.velocity_cutoff_hz", self.velocity_cutoff_hz,
                                                     0.0, 1e4, unit="Hz"))
        if self.velocity_cutoff_hz > 0.0 and self.control_period_s > 0.0 \
                and self.velocity_cutoff_hz >= 0.5 / self.control_period_s:
            raise ConfigError("loop.velocity_cutoff_hz", self.velocity_cutoff_hz,
                              f"must be < {0.5 / self.control_period_s:g} Hz, the Nyquist frequency of the "
                              f"{self.control_period_s:g} s control period")

    @classmethod
    def realistic(cls) -> LoopConfig:
        """The UR5e as it runs: 500 Hz, one period of latency, 18-bit encoders with half a count of noise,
        velocity filtered at 100 Hz (sources: :data:`UR_E_SERIES_CONTROL_PERIOD_S`,
        :data:`UR5E_ENCODER_RESOLUTION_RAD`, :data:`UR5E_ENCODER_NOISE_STD_RAD`, :data:`VELOCITY_CUTOFF_HZ`)."""
        return cls(control_period_s=UR_E_SERIES_CONTROL_PERIOD_S, latency_s=UR_E_SERIES_CONTROL_PERIOD_S,
                   encoder_resolution_rad=UR5E_ENCODER_RESOLUTION_RAD,
                   encoder_noise_std_rad=UR5E_ENCODER_NOISE_STD_RAD, velocity_cutoff_hz=VELOCITY_CUTOFF_HZ)

    @property
    def ideal(self) -> bool:
        """Every field off: exact state every physics step, torque applied at once."""
        return (self.control_period_s == 0.0 and self.latency_s == 0.0 and self.encoder_resolution_rad == 0.0
                and self.encoder_noise_std_rad == 0.0 and self.velocity_cutoff_hz == 0.0)

    def steps(self, timestep_s: float) -> tuple[int, int]:
        """``(period, latency)`` in physics steps of ``timestep_s`` (s).

        Raises:
            ConfigError: the period or the latency is not a whole number of steps.
        """
        def whole(name: str, value: float, at_least: int) -> int:
            n = round(value / timestep_s)
            if abs(n * timestep_s - value) > 1e-9 * max(1.0, value):
                raise ConfigError(f"loop.{name}", value, f"must be a whole number of {timestep_s:g} s physics steps")
            return max(at_least, n)

        return whole("control_period_s", self.control_period_s, 1), whole("latency_s", self.latency_s, 0)


class LoopRun(NamedTuple):
    """What :meth:`ControlLoop.run` did.

    Attributes:
        steps: Physics steps taken.
        ticks: Control ticks (law evaluations that returned a torque).
    """

    steps: int
    ticks: int


@dataclass(frozen=True, eq=False)
class ControlLoop:
    """A control loop's configuration and its noise source: pass one to every motion of
    :mod:`pickplace.motion.control` (``loop=``).

    Each motion starts a fresh loop state: the first tick is at the motion's first step; the velocity filter
    starts warm (its estimate at the arm's velocity, its last reading the first one); the torque already in
    ``data.ctrl`` (the previous motion's last one) is held until the first new torque arrives.

    Readings: ``q = round(q_true / resolution) * resolution + noise`` (+ the sensor fault's noise), i.e.
    encoder counts plus noise; velocity ``v += a (dq / T - v)``, ``a = 1 - exp(-2 pi f_c T)``, T the control
    period.

    Attributes:
        config: The loop.
        rng: Seeded generator of the encoder noise (required when ``config.encoder_noise_std_rad > 0``).
    """

    config: LoopConfig = field(default_factory=LoopConfig)
    rng: np.random.Generator | None = None
    _draws: _Draws | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.config, LoopConfig):
            raise ConfigError("loop.config", self.config, "must be a LoopConfig")
        if self.config.encoder_noise_std_rad > 0.0:
            if not isinstance(self.rng, np.random.Generator):
                raise ConfigError("loop.rng", self.rng, "must be a seeded numpy.random.Generator when "
                                                        "loop.encoder_noise_std_rad > 0")
            object.__setattr__(self, "_draws", _Draws(self.rng, self.config.encoder_noise_std_rad))

    @property
    def ideal(self) -> bool:
        """Whether this is the ideal loop (see :attr:`LoopConfig.ideal`)."""
        return self.config.ideal

    def period_s(self, robot: Robot) -> float:
        """The control period (s) on ``robot``'s physics timestep."""
        return self.config.steps(float(robot.mj.opt.timestep))[0] * float(robot.mj.opt.timestep)

    def run(
        self,
        robot: Robot,
        d: mujoco.MjData,
        law: Law,
        hook: Hook | Measured | None,
        noise: JointNoise | None = None,
    ) -> LoopRun:
        """Run ``law`` until it returns None, stepping the physics underneath.

        Args:
            robot: The models.
            d: MuJoCo data, advanced in place; only the six arm motors' controls are written.
            law: The control law (:data:`Law`); it clips its torques to the motors' limits itself.
            hook: Called with ``d`` after every physics step; may raise to abort. A :class:`Measured` hook also
                gets the tape of the arm's state (:class:`Measured`).
            noise: The sensor fault (noise added to the positions read), or None.

        Returns:
            The :class:`LoopRun`.
        """
        m, h = robot.mj, robot.handles
        qpos, qvel, ctrl = d.qpos, d.qvel, d.ctrl  # arrays aliasing d's memory
        arm_q, arm_v, arm_u = _selector(h.arm_qpos), _selector(h.arm_dof), _selector(h.arm_actuators)
        step_hook, tape = _split(hook, robot, d, TAPE_CHUNK)
        ticks = 0
        k = 0
        step = mujoco.mj_step
        try:
            if self.config.ideal:
                # exact state, torque applied in the same step; the arm's joints are consecutive in qpos and qvel,
                # so the state is read through two views made once (the law gets views of d's memory)
                q_view = qpos[arm_q] if isinstance(arm_q, slice) else None
                v_view = qvel[arm_v] if isinstance(arm_v, slice) else None
                while True:
                    q = (qpos[arm_q] if q_view is None else q_view) if noise is None else qpos[arm_q] + noise.sample()
                    tau = law(k, q, qvel[arm_v] if v_view is None else v_view)
                    if tau is None:
                        return LoopRun(k, ticks)
                    ticks += 1
                    ctrl[arm_u] = tau
                    step(m, d)
                    if tape is not None:
                        tape.record()
                    if step_hook is not None:
                        step_hook(d)
                    k += 1

            cfg = self.config
            dt = float(m.opt.timestep)
            period, latency = cfg.steps(dt)
            T = period * dt
            res = cfg.encoder_resolution_rad
            alpha = 1.0 - math.exp(-2.0 * math.pi * cfg.velocity_cutoff_hz * T) if cfg.velocity_cutoff_hz > 0 else 0.0
            draws = self._draws  # (None without encoder noise)
            pending: deque[tuple[int, np.ndarray]] = deque()
            # two reading buffers, swapped at each tick (this tick's and the last one's); the velocity estimate is
            # updated in place (a warm filter: it starts at the arm's velocity) and handed to the law as is
            q, q_prev = np.empty(N_ARM), np.empty(N_ARM)
            first = True
            v_est = np.array(qvel[arm_v])
            diff = np.empty(N_ARM)
            divide, rint, multiply, subtract, add = np.divide, np.rint, np.multiply, np.subtract, np.add
            # the scalars as arrays (a ufunc takes an array operand faster than a Python float; the same numbers)
            res_, T_, alpha_ = (np.full(N_ARM, x) for x in (res, T, alpha))
            q_arm = qpos[arm_q] if isinstance(arm_q, slice) else None  # a view when the joints are consecutive

            while True:
                if k % period == 0:
                    q, q_prev = q_prev, q
                    q[:] = qpos[arm_q] if q_arm is None else q_arm
                    if res > 0.0:  # round(q / res) * res, in place (rint: numpy's round to 0 decimals)
                        divide(q, res_, out=q)
                        rint(q, out=q)
                        multiply(q, res_, out=q)
                    if draws is not None:
                        add(q, draws.next(), out=q)
                    if noise is not None:
                        q += noise.sample()
                    if alpha > 0.0:
                        if not first:  # v += alpha ((q - q_prev) / T - v), operation for operation
                            subtract(q, q_prev, out=diff)
                            divide(diff, T_, out=diff)
                            subtract(diff, v_est, out=diff)
                            multiply(alpha_, diff, out=diff)
                            add(v_est, diff, out=v_est)
                        first = False
                        qd = v_est
                    else:
                        qd = np.array(qvel[arm_v])
                    tau = law(k, q, qd)
                    if tau is None:
                        return LoopRun(k, ticks)
                    ticks += 1
                    if latency == 0:
                        ctrl[arm_u] = tau
                    else:
                        pending.append((k + latency, np.array(tau)))
                while pending and pending[0][0] <= k:
                    ctrl[arm_u] = pending.popleft()[1]
                step(m, d)
                if tape is not None:
                    tape.record()
                if step_hook is not None:
                    step_hook(d)
                k += 1
        finally:
            if tape is not None:
                tape.flush()

    def run_servo(
        self,
        robot: Robot,
        d: mujoco.MjData,
        setpoints: np.ndarray,
        kp: np.ndarray,
        kd: np.ndarray,
        q_ref: np.ndarray,
        max_error: float,
        on_error: Callable[[int, np.ndarray, np.ndarray, np.ndarray], None],
        hook: Hook | Measured | None,
    ) -> np.ndarray:
        """Run the arm's actuators as position servos (:class:`ServoGains`) through ``len(setpoints)`` physics steps:
        at every step the control is the step's setpoint less ``kd / kp`` times the joints' velocities, and MuJoCo
        applies ``kp (control - q)``, clamped to the torque limits: joint impedance ``kp (q_ref - q) + kd (qd_ref -
        qd) + tau_ff`` with the setpoints of :func:`~pickplace.motion.control.servo_setpoints`. Python writes the
        control (two numpy calls), copies the arm's state block and calls the hook (ideal loop only).

        The damping is applied explicitly, from the velocities at the start of the step, as the Python laws apply
        it. As an actuator's bias (``-kd qd``) MuJoCo's implicit integrator would treat it implicitly, after the
        constraint solver has computed the contact forces without it: with the wrists' ``kd`` a third of their
        inertia over a step (20 N m s/rad, h = 1 ms, about 0.06 kg m^2) the held object then rang in the pads, the
        pads' forces jumping every few milliseconds and the arm passing its acceleration limits in transport
        (99 jumps of the pad force over 0.05 N in one L-bracket transport against 2; 17 of 80 L-bracket trials up to
        1.015x a joint's limit against none).

        The joint error is checked on the tape every :data:`ERROR_CHECK_STEPS` steps (and before the first step
        and after the last), for every step: a state past the bound is reported with its own step, at most
        ``ERROR_CHECK_STEPS`` ms of simulated time after it (the arm stays on the servos' torques meanwhile).

        Args:
            robot: The models.
            d: MuJoCo data, advanced in place; only the six arm actuators' controls are written.
            setpoints: The setpoints of each step (n, 6) (rad): ``q_ref + (kd qd_ref + tau_ff) / kp``.
            kp, kd: Stiffness (6,) (N m/rad) and damping (6,) (N m s/rad).
            q_ref: Reference positions before each step and after the last (n + 1, 6) (rad).
            max_error: ``on_error`` is called for the first state with a joint error ``|q_ref - q|`` beyond it (or not
                finite) (rad).
            on_error: ``on_error(k, e, tape, q)`` with the error (6,) and the positions (6,) of the state before step
                ``k`` and the tape of the steps before it (it may raise to abort).
            hook: Called with ``d`` after every physics step; may raise to abort. A :class:`Measured` hook also
                gets the tape.

        Returns:
            The tape (n, :data:`~pickplace.robot.model.ARM_STATE_WIDTH`): row ``k`` the arm's state at the start of
            step ``k`` (positions, velocities, the torques applied during the step, the tcp).

        Raises:
            ConfigError: the loop is not the ideal one.
        """
        if not self.config.ideal:
            raise ConfigError("loop", self.config, "joint servos run only in the ideal loop")
        m, h = robot.mj, robot.handles
        arm_q, arm_u = _selector(h.arm_qpos), _selector(h.arm_actuators)
        n = len(setpoints)
        step_hook, sink = (hook.step, hook.tape) if isinstance(hook, Measured) else (hook, None)
        rows = np.empty((n, ARM_STATE_WIDTH))
        a = h.arm_state_sensor
        block = d.sensordata[a : a + ARM_STATE_WIDTH]
        t0 = float(d.time)
        q = d.qpos[arm_q]
        ctrl = d.ctrl
        u = ctrl[arm_u]  # views of the arm's controls and velocities
        qd = d.qvel[_selector(h.arm_dof)]
        kd_kp = kd / kp
        damping = np.empty(N_ARM)
        mul, sub = np.multiply, np.subtract
        step = mujoco.mj_step
        every = ERROR_CHECK_STEPS
        max_sq = max_error * max_error
        taken = checked = 0  # steps taken; the states (rows) checked

        def check(upto: int) -> None:
            """Check the states of rows ``checked .. upto - 1``."""
            nonlocal checked
            e = q_ref[checked:upto] - rows[checked:upto, :N_ARM]
            flat = e.reshape(-1)
            if not flat.dot(flat) <= max_sq:  # below it every |e_i| is within the bound; a NaN is not
                outside = ~(np.abs(e) <= max_error).all(axis=1)
                if outside.any():
                    k = checked + int(np.flatnonzero(outside)[0])
                    on_error(k, e[k - checked], rows[:k], rows[k, :N_ARM])
            checked = upto

        try:
            with ServoGains(m, h.arm_actuators, kp):
                e = q_ref[0] - q
                if not (abs(e) <= max_error).all():
                    on_error(0, e, rows[:0], q)
                for k in range(n):
                    mul(kd_kp, qd, out=damping)
                    sub(setpoints[k], damping, out=u)  # the control: the setpoint less the damping's share
                    step(m, d)
                    rows[k] = block
                    taken = k + 1
                    if step_hook is not None:
                        step_hook(d)
                    if taken - checked == every:
                        check(taken)
                if checked < n:
                    check(n)
                e = q_ref[n] - q
                if not (abs(e) <= max_error).all():
                    on_error(n, e, rows, q)
        finally:
            if sink is not None:
                sink(rows[:taken], t0)
        return rows


#: The joint servos' loop checks the joint error of the steps taken every this many physics steps (each step's own
#: error; a state past the bound aborts the loop at most this many steps later).
ERROR_CHECK_STEPS = 16


#: Rows of the arm's state a loop whose length is not known ahead (:meth:`ControlLoop.run`) buffers before it hands
#: them to its :class:`Measured` hook.
TAPE_CHUNK = 512


@dataclass(frozen=True)
class Measured:
    """A loop's hook that also measures the arm's motion: ``step(d)`` after every physics step (may raise), and
    ``tape(rows, t0_s)`` with the arm's state block of the steps taken, in consecutive blocks as the loop runs and at
    its end (also when it ends by a raise); the rows are valid during the call only.

    The tape is MuJoCo's arm sensors (:data:`~pickplace.robot.model.ARM_STATE_FIELDS`), one row per physics step:
    row ``k`` holds the state at the start of step ``k`` (positions, velocities, the tcp) and the torques the
    actuators applied during it; ``t0_s`` is the simulated time (s) of the first row. Copying the block is one numpy
    assignment per step; what is measured on it is computed per block.

    Attributes:
        step: Called with the data after every physics step, or None.
        tape: Called with each block of rows (k, ARM_STATE_WIDTH) and its first row's time (s).
    """

    step: Hook | None
    tape: Callable[[np.ndarray, float], None]


class _Tape:
    """The arm's state block copied after every step into a buffer handed to a :class:`Measured` hook when full."""

    def __init__(self, robot: Robot, d: mujoco.MjData, sink: Callable[[np.ndarray, float], None], rows: int) -> None:
        a = robot.handles.arm_state_sensor
        self._block = d.sensordata[a : a + ARM_STATE_WIDTH]
        self._rows = np.empty((rows, ARM_STATE_WIDTH))
        self._n = 0
        self._d, self._dt = d, float(robot.mj.opt.timestep)
        self._t0 = float(d.time)
        self._sink = sink

    def record(self) -> None:
        """Copy the block after a step."""
        self._rows[self._n] = self._block
        self._n += 1
        if self._n == len(self._rows):
            self.flush()

    def flush(self) -> None:
        """Hand the rows so far to the sink."""
        if self._n:
            self._sink(self._rows[: self._n], self._t0)
            self._t0 += self._n * self._dt
            self._n = 0


def _split(hook: Hook | Measured | None, robot: Robot, d: mujoco.MjData, rows: int) -> tuple[Hook | None, _Tape | None]:
    if isinstance(hook, Measured):
        return hook.step, _Tape(robot, d, hook.tape, rows)
    return hook, None


class _Draws:
    """The encoders' noise (standard deviation ``std_rad``, rad), drawn from the loop's generator :data:`DRAW_CHUNK`
    ticks at a time and handed out a tick's row at a time, across the loop's runs: the same numbers, in the same
    order, as one draw of six per tick (``Generator.normal`` fills an array in the order single draws would come),
    for a tenth of the calls."""

    def __init__(self, rng: np.random.Generator, std_rad: float) -> None:
        self._rng, self._std = rng, std_rad
        self._rows = np.empty((0, N_ARM))
        self._i = 0

    def next(self) -> np.ndarray:
        """The next tick's noise (6,) (rad); valid until the next call."""
        if self._i == len(self._rows):
            self._rows, self._i = self._rng.normal(0.0, self._std, (DRAW_CHUNK, N_ARM)), 0
        row = self._rows[self._i]
        self._i += 1
        return row


#: Ticks of encoder noise a loop draws at once (:class:`_Draws`).
DRAW_CHUNK = 256


class ServoGains:
    """Turns the arm's actuators into position servos for a block: MuJoCo applies ``kp (ctrl - q)`` (clamped to the
    torque limits) at every physics step; restores pure torque actuators after.

    The arm's actuators are ``general`` actuators with an affine bias: torque mode is gain 1 and bias 0
    (``force = ctrl``), servo mode gain ``kp`` and bias ``-kp q``. The damping is not in the bias (``-kd qd`` there
    would be integrated implicitly, see :meth:`ControlLoop.run_servo`): the loop puts it in the control.
    """

    def __init__(self, m: mujoco.MjModel, actuators: np.ndarray, kp: np.ndarray) -> None:
        self.m, self.a, self.kp = m, actuators, kp

    def __enter__(self) -> None:
        m, a = self.m, self.a
        m.actuator_gainprm[a, 0] = self.kp
        m.actuator_biasprm[a, 1] = -self.kp

    def __exit__(self, *exc: object) -> None:
        m, a = self.m, self.a
        m.actuator_gainprm[a, 0] = 1.0
        m.actuator_biasprm[a, 1] = 0.0


def _selector(idx: np.ndarray) -> slice | np.ndarray:
    """A slice for consecutive indices (a view, cheaper than fancy indexing every step), else the indices."""
    ids = np.asarray(idx).tolist()
    if ids and ids == list(range(ids[0], ids[0] + len(ids))):
        return slice(ids[0], ids[0] + len(ids))
    return np.asarray(idx)


#: The ideal loop (no noise source needed).
IDEAL = ControlLoop()

__all__ = [
    "ERROR_CHECK_STEPS",
    "IDEAL",
    "UR5E_ENCODER_NOISE_STD_RAD",
    "UR5E_ENCODER_RESOLUTION_RAD",
    "UR_E_SERIES_CONTROL_PERIOD_S",
    "VELOCITY_CUTOFF_HZ",
    "ControlLoop",
    "Law",
    "LoopConfig",
    "LoopRun",
    "Measured",
    "ServoGains",
]
