"""Demonstrations as a dataset: a campaign's trials acted by the expert through the low-level environment, written
as one `Minari <https://minari.farama.org>`_ dataset (``pip install 'pickplace[dataset]'``).

Each trial of the campaign (its drawn configuration and seed, :mod:`pickplace.eval.campaign`) runs in a fresh
``pickplace/PickPlaceLowLevel-v0`` in joint mode (:data:`ENV_ID`, :meth:`RecordConfig.env_kwargs`), reset with the
trial's seed and ``options={"config": <the trial's EpisodeConfig as JSON>}``, and acted by the project's stack
(:func:`~pickplace.envs.expert.demonstrate`). The worker sends the :class:`~pickplace.envs.expert.Demonstration`
back with the trial's results line; the parent writes it to ``OUT/demos/trial_0007.npz`` (before the trial's line
in ``results.jsonl``, so a resumed campaign keeps it) and, once every trial is done, builds the dataset from the
parts of trials 0 .. N-1 with :func:`minari.create_dataset_from_buffers` in ``DIR/<dataset_id>/data`` (HDF5).

What the dataset holds, per episode (``minari.EpisodeData``): the observations (the environment's ``Dict``,
``N + 1`` steps), the actions ``(dq1..dq6, grip)`` (``N``, float32 in ``[-1, 1]``, at the environment's control
rate), the rewards (sparse: 1.0 at the step the object rests placed), terminations and truncations, and ``infos``
per step: ``phase`` (the expert's phase: ``RESET`` then ``EXEC_APPROACH`` ... ``RELEASE``), ``sim_time_s``,
``success``, ``released``, the place errors, and ``failure_phase``, ``failure_kind``, ``failure_reason`` (empty
strings until the step that failed). Per episode (``dataset.storage.get_episode_metadata``): ``seed``, ``options``
(the config), ``trial``, ``success``, the failure's phase, kind and reason, ``grasp_approach``, ``sim_time_s``. The
dataset's metadata: the environment's spec (``dataset.recover_environment()`` rebuilds it), and under
``pickplace``: the expert's settings, the campaign's seed and randomization, and which trials were dropped or not
recorded.

:func:`load` opens it by directory; ``MINARI_DATASETS_PATH=DIR`` and ``minari.load_dataset(dataset_id)`` does the
same. :func:`replay_episode` replays a stored episode's actions in the recovered environment from its seed and
options and compares every observation, reward and the outcome.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.metadata
import json
import logging
import math
import os
import re
import shutil
import warnings
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from pickplace.envs.expert import Demonstration, ExpertConfig, demonstrate, replay
from pickplace.errors import ConfigError
from pickplace.eval.campaign import (
    SIDECAR_KEY,
    CampaignConfig,
    CampaignError,
    CampaignProgress,
    CampaignRun,
    run_campaign,
)
from pickplace.task.episode import EpisodeConfig, EpisodeResult
from pickplace.world.checks import check_int, check_range

log = logging.getLogger(__name__)

#: The environment the demonstrations are episodes of.
ENV_ID = "pickplace/PickPlaceLowLevel-v0"
#: The dataset's id by default (Minari's ``namespace/name-vN``).
DATASET_ID = "pickplace/expert-v0"
#: What to do with failed episodes: keep them (labelled) or leave them out of the dataset.
FAILURES = ("keep", "drop")
#: The per-trial demonstrations inside the campaign's output directory.
DEMOS_DIR = "demos"
#: A dataset id: Minari's ``(namespace/)name-vN`` (its ``minari.dataset.minari_dataset.DATASET_ID_RE``, with the
#: version required).
DATASET_ID_RE = re.compile(r"(?:[-_\w][-_\w/]*[-_\w]+/)?[-_\w]+?-v\d+")
#: Install hint for a missing Minari.
INSTALL_HINT = "pip install 'pickplace[dataset]'"


def _minari() -> Any:
    """The ``minari`` module, or :class:`CampaignError` with the install hint."""
    try:
        import minari
    except ImportError as exc:
        raise CampaignError(f"recording a dataset needs Minari and h5py ({exc}): {INSTALL_HINT}") from None
    return minari


# --------------------------------------------------------------------------- #
# what to record
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class RecordConfig:
    """Where and how a campaign is recorded.

    Attributes:
        dataset_dir: The datasets' root directory (Minari's ``MINARI_DATASETS_PATH``): the dataset is written to
            ``dataset_dir/<dataset_id>/data``.
        dataset_id: The dataset's id, ``namespace/name-vN`` (Minari's syntax).
        failures: ``keep`` the failed episodes (labelled with their phase, kind and reason) or ``drop`` them.
        control_rate_hz: The environment's control rate (Hz): 20, 25, 40 or 50 in the ideal profile.
        max_joint_step_rad: The environment's largest joint increment per step (rad), up to 0.3.
        max_steps: Steps before the environment truncates an episode.
        expert: How the expert moves.
    """

    dataset_dir: Path
    dataset_id: str = DATASET_ID
    failures: Literal["keep", "drop"] = "keep"
    control_rate_hz: float = 20.0
    max_joint_step_rad: float = 0.3
    max_steps: int = 1000
    expert: ExpertConfig = field(default_factory=ExpertConfig)

    def __post_init__(self) -> None:
        object.__setattr__(self, "dataset_dir", Path(self.dataset_dir))
        if self.failures not in FAILURES:
            raise ConfigError("record.failures", self.failures, f"must be one of {', '.join(FAILURES)}")
        if not isinstance(self.dataset_id, str) or not DATASET_ID_RE.fullmatch(self.dataset_id):
            raise ConfigError("record.dataset_id", self.dataset_id,
                              "must be namespace/name-vN (letters, digits, _ and -; e.g. pickplace/expert-v0)")
        object.__setattr__(self, "control_rate_hz", check_range("record.control_rate_hz", self.control_rate_hz,
                                                                20.0, 50.0, unit="Hz"))
        object.__setattr__(self, "max_joint_step_rad", check_range(
            "record.max_joint_step_rad", self.max_joint_step_rad, 0.0, 0.3, lo_open=True, unit="rad"))
        object.__setattr__(self, "max_steps", check_int("record.max_steps", self.max_steps, 2, 100_000))
        if not isinstance(self.expert, ExpertConfig):
            raise ConfigError("record.expert", self.expert, "must be an ExpertConfig")

    @property
    def path(self) -> Path:
        """The dataset's directory (its ``data`` folder is inside)."""
        return self.dataset_dir / self.dataset_id

    def env_kwargs(self, profile: str) -> dict[str, Any]:
        """The environment's constructor arguments (stored in the dataset's environment spec)."""
        return {"action_mode": "joint", "control_rate_hz": float(self.control_rate_hz),
                "max_joint_step_rad": float(self.max_joint_step_rad), "max_steps": int(self.max_steps),
                "randomize": False, "profile": profile}


