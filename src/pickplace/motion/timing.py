"""Time-optimal time scaling of joint-space paths with TOPP-RA (the ``toppra`` package).

:func:`retime` turns a collision-checked polyline of UR5e joint waypoints into a rest-to-rest
trajectory that respects per-joint velocity and acceleration limits:

1. validate the path and drop near-duplicate waypoints (they make TOPP-RA fail or crawl);
2. insert points along long straight segments so the cubic spline hugs the polyline;
3. parameterize the spline by cumulative joint-space arc length (rad), which keeps |dq/ds| ~ 1;
4. optionally ask ``is_segment_valid`` about a dense sampling of the spline and densify again
   (halving the segment length) while it is rejected;
5. run TOPP-RA, then refine the grid locally wherever the piecewise-constant path acceleration
   between gridpoints exceeds a limit.

The output is evaluated exactly as TOPP-RA models it: constant path acceleration per grid stage.

:func:`retime_parts` times several pieces of path as one motion that does not stop where they meet (a planned
path that runs into a straight tcp move, the lift that runs into the transport): the straight moves' IK
waypoints are interpolated as given, the planned pieces loosely (see :class:`PathPart`), and the trajectory
knows when it passes each junction (:attr:`Trajectory.part_times_s`), so that a motion can be run, and reported,
phase by phase.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import toppra
import toppra.algorithm as talgo
import toppra.constraint as tcon

from pickplace.errors import ConfigError, TimingFailed
from pickplace.world.config import check_int, check_range, check_vector

logger = logging.getLogger(__name__)

N_JOINTS = 6
#: UR5e published joint speed limit, 180 deg/s on every joint (rad/s).
UR5E_VELOCITY_LIMITS_RAD_S: tuple[float, ...] = (math.pi,) * N_JOINTS
#: Joint acceleration limits used for the UR5e: shoulder/elbow 8, wrists 16 (rad/s^2).
UR5E_ACCELERATION_LIMITS_RAD_S2: tuple[float, ...] = (8.0, 8.0, 8.0, 16.0, 16.0, 16.0)
#: Velocity limits of the design note: 3.14 rad/s (joints 1-3), 6.28 rad/s (joints 4-6).
DESIGN_NOTE_VELOCITY_LIMITS_RAD_S: tuple[float, ...] = (3.14, 3.14, 3.14, 6.28, 6.28, 6.28)
_CHECK_FRACTIONS = np.linspace(0.0, 1.0, 9)  # where each grid stage is checked for limits


@dataclass(frozen=True)
class TimingConfig:
    """Limits and numerical settings of :func:`retime`.

    Attributes:
        velocity_limits_rad_s: Per-joint speed limits (6,) (rad/s).
        acceleration_limits_rad_s2: Per-joint acceleration limits (6,) (rad/s^2).
        limit_margin: Fraction the limits are shrunk by before TOPP-RA, absorbing discretization error.
        grid_step_rad: Initial TOPP-RA gridpoint spacing along the path (rad of joint-space arc length).
        max_segment_rad: Longest straight piece between spline knots (rad); smaller hugs the polyline
            more tightly but forces slower corners. Halved at each densification round.
        min_separation_rad: Waypoints closer than this to their predecessor are dropped (rad).
        check_step_rad: Spacing of the configurations passed to ``is_segment_valid`` (rad).
        max_densify_rounds: Extra densification rounds allowed when ``is_segment_valid`` rejects.
        max_refine_rounds: Rounds of local grid refinement where limits are exceeded between gridpoints.
    """

    velocity_limits_rad_s: tuple[float, ...] = UR5E_VELOCITY_LIMITS_RAD_S
    acceleration_limits_rad_s2: tuple[float, ...] = UR5E_ACCELERATION_LIMITS_RAD_S2
    limit_margin: float = 0.005
    grid_step_rad: float = 0.01
    max_segment_rad: float = 0.1
    min_separation_rad: float = 1e-3
    check_step_rad: float = 0.01
    max_densify_rounds: int = 4
    max_refine_rounds: int = 8

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "velocity_limits_rad_s", check_vector(
            "timing.velocity_limits_rad_s", self.velocity_limits_rad_s, N_JOINTS, 0.0, lo_open=True,
            unit="rad/s"))
        set_(self, "acceleration_limits_rad_s2", check_vector(
            "timing.acceleration_limits_rad_s2", self.acceleration_limits_rad_s2, N_JOINTS, 0.0,
            lo_open=True, unit="rad/s^2"))
        set_(self, "limit_margin", check_range("timing.limit_margin", self.limit_margin, 0.0, 0.2))
        set_(self, "grid_step_rad", check_range("timing.grid_step_rad", self.grid_step_rad, 1e-4, 0.1,
                                                unit="rad"))
        set_(self, "max_segment_rad", check_range("timing.max_segment_rad", self.max_segment_rad, 0.005,
                                                  unit="rad"))
        set_(self, "min_separation_rad", check_range("timing.min_separation_rad", self.min_separation_rad,
                                                     0.0, 0.05, unit="rad"))
        set_(self, "check_step_rad", check_range("timing.check_step_rad", self.check_step_rad, 1e-4, 0.5,
                                                 unit="rad"))
        set_(self, "max_densify_rounds", check_int("timing.max_densify_rounds", self.max_densify_rounds,
                                                   0, 10))
        set_(self, "max_refine_rounds", check_int("timing.max_refine_rounds", self.max_refine_rounds, 0, 20))

    @classmethod
    def ur5e(cls, **overrides: object) -> TimingConfig:
        """The default: UR5e published speed limits (pi rad/s) and 8/16 rad/s^2 accelerations."""
        return cls(**overrides)  # type: ignore[arg-type]

    @classmethod
    def design_note(cls, **overrides: object) -> TimingConfig:
        """Design-note limits: 3.14 rad/s (joints 1-3), 6.28 rad/s (joints 4-6), same accelerations."""
        return cls(velocity_limits_rad_s=DESIGN_NOTE_VELOCITY_LIMITS_RAD_S, **overrides)  # type: ignore[arg-type]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A rest-to-rest joint trajectory q(t) = spline(s(t)) with piecewise-constant path acceleration.

    Attributes:
        waypoints: The path it was built from (N, 6) (rad), read-only.
        knots: The de-duplicated, densified points the cubic spline interpolates (K, 6) (rad).
        duration_s: Total duration (s); 0 for a path that does not move.
        max_deviation_rad: Largest joint-space distance (Euclidean, rad) between the spline and the
            polyline at equal arc length, an upper bound of the distance to the polyline.
        retime_time_s: Wall time spent inside TOPP-RA, all grid refinements included (s).
        peak_velocity_ratio: max |qd_j| / vlim_j over the checked points (gridpoints and stage quarters).
        peak_acceleration_ratio: max |qdd_j| / alim_j over the same points.
        densify_rounds: Extra densification rounds that ``is_segment_valid`` required.
        part_times_s: Times (s) at which the trajectory passes the start of each of its parts and its end
            (:func:`retime_parts`; ``(0, duration)`` for one path).
    """

    waypoints: np.ndarray
    knots: np.ndarray
    duration_s: float
    max_deviation_rad: float
    retime_time_s: float
    peak_velocity_ratio: float
    peak_acceleration_ratio: float
    densify_rounds: int
    _spline: toppra.SplineInterpolator | None = field(repr=False)
    _s: np.ndarray = field(repr=False)  # (n,) gridpoints (rad)
    _t: np.ndarray = field(repr=False)  # (n,) time at each gridpoint (s)
    _sd: np.ndarray = field(repr=False)  # (n,) path speed ds/dt at each gridpoint (rad/s)
    _u: np.ndarray = field(repr=False)  # (n-1,) constant path acceleration of each stage (rad/s^2)
    part_times_s: tuple[float, ...] = ()
    _offset: tuple[float, float, np.ndarray] | None = field(default=None, repr=False)  # (t0, t1, dq): with_offset

    def __post_init__(self) -> None:
        if not self.part_times_s:
            object.__setattr__(self, "part_times_s", (0.0, float(self.duration_s)))

    def slowed(self, factor: float) -> Trajectory:
        """The same path run ``factor`` (>= 1) times slower: velocities divided by the factor, accelerations by
        its square (a uniform time scaling keeps every limit the original respected)."""
        k = float(factor)
        if not (math.isfinite(k) and k >= 1.0):
            raise ValueError(f"factor must be a finite number >= 1, got {factor!r}")
        offset = None if self._offset is None else (self._offset[0] * k, self._offset[1] * k, self._offset[2])
        return dataclasses.replace(self, duration_s=self.duration_s * k,
                                   peak_velocity_ratio=self.peak_velocity_ratio / k,
                                   peak_acceleration_ratio=self.peak_acceleration_ratio / k**2, _t=self._t * k,
                                   _sd=self._sd / k, _u=self._u / k**2,
                                   part_times_s=tuple(t * k for t in self.part_times_s), _offset=offset)

    def with_offset(self, t0_s: float, dq_rad: np.ndarray) -> Trajectory:
        """The same trajectory with an offset ``dq_rad`` (6,) (rad) blended in from ``t0_s`` (s) to its end by a
        minimum-jerk profile (0 before ``t0_s``, all of it from the end on): a correction of where it ends, made
        while it runs. The offset adds ``1.875 |dq| / T`` of speed and ``5.77 |dq| / T^2`` of acceleration at most
        (T the time left); :meth:`offset_headroom` says how much of it fits within limits."""
        dq = np.array(dq_rad, dtype=float).reshape(N_JOINTS)
        t0 = float(np.clip(t0_s, 0.0, self.duration_s))
        if self.duration_s - t0 <= 0.0 or not np.any(dq):
            return self
        if self._offset is not None:
            raise ValueError("the trajectory already has an offset")
        dq.setflags(write=False)
        return dataclasses.replace(self, _offset=(t0, self.duration_s, dq))

    def offset_headroom(self, t0_s: float, dq_rad: np.ndarray, velocity_limits: np.ndarray,
                        acceleration_limits: np.ndarray, dt_s: float) -> float:
        """The largest fraction (0..1) of the offset ``dq_rad`` that :meth:`with_offset` can blend in from ``t0_s``
        with the joints within ``velocity_limits`` (6,) and ``acceleration_limits`` (6,) at every ``dt_s`` (s):
        the offset's velocity and acceleration add linearly, so each sample bounds the fraction."""
        dq = np.asarray(dq_rad, dtype=float)
        t0 = float(np.clip(t0_s, 0.0, self.duration_s))
        T = self.duration_s - t0
        if T <= 0.0 or not np.any(dq):
            return 1.0
        ts = np.arange(t0, self.duration_s + dt_s, dt_s)
        _, qd, qdd = self.sample_many(ts)
        _, sd, sdd = _min_jerk((ts - t0) / T)
        fraction = 1.0
        for base, extra, lim in ((qd, np.outer(sd / T, dq), velocity_limits),
                                 (qdd, np.outer(sdd / T**2, dq), acceleration_limits)):
            lim = np.asarray(lim, dtype=float)
            # |base + a extra| <= lim for a in [0, fraction]: the bound where extra pushes base towards a limit
            with np.errstate(divide="ignore", invalid="ignore"):
                room = np.where(extra > 0, (lim - base) / extra, np.where(extra < 0, (-lim - base) / extra, np.inf))
            room = np.where(np.abs(base) > lim, 0.0, room)  # already at a limit there: no room
            fraction = min(fraction, float(np.min(room)))
        return max(0.0, fraction)

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Evaluate at one time ``t`` (s), clamped to [0, duration] and at rest outside.

        Returns:
            Joint positions (6,) (rad), velocities (6,) (rad/s) and accelerations (6,) (rad/s^2).
        """
        q, qd, qdd = self.sample_many(np.array([float(t)]))
        return q[0], qd[0], qdd[0]

    def sample_many(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Evaluate at times ``ts`` (N,) (s); see :meth:`sample`.

        Returns:
            Positions (N, 6) (rad), velocities (N, 6) (rad/s), accelerations (N, 6) (rad/s^2).
        """
        ts = np.asarray(ts, dtype=float)
        if ts.ndim != 1 or not np.isfinite(ts).all():
            raise ValueError(f"ts must be a 1-D array of finite times (s), got shape {ts.shape}")
        qd = np.zeros((ts.size, N_JOINTS))
        qdd = np.zeros((ts.size, N_JOINTS))
        if self._spline is None:
            return np.repeat(self.knots[:1], ts.size, axis=0), qd, qdd
        tc = np.clip(ts, 0.0, self.duration_s)
        i = np.clip(np.searchsorted(self._t, tc, side="right") - 1, 0, self._u.size - 1)
        dt, u = tc - self._t[i], self._u[i]
        sd = np.maximum(self._sd[i] + u * dt, 0.0)
        s = np.clip(self._s[i] + self._sd[i] * dt + 0.5 * u * dt**2, 0.0, self._s[-1])
        s[tc >= self.duration_s] = self._s[-1]
        d1, d2 = self._spline(s, 1), self._spline(s, 2)
        moving = (ts >= 0.0) & (ts <= self.duration_s)
        qd[moving] = (d1 * sd[:, None])[moving]
        qdd[moving] = (d2 * sd[:, None] ** 2 + d1 * u[:, None])[moving]
        q = self._spline(s)
        if self._offset is not None:
            t0, t1, dq = self._offset
            T = t1 - t0
            w, wd, wdd = _min_jerk((ts - t0) / T)
            q += np.outer(w, dq)
            qd += np.outer(np.where(moving, wd / T, 0.0), dq)
            qdd += np.outer(np.where(moving, wdd / T**2, 0.0), dq)
        return q, qd, qdd

    @property
    def end(self) -> np.ndarray:
        """Where the trajectory ends (6,) (rad): its last waypoint, plus its offset if it has one."""
        return self.sample(self.duration_s)[0]


