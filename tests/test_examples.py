"""The examples run as a user would run them, and do what they say."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _run(name: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(EXAMPLES / name), *args], capture_output=True, text=True, timeout=300)


def test_single_episode() -> None:
    proc = _run("single_episode.py")
    assert proc.returncode == 0, proc.stderr
    assert "placed" in proc.stdout and "RETRACT" in proc.stdout


@pytest.mark.slow
def test_faulted_episode() -> None:
    proc = _run("faulted_episode.py")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("max_retries=0: FAILED in EXEC_TRANSPORT")
    assert any(line.startswith("max_retries=3: success") for line in lines)


@pytest.mark.slow
def test_small_campaign(tmp_path: Path) -> None:
    proc = _run("small_campaign.py", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    assert "6/6 succeeded" in proc.stdout
    assert len((tmp_path / "results.jsonl").read_text().splitlines()) == 6