def episode_options(config: EpisodeConfig) -> dict[str, str]:
    """The reset options that run an episode with ``config`` (its ``to_dict()`` as JSON)."""
    return {"config": json.dumps(config.to_dict(), sort_keys=True)}


# --------------------------------------------------------------------------- #
# the trials (in the workers)
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class DemoResult:
    """A recorded trial: its figures as a campaign results line, and the demonstration as its sidecar.

    Attributes:
        demo: The demonstration.
        config: The trial's configuration.
    """

    demo: Demonstration
    config: EpisodeConfig

    def to_dict(self) -> dict[str, Any]:
        """The results line's fields (those of ``EpisodeResult`` the expert measures, None for the others) and
        the demonstration under :data:`~pickplace.eval.campaign.spec.SIDECAR_KEY`."""
        d = self.demo
        out: dict[str, Any] = {f.name: None for f in dataclasses.fields(EpisodeResult) if f.name != "telemetry"}
        last = {k: v[-1] for k, v in d.infos.items()}

        def finite(value: Any) -> float | None:
            return float(value) if math.isfinite(float(value)) else None

        out.update(success=d.success, failure_phase=d.failure_phase, failure_reason=d.failure_reason,
                   failure_kind=d.failure_kind, seed=d.seed, cycle_time_s=d.sim_time_s, wall_time_s=d.wall_time_s,
                   real_time_factor=d.sim_time_s / d.wall_time_s if d.wall_time_s > 0 else None,
                   place_error_xy_m=finite(last["place_error_xy_m"]), place_error_z_m=finite(last["place_error_z_m"]),
                   place_error_yaw_rad=finite(last["place_error_yaw_rad"]), grasp_approach=d.grasp_approach,
                   retries=0, recoveries=[], config=self.config.to_dict(), steps=d.steps,
                   expert_plan_time_s=d.plan_time_s)
        out[SIDECAR_KEY] = d
        return out


