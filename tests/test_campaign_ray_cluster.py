"""``pickplace eval --ray ADDRESS`` against real clusters started with ``ray start --head``.

Each cluster is a head node with 2 CPUs on a free port, in its own short ``RAY_TMPDIR`` and with its own ``HOME``
(so its token is not this machine's ``~/.ray/auth_token`` and no other Ray session is touched). Ray 2.60 turns token
authentication on at ``ray start --head`` when a token exists (here made with ``ray get-auth-token --generate``),
and off with ``RAY_AUTH_MODE=disabled``. The campaign joins through ``pickplace.cli.main`` with nothing exported by
hand: the token is where ``ray start`` found it (``$HOME/.ray/auth_token``); its results must equal the local
backend's. A driver without the token, or with a wrong one, must fail with one line that says what to set.
The tests that start a cluster are ``-m slow``; the token lookup, the address parsing and the error for an
address with nothing behind it run by default.

Teardown kills the head's process group and every descendant of its processes (Ray's workers run in their own
process groups), then checks that none is left; ``ray stop`` is not used, as it would stop every Ray session on the
machine (another engineer's, or another test's).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from pickplace.cli import main
from pickplace.eval.campaign import (
    RESULTS_FILE,
    CampaignConfig,
    CampaignError,
    CampaignRun,
    load_records,
    run_campaign,
    strip_wall_times,
)
from pickplace.eval.campaign.ray_cluster import split_address, token_source

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="finds the cluster's processes through /proc")
ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'pickplace[ray]')")

SEED = 11
TRIALS = 3
RAY = str(Path(sys.executable).with_name("ray"))
START_TIMEOUT_S = 180.0


@dataclass(frozen=True)
class Head:
    """A running head node: its address, the HOME and RAY_TMPDIR it was started with, its process group.

    ``ray start`` wrote ``$RAY_TMPDIR/ray/ray_current_cluster``, where ``--ray auto`` looks for the address.
    """

    address: str
    home: Path
    tmpdir: Path
    pgid: int


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _processes() -> dict[int, tuple[int, int]]:
    """pid -> (parent pid, process group) of every process."""
    out = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except (OSError, IndexError):
                continue
            if fields[0] != "Z":  # zombies are gone already, waiting for their parent
                out[int(entry.name)] = (int(fields[1]), int(fields[2]))
    return out


def _family(pgid: int) -> set[int]:
    """The processes of group ``pgid`` and all their descendants (Ray's workers set their own process group)."""
    procs = _processes()
    found = {pid for pid, (_, group) in procs.items() if group == pgid}
    while True:
        more = {pid for pid, (parent, _) in procs.items() if parent in found} - found
        if not more:
            return found
        found |= more


def _kill_family(pgid: int) -> set[int]:
    """SIGKILL the head's processes and their descendants until none is left (30 s); the ones still alive."""
    deadline = time.monotonic() + 30.0
    while (alive := _family(pgid)) and time.monotonic() < deadline:
        for pid in alive:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        time.sleep(0.2)
    return _family(pgid)


def _home(root: Path, name: str, token: bool) -> Path:
    """A HOME directory, with a fresh Ray token in ``.ray/auth_token`` if ``token``."""
    home = root / name
    home.mkdir()
    if token:
        subprocess.run([RAY, "get-auth-token", "--generate"], env=_env(home), check=True, capture_output=True,
                       timeout=120)
        assert (home / ".ray" / "auth_token").is_file()
    return home


def _env(home: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("RAY_AUTH", "RAY_ADDRESS", "RAY_TMPDIR"))}
    return {**env, "HOME": str(home), **extra}


