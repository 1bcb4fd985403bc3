"""A recorded episode (or task) on disk: what ``pickplace run --save`` writes and ``pickplace replay`` reads.

One compressed ``.npz`` file (NumPy's zip of arrays, read without pickle) holds:

- ``meta``: one JSON text: the format name and version, the pickplace version that wrote it, what ran
  (``episode`` or ``task``), the seed, the full :class:`~pickplace.task.episode.EpisodeConfig` (to rebuild the
  scene), the result's figures (:meth:`EpisodeResult.to_dict`, without the config), and the names and times of
  the telemetry's phases, joint segments, planned paths and grasp choices;
- ``tel.*``: the :class:`~pickplace.task.telemetry.Telemetry` arrays (per step, per video frame);
- ``seg.N.*``, ``plan.N.*``, ``grasp.N.*``: the arrays of each joint segment, planned path and grasp choice.

:func:`load_episode` refuses anything else with an :class:`EpisodeFileError` that says what the file is and what
was expected: not an ``.npz``, an ``.npz`` of something else, or another version of the format.
"""

from __future__ import annotations

import json
import logging
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pickplace import __version__
from pickplace.errors import ConfigError, PickPlaceError
from pickplace.robot.model import Robot, build
from pickplace.task.episode import EpisodeConfig
from pickplace.task.faults import apply_model_faults
from pickplace.task.telemetry import GraspChoice, JointSegment, PlannedPath, Telemetry

if TYPE_CHECKING:
    from pickplace.task.episode import EpisodeResult
    from pickplace.task.task_episode import TaskResult

log = logging.getLogger(__name__)

#: The ``format`` every episode file names in its ``meta``.
EPISODE_FORMAT = "pickplace-episode"
#: The version of the layout this module writes and reads; raise it when the layout changes.
EPISODE_VERSION = 1

#: The telemetry's per-step and per-frame arrays, stored as ``tel.<name>``.
_TEL_ARRAYS = ("t_s", "phase", "q", "tcp_pos_m", "object_pos_m", "pad_force_n", "frame_t_s", "frame_qpos",
               "goal_pos_m", "frame_mocap", "frame_pad_force_n", "frame_pad_point_m")


class EpisodeFileError(ConfigError):
    """A file that is not an episode file this version of pickplace reads (the message says what it is)."""

    def __init__(self, path: str | Path, allowed: str) -> None:
        super().__init__("episode file", str(path), allowed)


@dataclass(frozen=True, eq=False)
class SavedEpisode:
    """An episode or task read back from its file.

    Attributes:
        kind: ``episode`` (one pick and place) or ``task`` (several objects).
        seed: The seed it ran with.
        config: The configuration it ran with (the scene is rebuilt from it).
        result: The result's figures as plain data (``EpisodeResult.to_dict()`` or ``TaskResult.to_dict()``,
            without the config).
        telemetry: What was recorded while it ran.
        written_by: The pickplace version that wrote the file.
        path: The file it was read from ("" if it was not read from one).
    """

    kind: str
    seed: int
    config: EpisodeConfig
    result: dict[str, Any]
    telemetry: Telemetry
    written_by: str
    path: str = ""

    @property
    def success(self) -> bool:
        """Whether the episode (or task) succeeded."""
        return bool(self.result.get("success"))

    @property
    def duration_s(self) -> float:
        """Simulated time recorded (s)."""
        t = self.telemetry.t_s
        return float(t[-1]) if t.size else 0.0

    def build_robot(self) -> Robot:
        """The models of the scene it ran in, the configured model faults applied (a turned gripper shows).

        Raises:
            EpisodeFileError: the rebuilt scene does not match the recorded frames (another version's scene).
        """
        robot = build(self.config.scene)
        apply_model_faults(robot, self.config.faults)
        tel = self.telemetry
        if tel.frame_qpos.shape[1] != robot.mj.nq or tel.frame_mocap.shape[1] not in (0, robot.mj.nmocap):
            raise EpisodeFileError(
                self.path, f"its frames have {tel.frame_qpos.shape[1]} qpos values and {tel.frame_mocap.shape[1]} "
                f"mocap bodies, but the scene rebuilt from its config has {robot.mj.nq} and {robot.mj.nmocap} "
                f"(written by pickplace {self.written_by}; record it again with this version)")
        return robot


def episode_of(result: EpisodeResult | TaskResult) -> SavedEpisode:
    """A recorded result as a :class:`SavedEpisode` (as :func:`load_episode` would read it back).

    Raises:
        ConfigError: the result has no telemetry (it was not recorded).
    """
    if result.telemetry is None:
        raise ConfigError("result.telemetry", None, "must be recorded: run with record=True")
    data = result.to_dict()
    data.pop("config", None)
    return SavedEpisode("task" if "picks" in data else "episode", int(result.seed), result.config, data,
                        result.telemetry, __version__)