def retime(
    path: np.ndarray,
    config: TimingConfig | None = None,
    is_segment_valid: Callable[[np.ndarray], bool] | None = None,
) -> Trajectory:
    """Time-optimal rest-to-rest time scaling of a joint-space polyline.

    Args:
        path: Joint waypoints (N, 6) (rad), N >= 2, e.g. a planner's collision-checked polyline.
        config: Limits and numerical settings; defaults to :meth:`TimingConfig.ur5e`.
        is_segment_valid: Optional check of the geometric path the trajectory follows. Called with
            configurations (M, 6) (rad) sampled every ``config.check_step_rad`` of arc length; when it
            returns False the straight segments are densified further and the check repeated.

    Returns:
        The trajectory, starting at ``path[0]`` and ending at ``path[-1]`` at rest.

    Raises:
        ConfigError: ``path`` is not a finite (N, 6) array with N >= 2.
        TimingFailed: TOPP-RA found no parameterization, or ``is_segment_valid`` still rejects the
            path after ``config.max_densify_rounds`` rounds.
    """
    cfg = config if config is not None else TimingConfig()
    raw = _as_path(path)
    raw.setflags(write=False)
    pts = _dedupe(raw, cfg.min_separation_rad)
    logger.debug("retime: %d waypoints, %d after de-duplication", len(raw), len(pts))
    if len(pts) == 1:
        if is_segment_valid is not None and not is_segment_valid(pts.copy()):
            raise TimingFailed("is_segment_valid rejects the (motionless) path's only configuration")
        e0, e1 = np.zeros(1), np.zeros(0)
        return Trajectory(raw, pts, 0.0, 0.0, 0.0, 0.0, 0.0, 0, None, e0, e0, e0, e1)
    for rnd in range(cfg.max_densify_rounds + 1):
        knots = _densify(pts, cfg.max_segment_rad / 2**rnd)
        ss = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(knots, axis=0), axis=1))))
        spline = toppra.SplineInterpolator(ss, knots)  # not-a-knot; exactly straight on collinear knots
        s_chk = np.linspace(0.0, ss[-1], max(2, math.ceil(ss[-1] / cfg.check_step_rad) + 1))
        q_chk = spline(s_chk)
        polyline = np.stack([np.interp(s_chk, ss, knots[:, j]) for j in range(N_JOINTS)], axis=1)
        deviation = float(np.max(np.linalg.norm(q_chk - polyline, axis=1)))
        logger.debug("round %d: %d knots, length %.3f rad, deviation %.4f rad", rnd, len(knots), ss[-1],
                     deviation)
        if is_segment_valid is None or is_segment_valid(q_chk):
            break
    else:
        raise TimingFailed(
            f"is_segment_valid still rejects the spline after {cfg.max_densify_rounds} densification rounds "
            f"(segments <= {cfg.max_segment_rad / 2**cfg.max_densify_rounds:.4g} rad, "
            f"deviation {deviation:.4g} rad)")
    grid, sd, elapsed, v_ratio, a_ratio = _solve(spline, ss[-1], cfg)
    x = sd**2
    t = np.concatenate(([0.0], np.cumsum(2.0 * np.diff(grid) / (sd[:-1] + sd[1:]))))
    if not np.isfinite(t[-1]):
        raise TimingFailed(f"TOPP-RA stops mid-path (path speed 0 inside the path of {ss[-1]:.3f} rad)")
    u = np.diff(x) / (2.0 * np.diff(grid))
    knots.setflags(write=False)
    logger.debug("retime: duration %.4f s, TOPP-RA %.1f ms, %d gridpoints, peak ratios v %.4f a %.4f",
                 t[-1], elapsed * 1e3, grid.size, v_ratio, a_ratio)
    return Trajectory(raw, knots, float(t[-1]), deviation, elapsed, v_ratio, a_ratio, rnd, spline, grid, t,
                      sd, u)