@dataclass(frozen=True)
class DemoTrial:
    """The campaign's trial function when recording (picklable): the trial's episode acted by the expert in a fresh
    environment.

    Attributes:
        env_kwargs: The environment's constructor arguments (:meth:`RecordConfig.env_kwargs`).
        expert: How the expert moves.
    """

    env_kwargs: dict[str, Any]
    expert: ExpertConfig = field(default_factory=ExpertConfig)

    def __call__(self, config: EpisodeConfig, seed: int) -> DemoResult:
        import gymnasium as gym

        import pickplace.envs  # noqa: F401  (registers the ids)

        env = gym.make(ENV_ID, **self.env_kwargs)
        try:
            demo = demonstrate(env, seed, episode_options(config), self.expert)
        finally:
            env.close()
        return DemoResult(demo, config)


# --------------------------------------------------------------------------- #
# the per-trial parts (in the parent)
# --------------------------------------------------------------------------- #

_META_FIELDS = ("seed", "options", "success", "failure_phase", "failure_kind", "failure_reason", "grasp_approach",
                "plan_time_s", "wall_time_s")


def part_path(out_dir: str | Path, trial: int) -> Path:
    """Where trial ``trial``'s demonstration is kept in the campaign's output directory."""
    return Path(out_dir) / DEMOS_DIR / f"trial_{trial:04d}.npz"


def save_part(path: Path, demo: Demonstration) -> None:
    """Write a demonstration to ``path`` (``.npz``, no pickles), atomically."""
    arrays: dict[str, np.ndarray] = {f"obs/{k}": v for k, v in demo.observations.items()}
    arrays.update({f"info/{k}": v for k, v in demo.infos.items()})
    arrays.update(actions=demo.actions, rewards=demo.rewards, terminations=demo.terminations,
                  truncations=demo.truncations)
    meta = {name: getattr(demo, name) for name in _META_FIELDS}
    arrays["meta"] = np.array(json.dumps(meta))
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def load_part(path: Path) -> Demonstration:
    """Read a demonstration written by :func:`save_part`."""
    with np.load(path, allow_pickle=False) as z:
        obs = {k[4:]: z[k] for k in z.files if k.startswith("obs/")}
        infos = {k[5:]: z[k] for k in z.files if k.startswith("info/")}
        meta = json.loads(str(z["meta"]))
        return Demonstration(observations=obs, infos=infos, actions=z["actions"], rewards=z["rewards"],
                             terminations=z["terminations"], truncations=z["truncations"], **meta)


# --------------------------------------------------------------------------- #
# the dataset
# --------------------------------------------------------------------------- #


@contextlib.contextmanager
def _datasets_path(root: Path) -> Iterator[None]:
    """Minari's dataset root set to ``root`` while writing (its creation functions read the environment)."""
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root.resolve())  # Minari's size count breaks on a relative root
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def _requirements() -> list[str]:
    """The packages an episode's replay depends on, as installed (a replay on other versions may differ)."""
    out = []
    for name in ("pickplace", "mujoco", "gymnasium"):
        with contextlib.suppress(importlib.metadata.PackageNotFoundError):
            out.append(f"{name}=={importlib.metadata.version(name)}")
    return out