def save_episode(path: str | Path, result: EpisodeResult | TaskResult) -> Path:
    """Write a recorded episode or task to ``path`` (``.npz`` is appended if missing).

    Args:
        path: The file to write (its directory is created).
        result: A result run with ``record=True`` (:func:`~pickplace.task.episode.run_episode` or
            :func:`~pickplace.task.task_episode.run_task`).

    Returns:
        The path written.

    Raises:
        ConfigError: the result has no telemetry (it was not recorded).
    """
    episode = episode_of(result)
    tel = episode.telemetry
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    meta = {
        "format": EPISODE_FORMAT,
        "version": EPISODE_VERSION,
        "written_by": __version__,
        "kind": episode.kind,
        "seed": episode.seed,
        "config": episode.config.to_dict(),
        "result": episode.result,
        "phase_names": list(tel.phase_names),
        "segments": [s.phase for s in tel.joint_segments],
        "plans": [{"name": p.name, "t_s": p.t_s, "duration_s": p.duration_s} for p in tel.plans],
        "grasps": [{"t_s": g.t_s, "object_name": g.object_name, "approach": list(g.approach), "chosen": g.chosen}
                   for g in tel.grasps],
    }
    arrays: dict[str, np.ndarray] = {"meta": np.array(json.dumps(meta))}
    arrays.update({f"tel.{name}": np.asarray(getattr(tel, name)) for name in _TEL_ARRAYS})
    for i, s in enumerate(tel.joint_segments):
        arrays.update({f"seg.{i}.t_s": s.t_s, f"seg.{i}.q": s.q, f"seg.{i}.q_ref": s.q_ref})
    for i, p in enumerate(tel.plans):
        arrays[f"plan.{i}.tcp_m"] = p.tcp_m
    for i, g in enumerate(tel.grasps):
        arrays.update({f"grasp.{i}.T_world_object": g.T_world_object, f"grasp.{i}.T_world_tcp": g.T_world_tcp,
                       f"grasp.{i}.width_m": g.width_m, f"grasp.{i}.T_world_chosen": g.T_world_chosen})
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)
    log.info("wrote the %s to %s (%d frames)", meta["kind"], path, tel.frame_t_s.size)
    return path


def load_episode(path: str | Path) -> SavedEpisode:
    """Read an episode file written by :func:`save_episode`.

    Raises:
        EpisodeFileError: no such file, not an ``.npz``, not an episode file, or another version of the format;
            the message says which and what to do.
    """
    path = Path(path)
    expected = f"must be an episode file written by `pickplace run --save EP.npz` ({EPISODE_FORMAT} version " \
               f"{EPISODE_VERSION})"
    if not path.is_file():
        raise EpisodeFileError(path, f"no such file; {expected}")
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise EpisodeFileError(path, f"not an .npz file ({type(exc).__name__}); {expected}") from None
    try:
        meta = json.loads(str(arrays["meta"][()]))
        if not isinstance(meta, dict):
            raise TypeError
    except (KeyError, ValueError, TypeError):
        raise EpisodeFileError(path, f"an .npz of something else (no episode metadata); {expected}") from None
    if meta.get("format") != EPISODE_FORMAT:
        raise EpisodeFileError(path, f"its format is {meta.get('format')!r}; {expected}")
    version = meta.get("version")
    if version != EPISODE_VERSION:
        newer = isinstance(version, int) and version > EPISODE_VERSION
        why = (f"written by a newer pickplace ({meta.get('written_by')}, format version {version}): upgrade pickplace"
               if newer else f"an older episode format (version {version}, pickplace {meta.get('written_by')}) that "
                             "this version no longer reads: record it again with `pickplace run --save`")
        raise EpisodeFileError(path, f"{why}; {expected}")
    try:
        config = EpisodeConfig.from_dict(meta["config"])
        tel = _telemetry(meta, arrays)
        return SavedEpisode(str(meta["kind"]), int(meta["seed"]), config, dict(meta["result"]), tel,
                            str(meta.get("written_by", "?")), str(path))
    except ConfigError as exc:
        raise EpisodeFileError(path, f"its config no longer loads ({exc}); {expected}") from None
    except (KeyError, ValueError, TypeError, IndexError, PickPlaceError) as exc:
        raise EpisodeFileError(path, f"damaged ({type(exc).__name__}: {exc}); {expected}") from None


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a)
    a.setflags(write=False)
    return a


def _telemetry(meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> Telemetry:
    """The :class:`Telemetry` of an episode file's arrays and metadata."""
    tel = {name: _frozen(arrays[f"tel.{name}"]) for name in _TEL_ARRAYS}
    segments = tuple(JointSegment(phase, _frozen(arrays[f"seg.{i}.t_s"]), _frozen(arrays[f"seg.{i}.q"]),
                                  _frozen(arrays[f"seg.{i}.q_ref"])) for i, phase in enumerate(meta["segments"]))
    plans = tuple(PlannedPath(str(p["name"]), float(p["t_s"]), float(p["duration_s"]),
                              _frozen(arrays[f"plan.{i}.tcp_m"])) for i, p in enumerate(meta["plans"]))
    grasps = tuple(GraspChoice(float(g["t_s"]), str(g["object_name"]), _frozen(arrays[f"grasp.{i}.T_world_object"]),
                               _frozen(arrays[f"grasp.{i}.T_world_tcp"]), _frozen(arrays[f"grasp.{i}.width_m"]),
                               tuple(str(a) for a in g["approach"]), int(g["chosen"]),
                               _frozen(arrays[f"grasp.{i}.T_world_chosen"])) for i, g in enumerate(meta["grasps"]))
    nq = tel["frame_qpos"].shape[1] if tel["frame_qpos"].ndim == 2 else -1
    if nq < 0 or tel["frame_t_s"].shape[0] != tel["frame_qpos"].shape[0]:
        raise ValueError(f"frame_t_s {tel['frame_t_s'].shape} and frame_qpos {tel['frame_qpos'].shape} disagree")
    return Telemetry(tel["t_s"], tel["phase"], tuple(str(n) for n in meta["phase_names"]), tel["q"],
                     tel["tcp_pos_m"], tel["object_pos_m"], tel["pad_force_n"], segments, tel["frame_t_s"],
                     tel["frame_qpos"], tel["goal_pos_m"], tel["frame_mocap"], tel["frame_pad_force_n"],
                     tel["frame_pad_point_m"], plans, grasps)


__all__ = ["EPISODE_FORMAT", "EPISODE_VERSION", "EpisodeFileError", "SavedEpisode", "episode_of", "load_episode",
           "save_episode"]