@dataclass(frozen=True, eq=False)
class PathPart:
    """One piece of a joint path that :func:`retime_parts` times as one motion with its neighbours.

    Attributes:
        waypoints: Joint waypoints (N, 6) (rad), N >= 2; the first is the previous part's last. A planned part: a
            planner's polyline; a straight part: the IK waypoints of a straight tcp move, close together (1 cm).
        straight: A straight tcp move: the spline passes through every waypoint as given, none added or removed.
            A planned part is interpolated loosely, through its waypoints only (its straight joint segments are
            not followed), so that the motion turns into and out of the straight moves without slowing down
            at the junction; its waypoints are densified only as far as ``is_valid`` requires.
        is_valid: Check of the spline over this part (configurations (M, 6), every ``check_step_rad``), or None.
        tcp_speed_m_s: The tcp's speed limit along the part (m/s) (needs ``tcp_rate`` in :func:`retime_parts`);
            inf: none.
        reserve: The share of the joints' speed and acceleration limits the part is *not* timed with (0..0.5):
            room left for a correction made while it runs (:meth:`Trajectory.with_offset`).
    """

    waypoints: np.ndarray
    straight: bool = False
    is_valid: Callable[[np.ndarray], bool] | None = None
    tcp_speed_m_s: float = math.inf
    reserve: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "waypoints", _as_path(self.waypoints))
        if not (self.tcp_speed_m_s > 0.0):
            raise ConfigError("part.tcp_speed_m_s", self.tcp_speed_m_s, "must be > 0 (m/s)")
        object.__setattr__(self, "reserve", check_range("part.reserve", self.reserve, 0.0, 0.5))