def _storable(infos: dict[str, np.ndarray]) -> dict[str, Any]:
    """The per-step infos as HDF5 writes them: text as lists of ``str`` (h5py has no conversion of numpy's
    unicode arrays)."""
    return {k: [str(x) for x in v] if v.dtype.kind == "U" else v for k, v in infos.items()}


def _episode_metadata(demo: Demonstration, trial: int) -> dict[str, Any]:
    """HDF5-storable attributes of one episode (no None: empty strings)."""
    return {"trial": int(trial), "success": bool(demo.success), "failure_phase": demo.failure_phase or "",
            "failure_kind": demo.failure_kind or "", "failure_reason": demo.failure_reason or "",
            "grasp_approach": demo.grasp_approach or "", "sim_time_s": float(demo.sim_time_s),
            "steps": int(demo.steps)}


@dataclass(frozen=True)
class DatasetWritten:
    """What :func:`write_dataset` wrote.

    Attributes:
        path: The dataset's directory (``DIR/<dataset_id>``).
        dataset_id: Its id.
        episodes: Episodes in it.
        steps: Steps in it.
        successes: Successful episodes in it.
        trials: The trial index of each episode, in order.
        dropped: Trials left out because they failed (``failures="drop"``).
        missing: Trials with no demonstration (a worker crashed or timed out, or the campaign ran without
            recording).
    """

    path: Path
    dataset_id: str
    episodes: int
    steps: int
    successes: int
    trials: tuple[int, ...]
    dropped: tuple[int, ...]
    missing: tuple[int, ...]


def write_dataset(out_dir: str | Path, record: RecordConfig, campaign: CampaignConfig,
                  replace: bool = False) -> DatasetWritten:
    """Build the dataset from the demonstrations of trials ``0 .. campaign.trials - 1`` in ``out_dir``.

    Args:
        out_dir: The campaign's output directory (its ``demos/``).
        record: Where and how.
        campaign: The campaign (its trials, seed, randomization and profile go into the metadata).
        replace: Replace a dataset already at the path (a resumed campaign rebuilds its dataset); otherwise that
            is an error.

    Raises:
        ConfigError: the dataset exists and ``replace`` is False, or no episode is left to write.
        CampaignError: Minari is not installed.
    """
    minari = _minari()
    from minari.data_collector import EpisodeBuffer

    if record.path.exists():
        if not replace:
            raise ConfigError("record", str(record.dataset_dir), f"already holds the dataset {record.dataset_id}: "
                                                                 "choose another directory or id, or delete it")
        shutil.rmtree(record.path)
    buffers, metas, trials, dropped, missing = [], [], [], [], []
    steps = successes = 0
    for i in range(campaign.trials):
        path = part_path(out_dir, i)
        if not path.exists():
            missing.append(i)
            continue
        demo = load_part(path)
        if record.failures == "drop" and not demo.success:
            dropped.append(i)
            continue
        buffers.append(EpisodeBuffer(id=len(buffers), seed=demo.seed, options=demo.options,
                                     observations=demo.observations, actions=demo.actions,
                                     rewards=demo.rewards.tolist(), terminations=demo.terminations.tolist(),
                                     truncations=demo.truncations.tolist(), infos=_storable(demo.infos)))
        metas.append(_episode_metadata(demo, i))
        trials.append(i)
        steps += demo.steps
        successes += demo.success
    if not buffers:
        raise ConfigError("record", str(record.dataset_dir),
                          f"has no episode to write: of {campaign.trials} trials {len(dropped)} failed (dropped) and "
                          f"{len(missing)} have no demonstration")
    import gymnasium as gym

    import pickplace.envs  # noqa: F401  (registers the ids)

    env = gym.make(ENV_ID, **record.env_kwargs(campaign.base.profile.name))
    description = (f"pickplace's expert (grasp synthesis, IK, RRT*, TOPP-RA, the pick-and-place phases and their "
                   f"checks) acting {ENV_ID} in joint mode at {record.control_rate_hz:g} Hz: {len(buffers)} "
                   f"episodes of a {campaign.trials}-trial campaign (seed {campaign.seed}), failed episodes "
                   f"{'kept, labelled' if record.failures == 'keep' else 'dropped'}. Replay an episode with "
                   "env.reset(seed=its seed, options=its options) and its actions.")
    try:
        record.dataset_dir.mkdir(parents=True, exist_ok=True)
        with _datasets_path(record.dataset_dir), warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*(code_permalink|author_email).*", category=UserWarning)
            dataset = minari.create_dataset_from_buffers(
                record.dataset_id, buffers, env=env, eval_env=env.spec, algorithm_name="pickplace expert",
                author="pickplace", description=description, data_format="hdf5", requirements=_requirements())
        dataset.storage.update_episode_metadata(metas, range(len(metas)))
        dataset.storage.update_metadata({"pickplace": {
            "env_id": ENV_ID, "env_kwargs": record.env_kwargs(campaign.base.profile.name),
            "expert": dataclasses.asdict(record.expert), "failures": record.failures,
            "campaign": {"trials": campaign.trials, "seed": campaign.seed,
                         "randomization": campaign.randomization.to_dict()},
            "trials": trials, "dropped": dropped, "missing": missing}})
    except BaseException:
        shutil.rmtree(record.path, ignore_errors=True)  # no half-written dataset
        raise
    finally:
        env.close()
    log.info("dataset %s: %d episodes (%d steps, %d successes) in %s; %d dropped, %d missing", record.dataset_id,
             len(buffers), steps, successes, record.path, len(dropped), len(missing))
    return DatasetWritten(record.path, record.dataset_id, len(buffers), steps, successes, tuple(trials),
                          tuple(dropped), tuple(missing))