@contextlib.contextmanager
def _ray_head(home: Path, auth: bool) -> Iterator[Head]:
    """``ray start --head`` with 2 CPUs on a free port (token auth on if HOME holds a token and ``auth``)."""
    temp_dir = Path(tempfile.mkdtemp(prefix="pp-ray-", dir="/tmp"))  # short: Ray's unix sockets live in it
    port = _free_port()
    cmd = [RAY, "start", "--head", f"--port={port}", "--num-cpus=2", "--include-dashboard=false",
           "--disable-usage-stats", f"--dashboard-agent-listen-port={_free_port()}"]
    # its session goes to $RAY_TMPDIR/ray, away from other sessions; its workers run at niceness 0 (Ray's default,
    # 15, makes them ~10x slower than every other process on a busy machine)
    env = _env(home, RAY_TMPDIR=str(temp_dir), RAY_worker_niceness="0")
    if not auth:
        env["RAY_AUTH_MODE"] = "disabled"
    log = temp_dir / "ray-start.log"
    with log.open("wb") as f:
        proc = subprocess.Popen(cmd, env=env, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        assert proc.wait(timeout=START_TIMEOUT_S) == 0, log.read_text()  # returns once the head is up
        text = log.read_text()
        assert ("Token authentication is enabled" in text) == auth, text
        yield Head(f"127.0.0.1:{port}", home, temp_dir, proc.pid)
    finally:
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.kill()
            proc.wait(timeout=10)
        left = _kill_family(proc.pid)
        subprocess.run(["rm", "-rf", str(temp_dir)], check=False)
        assert not left, f"processes of the Ray cluster left behind: {sorted(left)}"


@pytest.fixture(scope="module")
def local(tmp_path_factory: pytest.TempPathFactory) -> CampaignRun:
    """The campaign on the local backend: what the clusters must reproduce."""
    return run_campaign(CampaignConfig(trials=TRIALS, seed=SEED, workers=2), tmp_path_factory.mktemp("local"))


@pytest.fixture(scope="module")
def token_head(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Head]:
    """A head with token authentication on (the default of `ray start --head` when a token exists)."""
    root = tmp_path_factory.mktemp("token-cluster")
    with _ray_head(_home(root, "head-home", token=True), auth=True) as head:
        yield head


def _eval(head_address: str, out: Path) -> int:
    """``pickplace eval`` on the cluster (a per-trial limit that no normal trial comes near, busy machine or not)."""
    return main(["eval", "--trials", str(TRIALS), "--workers", "2", "--seed", str(SEED), "--ray", head_address,
                 "--timeout", "300", "--out", str(out)])


def _check_same_as_local(out: Path, local: CampaignRun) -> None:
    records = load_records(out)
    assert [r.trial for r in records] == list(range(TRIALS))
    for mine, theirs in zip(records, local.records, strict=True):
        assert mine.params == theirs.params
        assert strip_wall_times(mine.result) == strip_wall_times(theirs.result)


def _scrub_ray_env(monkeypatch: pytest.MonkeyPatch, home: Path) -> None:
    """This process as a user's shell: HOME set, nothing of Ray's exported."""
    for name in [k for k in os.environ if k.startswith(("RAY_AUTH", "RAY_ADDRESS", "RAY_TMPDIR"))]:
        monkeypatch.delenv(name)
    monkeypatch.setenv("HOME", str(home))


def test_token_source_follows_rays_order_and_addresses_split(tmp_path: Path) -> None:
    """RAY_AUTH_TOKEN, then RAY_AUTH_TOKEN_PATH, then $HOME/.ray/auth_token (Ray's own order)."""
    home = _home(tmp_path, "home", token=True)
    token_file = str(home / ".ray" / "auth_token")
    assert token_source({"HOME": str(home)}) == token_file
    assert token_source({"HOME": str(home), "RAY_AUTH_TOKEN_PATH": "/x"}) == "RAY_AUTH_TOKEN_PATH=/x"
    assert token_source({"HOME": str(home), "RAY_AUTH_TOKEN_PATH": "/x", "RAY_AUTH_TOKEN": "t"}) == "RAY_AUTH_TOKEN"
    assert token_source({"HOME": str(tmp_path / "nobody")}) is None
    assert split_address("10.0.0.5:6390") == ("10.0.0.5", 6390)
    assert split_address("head-node") == ("head-node", 6379)
    assert split_address("[::1]:6390") == ("::1", 6390)
    with pytest.raises(CampaignError, match="expected host:port"):
        split_address("10.0.0.5:port")


@pytest.mark.slow
def test_eval_joins_a_cluster_with_token_auth(token_head: Head, local: CampaignRun, tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch,
                                              capfd: pytest.CaptureFixture[str]) -> None:
    """The driver finds the token where `ray start` found it ($HOME/.ray/auth_token), with nothing exported."""
    _scrub_ray_env(monkeypatch, token_head.home)
    assert _eval(token_head.address, tmp_path / "out") == 0
    assert "Unauthenticated" not in capfd.readouterr().err
    _check_same_as_local(tmp_path / "out", local)
    assert "RAY_AUTH_MODE" not in os.environ  # set for the session only
    assert not ray.is_initialized()


@pytest.mark.slow
def test_eval_joins_a_cluster_without_auth(local: CampaignRun, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """RAY_AUTH_MODE=disabled on the head. The driver has a token and RAY_AUTH_MODE=token (as a local ray.init()
    leaves it): a driver in token mode cannot serve a cluster without tokens, so the cluster's mode must win."""
    home = _home(tmp_path, "home", token=True)
    with _ray_head(home, auth=False) as head:
        _scrub_ray_env(monkeypatch, home)
        monkeypatch.setenv("RAY_AUTH_MODE", "token")
        assert _eval(head.address, tmp_path / "out") == 0
        assert os.environ["RAY_AUTH_MODE"] == "token"  # put back after the session
        # `--ray auto` finds the cluster on this machine; alone, Ray would join it in token mode (a token exists)
        monkeypatch.setenv("RAY_TMPDIR", str(head.tmpdir))
        monkeypatch.delenv("RAY_AUTH_MODE")
        assert _eval("auto", tmp_path / "auto") == 0
    _check_same_as_local(tmp_path / "out", local)
    _check_same_as_local(tmp_path / "auto", local)


@pytest.mark.slow
@pytest.mark.parametrize("token", [None, "not-the-token"])
def test_eval_without_the_right_token_fails_with_one_line(token_head: Head, token: str | None, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch,
                                                          capfd: pytest.CaptureFixture[str]) -> None:
    _scrub_ray_env(monkeypatch, _home(tmp_path, "home", token=False))
    if token is not None:
        monkeypatch.setenv("RAY_AUTH_TOKEN", token)
    assert _eval(token_head.address, tmp_path / "out") == 1
    err = [line for line in capfd.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1, err
    assert err[0].startswith(f"error: CampaignError: cannot join the Ray cluster at '{token_head.address}': ")
    assert ("has no token" if token is None else "rejected the token from RAY_AUTH_TOKEN") in err[0]
    assert "RAY_AUTH_TOKEN" in err[0] and "ray get-auth-token" in err[0]
    results = tmp_path / "out" / RESULTS_FILE
    assert not results.exists() or results.stat().st_size == 0  # stopped before any trial


def test_eval_with_nothing_at_the_address_fails_with_one_line(tmp_path: Path,
                                                             capfd: pytest.CaptureFixture[str]) -> None:
    address = f"127.0.0.1:{_free_port()}"
    assert _eval(address, tmp_path / "out") == 1
    err = [line for line in capfd.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1, err
    assert "nothing accepts connections" in err[0] and "ray start --head" in err[0]