class _ScaledJointAcceleration(tcon.JointAccelerationConstraint):
    """TOPP-RA's joint acceleration constraint with the limits scaled by ``scale(s)`` (0..1] per gridpoint: the
    path derivatives are divided by it instead (``|q' u + q'' x| <= scale alim``), which keeps the limits' matrices
    the same at every gridpoint."""

    def __init__(self, alim: np.ndarray, scale: Callable[[np.ndarray], np.ndarray]) -> None:
        super().__init__(alim, tcon.DiscretizationType.Interpolation)
        self.scale = scale

    def compute_constraint_params(self, path: toppra.SplineInterpolator, gridpoints: np.ndarray,
                                  *args: object, **kwargs: object) -> tuple:
        k = 1.0 / self.scale(np.asarray(gridpoints))[:, None]

        class _Scaled:  # the path as the constraint sees it: its derivatives over the scale
            dof = path.dof

            def __call__(self, s: np.ndarray, order: int = 0) -> np.ndarray:
                return path(s, order) * k if order else path(s, order)

        return super().compute_constraint_params(_Scaled(), gridpoints)


class _PathSpeedLimit(tcon.LinearConstraint):
    """TOPP-RA constraint ``sd <= sd_max(s)``: the path speed bounded per gridpoint (here by the tcp's speed)."""

    def __init__(self, sd_max: Callable[[np.ndarray], np.ndarray]) -> None:
        super().__init__()
        self.dof = N_JOINTS
        self.sd_max = sd_max
        self._format_string = "    Path speed limit\n"

    def compute_constraint_params(self, path: toppra.SplineInterpolator, gridpoints: np.ndarray) -> tuple:
        x_max = np.minimum(self.sd_max(np.asarray(gridpoints)) ** 2, _X_UNBOUNDED)
        xbound = np.column_stack([np.zeros_like(x_max), x_max])
        return None, None, None, None, None, None, xbound