@dataclass(frozen=True)
class RecordedCampaign:
    """What :func:`record_campaign` did: the campaign's run and the dataset written."""

    run: CampaignRun
    dataset: DatasetWritten


def record_campaign(campaign: CampaignConfig, out_dir: str | Path, record: RecordConfig, *, resume: bool = False,
                    backend: Literal["local", "ray"] = "local", ray_address: str | None = None,
                    on_progress: Callable[[CampaignProgress], None] | None = None) -> RecordedCampaign:
    """Run a campaign whose trials the expert acts through the low-level environment, and write them as one
    Minari dataset (module docstring).

    Args:
        campaign: The campaign (single-object, ideal profile).
        out_dir: The campaign's output directory (``results.jsonl``, ``summary.json``, ``demos/`` ...).
        record: Where the dataset goes and how it is recorded.
        resume: Complete the campaign in ``out_dir`` (its recorded trials keep their demonstrations) and rebuild
            the dataset.
        backend, ray_address, on_progress: As :func:`~pickplace.eval.campaign.run_campaign`'s.

    Raises:
        ConfigError: the campaign is a task (several objects) or in the realistic profile, the dataset exists
            (without ``resume``), or a recording setting is invalid (the environment names it).
        CampaignError: Minari is not installed, or the campaign cannot run.
    """
    _minari()
    if campaign.base.task is not None:
        raise ConfigError("record", str(record.dataset_dir), "records single-object campaigns only (the low-level "
                                                            "environment has one object): drop --task")
    if campaign.base.profile.name != "ideal":
        raise ConfigError("profile", campaign.base.profile.name, "must be 'ideal' to record: in the realistic profile "
                                                                 "the low-level environment's object pose is the "
                                                                 "camera's fit of the object resting on the table, "
                                                                 "which does not follow it once it is held")
    if record.path.exists() and not resume:
        raise ConfigError("record", str(record.dataset_dir), f"already holds the dataset {record.dataset_id}: "
                                                             "choose another directory or id, or delete it")
    import gymnasium as gym

    import pickplace.envs  # noqa: F401  (registers the ids)

    kwargs = record.env_kwargs(campaign.base.profile.name)
    gym.make(ENV_ID, **kwargs).close()  # a rate the profile's loop cannot run fails here, naming the argument

    def keep(trial: int, demo: Any) -> None:
        if isinstance(demo, Demonstration):
            save_part(part_path(out_dir, trial), demo)

    run = run_campaign(campaign, out_dir, resume=resume, backend=backend, ray_address=ray_address,
                       on_progress=on_progress, run_fn=DemoTrial(kwargs, record.expert), on_sidecar=keep)
    return RecordedCampaign(run, write_dataset(out_dir, record, campaign, replace=resume))


