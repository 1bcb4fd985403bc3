"""A campaign's output directory: the results file, the trial TOML files, and the recorded campaign.

* ``campaign.json``: the base config, the randomization, the campaign seed and the number of trials;
* ``results.jsonl``: one line per finished trial, ``{"trial": i, "params": {...}, **EpisodeResult.to_dict()}``,
  appended by the parent process only (one writer, holding an ``flock`` on the file so that a second campaign
  cannot write into the same directory), with one ``write`` and an ``fsync`` as soon as the trial finishes;
* ``trials/trial_0007.toml``: the full episode config of each failed trial (with the command reproducing it);
* ``summary.json``: the :class:`~pickplace.eval.campaign.summary.CampaignSummary`.

A last line cut short by a kill is ignored when reading and cut before appending, so a resumed campaign never
glues two lines together.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pickplace.errors import ConfigError
from pickplace.eval.campaign.spec import CampaignConfig, RandomizationSpec
from pickplace.task.episode import EpisodeConfig, read_toml

log = logging.getLogger(__name__)

#: File names inside a campaign's output directory.
RESULTS_FILE = "results.jsonl"
SUMMARY_FILE = "summary.json"
CAMPAIGN_FILE = "campaign.json"
TRIALS_DIR = "trials"
#: EpisodeResult fields that measure wall-clock time: they differ between two runs of the same trial.
WALL_TIME_FIELDS = ("wall_time_s", "real_time_factor", "plan_time_s", "retime_time_s")

#: Version of the layout of ``campaign.json``.
FORMAT_VERSION = 1


# --------------------------------------------------------------------------- #
# records and persistence
# --------------------------------------------------------------------------- #


@dataclass(frozen=True)
class TrialRecord:
    """One line of ``results.jsonl``.

    Attributes:
        trial: Trial index.
        params: The sampled parameters.
        result: ``EpisodeResult.to_dict()`` (for a ``WORKER`` failure: the same keys, None where nothing was
            measured).
    """

    trial: int
    params: dict[str, Any]
    result: dict[str, Any]

    @classmethod
    def from_line(cls, line: Mapping[str, Any]) -> TrialRecord:
        """Parse one decoded JSON line."""
        data = dict(line)
        trial = data.pop("trial")
        params = data.pop("params")
        if not isinstance(trial, int) or not isinstance(params, dict) or "success" not in data:
            raise ValueError("not a trial record")
        return cls(trial, params, data)

    def to_line(self) -> dict[str, Any]:
        """The JSON object written to ``results.jsonl``."""
        return {"trial": self.trial, "params": self.params, **self.result}

    @property
    def success(self) -> bool:
        """The episode succeeded."""
        return bool(self.result.get("success"))

    @property
    def seed(self) -> int:
        """The episode seed."""
        return int(self.result["seed"])

    @property
    def failure_phase(self) -> str | None:
        """Phase that failed (``WORKER`` for a crash, a timeout or an exception)."""
        return self.result.get("failure_phase")

    @property
    def failure_kind(self) -> str | None:
        """The error behind the failure."""
        return self.result.get("failure_kind")

    @property
    def failure_reason(self) -> str | None:
        """What failed, with the numbers."""
        return self.result.get("failure_reason")


def read_results(path: str | Path) -> list[TrialRecord]:
    """The records of ``results.jsonl`` in file order.

    A last line without its newline (cut short by a kill) is ignored; an undecodable complete line is skipped
    with a warning (its trial is then run again on resume).
    """
    p = Path(path)
    if not p.exists():
        return []
    raw = p.read_bytes()
    lines = raw.split(b"\n")
    if lines and lines[-1]:
        log.warning("%s: ignoring a truncated last line (%d bytes)", p, len(lines[-1]))
    records = []
    for n, line in enumerate(lines[:-1], start=1):
        if not line.strip():
            continue
        try:
            records.append(TrialRecord.from_line(json.loads(line)))
        except (ValueError, KeyError, TypeError) as exc:
            log.warning("%s:%d: skipping an unreadable line (%s)", p, n, exc)
    return records


class ResultsWriter:
    """Appends records to ``results.jsonl``: one ``write`` per line, then fsync (single writer: the parent).

    Opening it takes an exclusive lock on the file (``flock``, released by the kernel even on ``kill -9``), so
    that two campaigns never write into one directory at once.
    """

    def __init__(self, path: Path) -> None:
        self._path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not on Windows
            return
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._fd)
            raise ConfigError("out", str(path.parent), "is in use by another running campaign "
                              f"({path.name} is locked)") from None

    def cut_partial_line(self) -> None:
        """A kill while writing can leave a partial last line: cut it, or the next line would be glued to it."""
        size = os.fstat(self._fd).st_size
        if size:
            data = self._path.read_bytes()
            keep = data.rfind(b"\n") + 1
            if keep != size:
                os.ftruncate(self._fd, keep)

    def append(self, line: Mapping[str, Any]) -> None:
        """Write one results line and fsync it."""
        data = (json.dumps(json_ready(line), allow_nan=False, separators=(",", ":"), default=json_default)
                + "\n").encode()
        os.write(self._fd, data)
        os.fsync(self._fd)

    def close(self) -> None:
        """Close the file (releasing the lock)."""
        os.close(self._fd)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a fsynced temporary file and a rename (never a half-written file)."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


# --------------------------------------------------------------------------- #
# TOML (the trial files; no extra dependency)
# --------------------------------------------------------------------------- #

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(key: str) -> str:
    return key if _BARE_KEY.match(key) else json.dumps(key)


def _toml_value(value: Any) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):  # an inline table (e.g. one part of a compound object)
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items() if v is not None) + "}"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def toml_dumps(data: Mapping[str, Any], _prefix: str = "") -> str:
    """TOML text of nested mappings of scalars and lists (``None`` values are left out: the default applies)."""
    scalars = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in data.items()
               if v is not None and not isinstance(v, Mapping)]
    out = []
    if scalars:
        out.append(("" if not _prefix else f"[{_prefix}]\n") + "\n".join(scalars) + "\n")
    for k, v in data.items():
        if isinstance(v, Mapping):
            out.append(toml_dumps(v, f"{_prefix}.{_toml_key(k)}" if _prefix else _toml_key(k)))
    return "\n".join(out)


def episode_config_toml(config: EpisodeConfig, header: str = "") -> str:
    """The full episode config as TOML for ``pickplace run --config`` (floats written exactly)."""
    tables = config.to_dict()
    comment = "".join(f"# {line}\n" for line in header.splitlines())
    return comment + ("\n" if comment else "") + toml_dumps(tables)


def trial_toml_path(out_dir: str | Path, index: int) -> Path:
    """Where the config of trial ``index`` is written."""
    return Path(out_dir) / TRIALS_DIR / f"trial_{index:04d}.toml"


def reproduce_command(config_path: str | Path, seed: int) -> str:
    """The command that re-runs one trial alone."""
    return f"pickplace run --config {config_path} --seed {seed}"


def load_campaign_toml(path: str | Path) -> tuple[EpisodeConfig, RandomizationSpec]:
    """Load an episode config TOML that may also hold a ``[randomization]`` table.

    Returns:
        The episode config (without the randomization table) and the spec (defaults if the table is absent).
    """
    data = read_toml(path)
    randomization = data.pop("randomization", {})
    base = EpisodeConfig.from_dict(data)
    return base, RandomizationSpec.from_dict(randomization, base.scene.object)


def load_campaign(out_dir: str | Path, *, workers: int | None = None, timeout_s: float = 60.0,
                  trials: int | None = None) -> CampaignConfig:
    """The campaign recorded in ``OUT/campaign.json`` (to resume it without repeating its options)."""
    p = Path(out_dir) / CAMPAIGN_FILE
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError("out", str(out_dir), f"holds no campaign ({p}: {exc.strerror or exc})") from None
    except json.JSONDecodeError as exc:
        raise ConfigError("out", str(p), f"is not valid JSON: {exc}") from None
    base = EpisodeConfig.from_dict(data["base"])
    return CampaignConfig(base, RandomizationSpec.from_dict(data["randomization"], base.scene.object),
                          trials if trials is not None else data["trials"], data["seed"], workers, timeout_s)


def json_ready(value: Any) -> Any:
    """Nested dicts, lists and tuples as JSON data: tuples become lists, NaN and infinities None."""
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def json_default(value: Any) -> Any:
    """numpy scalars and arrays in a results line become plain numbers and lists."""
    if isinstance(value, np.generic):
        return json_ready(value.item())
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


def load_records(out_dir: str | Path) -> tuple[TrialRecord, ...]:
    """The records of a campaign's output directory, one per trial (the first if a trial appears twice), by index."""
    seen: dict[int, TrialRecord] = {}
    for r in read_results(Path(out_dir) / RESULTS_FILE):
        seen.setdefault(r.trial, r)
    return tuple(seen[i] for i in sorted(seen))


def strip_wall_times(result: Mapping[str, Any]) -> dict[str, Any]:
    """A result dict without the fields that measure wall-clock time (to compare two runs of one trial)."""
    return {k: v for k, v in result.items() if k not in WALL_TIME_FIELDS}


__all__ = [
    "CAMPAIGN_FILE",
    "FORMAT_VERSION",
    "RESULTS_FILE",
    "SUMMARY_FILE",
    "TRIALS_DIR",
    "WALL_TIME_FIELDS",
    "ResultsWriter",
    "TrialRecord",
    "episode_config_toml",
    "json_default",
    "json_ready",
    "load_campaign",
    "load_campaign_toml",
    "load_records",
    "read_results",
    "reproduce_command",
    "strip_wall_times",
    "toml_dumps",
    "trial_toml_path",
    "write_atomic",
]