#: Bound on the squared path speed where nothing bounds it (TOPP-RA takes finite bounds).
_X_UNBOUNDED = 1e12


def retime_parts(
    parts: Sequence[PathPart],
    config: TimingConfig | None = None,
    tcp_rate: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> Trajectory:
    """Time-optimal rest-to-rest time scaling of several path parts as one motion, without stopping between them.

    The knots are the straight parts' waypoints and the planned parts' waypoints; one natural cubic spline
    through them is C2 everywhere, so where a planned path meets a straight move the motion turns into it
    instead of stopping at the corner. The planned parts are checked (``is_valid``) and, while the check
    rejects the spline anywhere, their segments are densified (longest ``0.4, 0.2, ...`` rad, halved each round,
    :attr:`TimingConfig.max_densify_rounds` + 2 rounds): the spline then hugs their polyline, and corners at the
    junctions come back. With straight parts only (a straight move timed on its own), a rejection is final.

    Args:
        parts: The parts in order; each starts where the one before ends.
        config: Limits and numerical settings; defaults to :meth:`TimingConfig.ur5e`.
        tcp_rate: The tcp's speed per unit path speed (m/rad), ``|J(q) q'|``, at configurations (M, 6) with
            path derivatives (M, 6): needed if a part limits the tcp's speed.

    Returns:
        The trajectory, starting at the first part's start and ending at the last part's end at rest;
        ``part_times_s`` gives when it passes the start of each part (and its end).

    Raises:
        ConfigError: no part, parts that do not join, or a tcp speed limit without ``tcp_rate``.
        TimingFailed: TOPP-RA found no parameterization, or a check still rejects the spline after the last
            round.
    """
    cfg = config if config is not None else TimingConfig()
    if not parts:
        raise ConfigError("parts", parts, "must be at least one path part")
    for i, (a, b) in enumerate(itertools.pairwise(parts)):
        gap = float(np.max(np.abs(a.waypoints[-1] - b.waypoints[0])))
        if gap > 1e-6:
            raise ConfigError(f"parts[{i + 1}].waypoints[0]", gap, "must be the previous part's last waypoint "
                                                                    "(within 1e-6 rad)")
    if any(math.isfinite(p.tcp_speed_m_s) for p in parts) and tcp_rate is None:
        raise ConfigError("tcp_rate", None, "is needed to limit the tcp's speed along a part")
    raw = np.vstack([parts[0].waypoints[:1], *(p.waypoints[1:] for p in parts)])
    raw.setflags(write=False)
    lengths = [math.inf] + [cfg.max_segment_rad * 2.0 ** (2 - r) for r in range(1, cfg.max_densify_rounds + 3)]
    for rnd, max_len in enumerate(lengths):
        pieces = [parts[0].waypoints[:1]]
        for p in parts:
            pts = p.waypoints if p.straight else _densify(_dedupe(p.waypoints, cfg.min_separation_rad), max_len)
            pieces.append(pts[1:])
        knots = np.vstack(pieces)
        bounds = np.cumsum([0] + [len(x) for x in pieces[1:]])  # knot index where each part ends
        keep = np.concatenate(([True], np.linalg.norm(np.diff(knots, axis=0), axis=1) > 1e-9))
        if not keep.all():
            raise ConfigError("parts", "duplicate waypoints", "a part repeats a waypoint (no motion between two)")
        ss = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(knots, axis=0), axis=1))))
        s_parts = ss[bounds]  # (n_parts + 1,): arc length at each part's start, and the end
        spline = toppra.SplineInterpolator(ss, knots, bc_type="natural")
        s_chk = np.linspace(0.0, ss[-1], max(2, math.ceil(ss[-1] / cfg.check_step_rad) + 1))
        q_chk = spline(s_chk)
        rejected = [i for i, p in enumerate(parts) if p.is_valid is not None and not p.is_valid(
            q_chk[(s_chk >= s_parts[i] - 1e-12) & (s_chk <= s_parts[i + 1] + 1e-12)])]
        logger.debug("retime_parts round %d: %d knots, length %.3f rad, parts rejected %s", rnd, len(knots), ss[-1],
                     rejected)
        if not rejected:
            break
        if all(p.straight for p in parts):  # nothing to densify: the next rounds would give the same spline
            raise TimingFailed(f"the checks reject parts {rejected} of the spline through the straight parts' "
                               "waypoints")
    else:
        raise TimingFailed(f"the checks still reject parts {rejected} of the spline after densifying the planned "
                           f"parts to {lengths[-1]:.4g} rad")
    vmax = np.array([p.tcp_speed_m_s for p in parts])
    share = 1.0 - np.array([p.reserve for p in parts])
    vlim = np.array(cfg.velocity_limits_rad_s) * (1.0 - cfg.limit_margin)

    def part_at(s: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(s_parts, s, side="right") - 1, 0, len(parts) - 1)

    def sd_max(s: np.ndarray) -> np.ndarray:
        part = part_at(s)
        out = np.full(s.shape, math.inf)
        bounded = np.isfinite(vmax[part])
        if bounded.any():  # the tcp's speed
            assert tcp_rate is not None
            rate = tcp_rate(spline(s[bounded]), spline(s[bounded], 1))
            out[bounded] = vmax[part][bounded] / np.maximum(rate, 1e-9)
        reserved = share[part] < 1.0
        if reserved.any():  # the joints' speeds, less the reserve
            d1 = np.abs(spline(s[reserved], 1))
            with np.errstate(divide="ignore"):
                out[reserved] = np.minimum(out[reserved], np.min(share[part][reserved, None] * vlim / d1, axis=1))
        return out

    extra = [_PathSpeedLimit(sd_max)] if np.isfinite(vmax).any() or (share < 1.0).any() else []
    scale = (lambda s: share[part_at(s)]) if (share < 1.0).any() else None
    grid, sd, elapsed, v_ratio, a_ratio = _solve(spline, ss[-1], cfg, extra, scale, breaks=s_parts[1:-1])
    x = sd**2
    t = np.concatenate(([0.0], np.cumsum(2.0 * np.diff(grid) / (sd[:-1] + sd[1:]))))
    if not np.isfinite(t[-1]):
        raise TimingFailed(f"TOPP-RA stops mid-path (path speed 0 inside the path of {ss[-1]:.3f} rad)")
    u = np.diff(x) / (2.0 * np.diff(grid))
    part_times = tuple(float(v) for v in _times_at(s_parts, grid, t, sd, u))
    polyline = np.stack([np.interp(s_chk, ss, knots[:, j]) for j in range(N_JOINTS)], axis=1)
    deviation = float(np.max(np.linalg.norm(q_chk - polyline, axis=1)))
    knots.setflags(write=False)
    logger.debug("retime_parts: %d parts, duration %.4f s (parts at %s s), TOPP-RA %.1f ms, peak ratios v %.4f "
                 "a %.4f", len(parts), t[-1], np.round(part_times, 3).tolist(), elapsed * 1e3, v_ratio, a_ratio)
    return Trajectory(raw, knots, float(t[-1]), deviation, elapsed, v_ratio, a_ratio, rnd, spline, grid, t, sd, u,
                      part_times)