# --------------------------------------------------------------------------- #
# reading it back
# --------------------------------------------------------------------------- #


def load(dataset_dir: str | Path, dataset_id: str = DATASET_ID) -> Any:
    """The ``minari.MinariDataset`` at ``dataset_dir/<dataset_id>`` (as ``minari.load_dataset(dataset_id)`` with
    ``MINARI_DATASETS_PATH=dataset_dir``).

    Raises:
        ConfigError: there is no dataset there.
        CampaignError: Minari is not installed.
    """
    minari = _minari()
    data = Path(dataset_dir) / dataset_id / "data"
    if not (data / "metadata.json").exists():
        raise ConfigError("dataset", str(dataset_dir), f"holds no dataset {dataset_id} (no {data}/metadata.json)")
    return minari.MinariDataset(data)


def text(value: Any) -> str:
    """A string stored in the dataset as text (HDF5 gives bytes back)."""
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def episode_metadata(dataset: Any, index: int) -> dict[str, Any]:
    """Episode ``index``'s metadata: ``seed``, ``options`` (the reset options), ``trial``, ``success``, the
    failure's phase, kind and reason, ``grasp_approach``, ``sim_time_s``, ``steps``."""
    return next(iter(dataset.storage.get_episode_metadata([int(dataset.episode_indices[index])])))


@dataclass(frozen=True)
class ReplayCheck:
    """A stored episode replayed from its seed and options with its actions.

    Attributes:
        index: The episode's index in the dataset.
        steps: Steps stored / steps replayed.
        identical_observations: Every observation of every step equal, bit for bit.
        max_difference: The largest absolute difference over every observation entry (0 when identical).
        same_rewards: The rewards equal.
        same_terminations: The environment ended the episode at the same step (or neither did).
        success_stored: The stored outcome.
        success_replayed: The replay's outcome (the environment's ``success``).
        failure_stored: The stored failure's kind and phase (``kind in PHASE``), or None.
        failure_replayed: The environment's failure kind in the replay, or None (a failure the expert's check
            found is not the environment's: the replay reproduces it through the identical observations).
    """

    index: int
    steps: tuple[int, int]
    identical_observations: bool
    max_difference: float
    same_rewards: bool
    same_terminations: bool
    success_stored: bool
    success_replayed: bool
    failure_stored: str | None
    failure_replayed: str | None

    @property
    def reproduced(self) -> bool:
        """The replay is the stored episode: every step, the outcome."""
        return (self.steps[0] == self.steps[1] and self.identical_observations and self.same_rewards
                and self.same_terminations and self.success_stored == self.success_replayed)


