"""Bad input is rejected cleanly: one line naming the field, the value and what is allowed; no traceback;
nothing runs.

A property-based test throws random configs at the validator (it accepts them or raises ConfigError, never
anything else), and the command line is checked on every kind of bad input a user can give it.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pickplace.cli import main
from pickplace.errors import ConfigError
from pickplace.task.episode import _SECTIONS, EpisodeConfig

# --------------------------------------------------------------------------- #
# property: the validator accepts or raises ConfigError, nothing else
# --------------------------------------------------------------------------- #

_FIELDS = {name: [f.name for f in dataclasses.fields(cls)] for name, cls in _SECTIONS.items()}
_numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.floats(min_value=-2.0, max_value=2.0),
    st.integers(min_value=-10**12, max_value=10**12),
)
_values = st.one_of(
    _numbers,
    st.booleans(),
    st.text(max_size=8),
    st.none(),
    st.lists(_numbers, min_size=0, max_size=7),
    st.lists(st.text(max_size=3), max_size=3),
    st.dictionaries(st.text(max_size=3), _numbers, max_size=2),
)


@st.composite
def _raw_configs(draw: st.DrawFn) -> dict:
    data: dict = {}
    for section in draw(st.lists(st.sampled_from([*_FIELDS, "bogus_table"]), unique=True, max_size=4)):
        fields = [*_FIELDS.get(section, ["x"]), "bogus_key"]
        keys = draw(st.lists(st.sampled_from(fields), unique=True, max_size=4))
        data[section] = {k: draw(_values) for k in keys}
    if draw(st.booleans()) and data:  # sometimes a table that is not a table
        data[next(iter(data))] = draw(_values)
    return data


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_raw_configs())
def test_random_configs_accepted_or_config_error(data: dict) -> None:
    try:
        config = EpisodeConfig.from_dict(data)
    except ConfigError as exc:
        assert exc.field and str(exc).startswith(exc.field)  # names the field first
        return
    assert isinstance(config, EpisodeConfig)
    for section in _SECTIONS:  # what was accepted is a valid, fully typed config
        assert dataclasses.is_dataclass(getattr(config, section))


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted((s, f) for s, fs in _FIELDS.items() for f in fs)),
       st.sampled_from([math.nan, math.inf, -math.inf]))
def test_non_finite_numbers_are_rejected_everywhere(field: tuple[str, str], value: float) -> None:
    """NaN and infinities never slip through, whatever numeric field they are put in."""
    section, name = field
    default = getattr(getattr(EpisodeConfig(), section), name)
    if isinstance(default, bool) or not isinstance(default, (int, float, tuple)) or default == ():
        return  # (an empty tuple is a list of tables, scene.boxes: their numbers are checked in test_planning_scene)
    bad = [value] * len(default) if isinstance(default, tuple) else value
    with pytest.raises(ConfigError, match=rf"{section}\.{name}"):
        EpisodeConfig.from_dict({section: {name: bad}})


# --------------------------------------------------------------------------- #
# the command line: one line, non-zero exit, no traceback, before anything moves
# --------------------------------------------------------------------------- #


def _toml(tmp_path: Path, text: str) -> str:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    return str(path)


CASES = [
    ("malformed TOML", lambda p: ["run", "--config", _toml(p, "[scene\ncube_mass_kg = 1")], "is not valid TOML"),
    ("unknown key", lambda p: ["run", "--config", _toml(p, "[scene]\ncube_colour = 'red'\n")],
     "scene.cube_colour"),
    ("unknown table", lambda p: ["run", "--config", _toml(p, "[scenery]\nx = 1\n")], "unknown table"),
    ("missing file", lambda p: ["run", "--config", str(p / "nope.toml")], "cannot be read"),
    ("NaN mass", lambda p: ["run", "--cube-mass", "nan"], "scene.cube_mass_kg"),
    ("infinite friction", lambda p: ["run", "--friction", "inf"], "scene.cube_friction"),
    ("negative mass", lambda p: ["run", "--cube-mass", "-1"], "scene.cube_mass_kg"),
    ("cube wider than the open gripper", lambda p: ["run", "--cube-size", "0.09"], "scene.cube_size_m"),
    ("cube start off the table", lambda p: ["run", "--cube-start", "2.0", "0.0"], "scene.cube_start_xy_m"),
    ("goal out of reach", lambda p: ["run", "--goal", "1.5", "0"], "UnreachableTarget"),
    ("goal inside the obstacle",
     lambda p: ["run", "--obstacle", "--config", _toml(p, "[scene]\nobstacle_offset_xy_m = [0.0, -0.2]\n")],
     "cube <-> obstacle"),
    ("timestep out of range", lambda p: ["run", "--config", _toml(p, "[scene]\ntimestep_s = 0.1\n")],
     "scene.timestep_s"),
    ("negative gain", lambda p: ["run", "--config", _toml(p, "[control]\njoint_kp_nm_rad = [-1, 200, 200, 100, "
                                                             "100, 100]\n")], "control.joint_kp_nm_rad"),
    ("gain vector too short", lambda p: ["run", "--config", _toml(p, "[control]\njoint_kp_nm_rad = [200]\n")],
     "control.joint_kp_nm_rad"),
    ("string for a number", lambda p: ["run", "--config", _toml(p, "[scene]\ncube_mass_kg = '0.2'\n")],
     "scene.cube_mass_kg"),
    ("string for a bool", lambda p: ["run", "--config", _toml(p, "[scene]\nobstacle = 'yes'\n")],
     "scene.obstacle"),
    ("bad fault", lambda p: ["run", "--config", _toml(p, "[faults]\npad_friction_scale = -2\n")],
     "faults.pad_friction_scale"),
    ("bad seed", lambda p: ["run", "--seed", "-3"], "seed"),
]


#: Cases that build the scene and fail in the episode's IDLE checks (~3 s each): "goal out of reach" stays in the
#: default run; the obstacle case is -m slow (test_episode.py checks the same failure in-process by default).
SLOW_CASES = {"goal inside the obstacle"}


@pytest.mark.parametrize(("label", "argv", "expected"),
                         [pytest.param(*c, id=c[0], marks=[pytest.mark.slow] if c[0] in SLOW_CASES else [])
                          for c in CASES])
def test_cli_rejects_bad_input_in_one_line(label: str, argv, expected: str, tmp_path: Path, capsys) -> None:
    code = main(argv(tmp_path))
    out, err = capsys.readouterr()
    assert code != 0, label
    assert out == ""  # nothing ran: no timeline, no table
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ") and expected in lines[0]
    assert "Traceback" not in err


def test_cli_bad_input_as_a_user_sees_it(tmp_path: Path) -> None:
    """The same through a real process: exit code 1, one line on stderr, no traceback."""
    proc = subprocess.run([sys.executable, "-m", "pickplace", "run", "--config",
                           _toml(tmp_path, "[scene]\ncube_mass_kg = nan\n")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr.strip().count("\n") == 0 and "scene.cube_mass_kg = nan" in proc.stderr
    assert "Traceback" not in proc.stderr