def _times_at(s_query: np.ndarray, grid: np.ndarray, t: np.ndarray, sd: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Times (s) at which a TOPP-RA solution (gridpoints, their times, path speeds, stage accelerations) reaches
    the arc lengths ``s_query`` (constant path acceleration within each stage)."""
    out = np.empty(len(s_query))
    for k, s in enumerate(s_query):
        i = int(np.clip(np.searchsorted(grid, s, side="right") - 1, 0, len(u) - 1))
        ds = float(s - grid[i])
        if ds <= 0.0:
            out[k] = t[i]
            continue
        v0, a = float(sd[i]), float(u[i])
        # s = v0 dt + a dt^2 / 2: the root reached first (the stable form of the quadratic formula)
        root = math.sqrt(max(v0 * v0 + 2.0 * a * ds, 0.0))
        out[k] = t[i] + (2.0 * ds / (v0 + root) if v0 + root > 0.0 else 0.0)
    out[0], out[-1] = t[0], t[-1]  # the start and the end exactly
    return np.minimum(out, t[-1])


def _min_jerk(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk profile from 0 to 1 at normalized times ``tau`` (N,) (clipped to [0, 1]): position and its
    first and second derivatives with respect to ``tau``."""
    x = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
    return (x**3 * (10.0 - 15.0 * x + 6.0 * x * x), 30.0 * x * x * (1.0 - x) ** 2,
            60.0 * x * (1.0 - x) * (1.0 - 2.0 * x))


def _solve(
    spline: toppra.SplineInterpolator, length: float, cfg: TimingConfig,
    extra: Sequence[tcon.LinearConstraint] = (), accel_scale: Callable[[np.ndarray], np.ndarray] | None = None,
    breaks: np.ndarray | Sequence[float] = (),
) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """Run TOPP-RA, refining stages that exceed a limit between gridpoints (``extra``: more constraints;
    ``accel_scale(s)``: the share (0..1] of the acceleration limits allowed at ``s``; ``breaks``: arc lengths
    (rad) that must be gridpoints, where a constraint changes, e.g. where a part with a speed limit starts: a
    stage that straddles one is bounded only at its ends, by the part before).

    Returns:
        Gridpoints (n,) (rad), path speeds (n,) (rad/s), TOPP-RA wall time (s), and the peak
        velocity and acceleration ratios to the (unshrunk) limits.
    """
    vlim = np.array(cfg.velocity_limits_rad_s)
    alim = np.array(cfg.acceleration_limits_rad_s2)
    shrink = 1.0 - cfg.limit_margin
    constraints = [
        tcon.JointVelocityConstraint(vlim * shrink),
        tcon.JointAccelerationConstraint(alim * shrink, tcon.DiscretizationType.Interpolation)
        if accel_scale is None else _ScaledJointAcceleration(alim * shrink, accel_scale),
        *extra,
    ]
    grid = np.linspace(0.0, length, max(50, math.ceil(length / cfg.grid_step_rad) + 1))
    inner = np.asarray(breaks, dtype=float)
    inner = inner[(inner > 0.0) & (inner < length)]
    if inner.size:
        step = length / (grid.size - 1)
        far = np.min(np.abs(grid[:, None] - inner[None, :]), axis=1) > 1e-3 * step  # no near-duplicate gridpoints
        grid = np.unique(np.concatenate([grid[far | (grid == 0.0) | (grid == length)], inner]))
    elapsed = 0.0
    for rnd in range(cfg.max_refine_rounds + 1):
        t0 = time.perf_counter()
        solver = talgo.TOPPRA(constraints, spline, gridpoints=grid, solver_wrapper="seidel",
                              parametrizer="ParametrizeConstAccel")
        out = solver.compute_trajectory(0.0, 0.0)
        elapsed += time.perf_counter() - t0
        sd = solver.problem_data.sd_vec
        if out is None or sd is None or not np.all(np.isfinite(sd)):
            raise TimingFailed(
                f"TOPP-RA found no time scaling ({solver.problem_data.return_code}) for a path of "
                f"{length:.4g} rad on {grid.size} gridpoints")
        sd = np.maximum(np.asarray(sd, dtype=float), 0.0)
        v_ratio, a_ratio = _stage_ratios(spline, grid, sd, vlim, alim)
        bad = np.maximum(v_ratio, a_ratio) > 1.0
        logger.debug("TOPP-RA round %d: %d gridpoints, %d stages over a limit", rnd, grid.size, bad.sum())
        if not bad.any():
            break
        if rnd == cfg.max_refine_rounds:
            logger.warning("limits exceeded between gridpoints by up to %.2f %% after %d refinements",
                           100 * (max(v_ratio.max(), a_ratio.max()) - 1), rnd)
            break
        bad[:-1] |= bad[1:].copy()  # split the offending stages and their predecessors in four
        ds = np.diff(grid)[bad]
        grid = np.sort(np.concatenate([grid, *(grid[:-1][bad] + f * ds for f in (0.25, 0.5, 0.75))]))
    return grid, sd, elapsed, float(v_ratio.max()), float(a_ratio.max())


def _stage_ratios(
    spline: toppra.SplineInterpolator, grid: np.ndarray, sd: np.ndarray, vlim: np.ndarray, alim: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per stage (n-1,), the largest |qd_j|/vlim_j and |qdd_j|/alim_j at a few points inside it."""
    ds = np.diff(grid)
    x = sd**2
    u = np.diff(x) / (2.0 * ds)
    s = grid[:-1, None] + _CHECK_FRACTIONS * ds[:, None]  # (n-1, k)
    xs = np.maximum(x[:-1, None] + 2.0 * u[:, None] * (s - grid[:-1, None]), 0.0)
    shape = (*s.shape, N_JOINTS)
    d1 = spline(s.ravel(), 1).reshape(shape)
    d2 = spline(s.ravel(), 2).reshape(shape)
    v = np.abs(d1) * np.sqrt(xs)[..., None] / vlim
    a = np.abs(d2 * xs[..., None] + d1 * u[:, None, None]) / alim
    return v.max(axis=(1, 2)), a.max(axis=(1, 2))


def _as_path(path: np.ndarray) -> np.ndarray:
    """Return ``path`` as a fresh float array (N, 6), or raise ConfigError."""
    try:
        arr = np.array(path, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError("path", type(path).__name__, "must be an (N, 6) array of joint positions (rad)") \
            from None
    if arr.ndim != 2 or arr.shape[1] != N_JOINTS or arr.shape[0] < 2:
        raise ConfigError("path.shape", arr.shape, f"must be (N, {N_JOINTS}) with N >= 2 waypoints")
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if bad.size:
        raise ConfigError(f"path[{bad[0]}]", tuple(arr[bad[0]].tolist()),
                          "must be finite joint positions (rad)")
    return arr


def _dedupe(path: np.ndarray, tol: float) -> np.ndarray:
    """Drop waypoints within ``tol`` (rad) of their predecessor, keeping both endpoints (K, 6)."""
    keep = [path[0]]
    for q in path[1:-1]:
        if np.linalg.norm(q - keep[-1]) > tol:
            keep.append(q)
    while len(keep) > 1 and np.linalg.norm(path[-1] - keep[-1]) <= tol:
        keep.pop()
    if np.linalg.norm(path[-1] - keep[-1]) > tol:
        keep.append(path[-1])
    return np.array(keep)


def _densify(pts: np.ndarray, max_len: float) -> np.ndarray:
    """Split every segment of the polyline ``pts`` (K, 6) into equal pieces <= ``max_len`` (rad)."""
    out = [pts[:1]]
    for a, b in itertools.pairwise(pts):
        n = max(1, math.ceil(np.linalg.norm(b - a) / max_len))
        out.append(a + (np.arange(1, n + 1)[:, None] / n) * (b - a))
    return np.concatenate(out)


__all__ = [
    "DESIGN_NOTE_VELOCITY_LIMITS_RAD_S",
    "UR5E_ACCELERATION_LIMITS_RAD_S2",
    "UR5E_VELOCITY_LIMITS_RAD_S",
    "PathPart",
    "TimingConfig",
    "Trajectory",
    "retime",
    "retime_parts",
]