def replay_episode(dataset: Any, index: int, env: Any = None) -> ReplayCheck:
    """Replay episode ``index`` of ``dataset`` in its environment (``dataset.recover_environment()`` unless
    ``env`` is given) from its seed and options, with its actions, and compare.

    Returns:
        The :class:`ReplayCheck`.
    """
    meta = episode_metadata(dataset, index)
    ep = dataset[index]
    own = env is None
    env = dataset.recover_environment() if own else env
    try:
        obs, rewards, terms, _, info = replay(env, int(meta["seed"]), ep.actions, meta.get("options"))
    finally:
        if own:
            env.close()
    n_stored, n_replayed = len(ep.actions), len(rewards)
    n = min(n_stored, n_replayed)
    diff = 0.0
    identical = n_stored == n_replayed
    for key, stored in ep.observations.items():
        a, b = np.asarray(stored)[:n + 1], np.asarray(obs[key])[:n + 1]
        if a.shape != b.shape:
            identical, diff = False, math.inf
            continue
        identical &= bool(np.array_equal(a, b))
        if a.size:
            diff = max(diff, float(np.max(np.abs(a.astype(np.float64) - b.astype(np.float64)))))
    kind, phase = text(ep.infos["failure_kind"][-1]), text(meta.get("failure_phase", ""))
    return ReplayCheck(
        index=index, steps=(n_stored, n_replayed), identical_observations=identical, max_difference=diff,
        same_rewards=bool(np.array_equal(np.asarray(ep.rewards)[:n], rewards[:n])),
        same_terminations=bool(np.array_equal(np.asarray(ep.terminations)[:n], terms[:n])),
        success_stored=bool(meta.get("success")), success_replayed=bool(info.get("success")),
        failure_stored=f"{kind} in {phase}" if kind else None,
        failure_replayed=str(info["failure_kind"]) if info.get("failure_kind") else None)


@dataclass(frozen=True)
class DatasetSummary:
    """The figures of a recorded dataset.

    Attributes:
        dataset_id: Its id.
        path: Its directory.
        episodes: Episodes.
        steps: Steps.
        successes: Successful episodes.
        failures: ``(phase, kind, count)`` of the failed episodes, most frequent first.
        env_kwargs: The environment's constructor arguments.
        control_rate_hz: Steps per simulated second.
        mean_steps: Mean steps per episode.
        dropped: Trials left out because they failed.
        missing: Trials with no demonstration.
    """

    dataset_id: str
    path: str
    episodes: int
    steps: int
    successes: int
    failures: tuple[tuple[str, str, int], ...]
    env_kwargs: dict[str, Any]
    control_rate_hz: float
    mean_steps: float
    dropped: tuple[int, ...]
    missing: tuple[int, ...]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data."""
        out = dataclasses.asdict(self)
        out["failures"] = [{"phase": p, "kind": k, "count": c} for p, k, c in self.failures]
        return out


def summarize_dataset(dataset: Any) -> DatasetSummary:
    """The figures of ``dataset`` (:func:`load`), from its metadata."""
    metas = list(dataset.storage.get_episode_metadata(dataset.episode_indices))
    raw = dataset.storage.metadata
    own = raw.get("pickplace", {})
    failures = Counter((text(m.get("failure_phase", "")), text(m.get("failure_kind", "")))
                       for m in metas if not m.get("success"))
    kwargs = own.get("env_kwargs", dataset.env_spec.kwargs if dataset.env_spec is not None else {})
    steps = int(sum(int(m["total_steps"]) for m in metas))
    return DatasetSummary(
        dataset_id=dataset.id, path=str(Path(dataset.storage.data_path).parent), episodes=len(metas), steps=steps,
        successes=sum(bool(m.get("success")) for m in metas),
        failures=tuple((p, k, c) for (p, k), c in failures.most_common()), env_kwargs=dict(kwargs),
        control_rate_hz=float(kwargs.get("control_rate_hz", math.nan)),
        mean_steps=steps / len(metas) if metas else math.nan, dropped=tuple(own.get("dropped", ())),
        missing=tuple(own.get("missing", ())))


__all__ = ["DATASET_ID", "DEMOS_DIR", "ENV_ID", "FAILURES", "DatasetSummary", "DatasetWritten", "DemoResult",
           "DemoTrial", "RecordConfig", "RecordedCampaign", "ReplayCheck", "episode_metadata", "episode_options",
           "load", "load_part", "part_path", "record_campaign", "replay_episode", "save_part", "summarize_dataset",
           "text", "write_dataset"]
