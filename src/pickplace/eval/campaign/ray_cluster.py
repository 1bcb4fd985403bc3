"""Connecting a campaign to Ray: a local instance, or a running cluster by address, with or without token auth.

Ray 2.60's token authentication, as its source has it (``ray/_private/authentication/authentication_token_setup.py``,
``ray/_private/worker.py`` ``init``, ``ray/scripts/scripts.py`` ``start``):

* ``ray start --head`` turns token mode on when a token exists on the head node (``RAY_AUTH_TOKEN``, else the file
  named by ``RAY_AUTH_TOKEN_PATH``, else ``~/.ray/auth_token``, which any local ``ray.init()`` and
  ``ray get-auth-token --generate`` create), unless ``RAY_AUTH_MODE=disabled``;
  ``ray start --address ...`` (a worker node) uses token mode only with ``RAY_AUTH_MODE=token``;
* ``ray.init(address="host:port")`` never turns token mode on by itself (``address="auto"`` does whenever a token
  exists locally), so against a token cluster every RPC is refused (``Unauthenticated``, retried for a while);
* a driver in token mode cannot serve a cluster without tokens either: the cluster's workers cannot call back into
  it, and its actors die before they start.

So the driver must run in the cluster's mode. Before joining, :func:`cluster_auth_mode` asks the cluster's GCS, in a
short subprocess (a refused attempt then logs nothing in this process), whether it answers without a token, and
with this machine's token if not; :func:`ray_session` sets ``RAY_AUTH_MODE`` for the session to match and puts the
previous value back afterwards. When the cluster wants a token that this machine does not have, or rejects it, the
campaign stops with one :class:`~pickplace.eval.campaign.spec.CampaignError` that says what to set.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import socket
import subprocess
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, Literal

from pickplace.eval.campaign.spec import CampaignError

log = logging.getLogger(__name__)

#: The pip command that installs Ray.
RAY_HINT = "pip install 'pickplace[ray]'"
#: Environment variables of Ray's token authentication.
AUTH_MODE_ENV = "RAY_AUTH_MODE"
TOKEN_ENV = "RAY_AUTH_TOKEN"
TOKEN_PATH_ENV = "RAY_AUTH_TOKEN_PATH"
#: Port of a head node started without ``--port``.
DEFAULT_GCS_PORT = 6379
#: Time allowed to open a TCP connection to the cluster's address (s).
CONNECT_TIMEOUT_S = 5.0
#: Time allowed to the subprocess that asks the cluster for its authentication mode (s).
PROBE_TIMEOUT_S = 120.0
#: Niceness of the worker processes of a local Ray instance. Ray's default (``worker_niceness``, 15) makes its
#: workers yield to every other process: on a busy machine a trial then runs ~10 times slower than on a local
#: worker process (measured: 30-43 s against 4-5 s with two other processes keeping both cores busy).
LOCAL_WORKER_NICENESS = 0

AuthMode = Literal["disabled", "token"]

#: How to give the driver the token (the end of the error messages).
TOKEN_HELP = (f"set {TOKEN_ENV} to the output of `ray get-auth-token` on the head node (or {TOKEN_PATH_ENV} to a "
              "file holding it, or copy it to ~/.ray/auth_token)")

# Run by `python -c` with the address as argv[1]: prints one JSON object, {"mode": ...} or {"error": ...}.
_PROBE = r"""
import json, os, sys

def attempt(mode):
    from ray._raylet import AuthenticationTokenLoader, Config, GcsClient
    os.environ["RAY_AUTH_MODE"] = mode
    Config.initialize("")
    AuthenticationTokenLoader.instance().reset_cache()
    try:
        GcsClient(address=sys.argv[1])
    except Exception as exc:
        return type(exc).__name__, (str(exc).strip().splitlines() or [""])[0]
    return None

def probe():
    try:
        from ray._raylet import AuthenticationTokenLoader
    except ImportError:
        return {"mode": None}
    error = attempt("disabled")
    if error is None:
        return {"mode": "disabled"}
    if error[0] != "AuthenticationError":
        return {"error": "other", "detail": ": ".join(error)}
    if not AuthenticationTokenLoader.instance().has_token(ignore_auth_mode=True):
        return {"error": "no-token"}
    error = attempt("token")
    if error is None:
        return {"mode": "token"}
    return {"error": "rejected" if error[0] == "AuthenticationError" else "other", "detail": ": ".join(error)}

print(json.dumps(probe()))
"""


def import_ray() -> Any:
    """The ``ray`` module, or a :class:`CampaignError` that says how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise CampaignError(f"the Ray backend needs Ray, which is not installed ({exc}): {RAY_HINT}") from None
    return ray


def token_source(environ: Mapping[str, str] | None = None) -> str | None:
    """Where Ray reads the authentication token from on this machine (its order), or None if it finds none.

    Args:
        environ: The environment (default ``os.environ``).

    Returns:
        ``"RAY_AUTH_TOKEN"``, ``"RAY_AUTH_TOKEN_PATH=<path>"``, the path of ``~/.ray/auth_token``, or None.
    """
    env = os.environ if environ is None else environ
    if env.get(TOKEN_ENV):
        return TOKEN_ENV
    if env.get(TOKEN_PATH_ENV):
        return f"{TOKEN_PATH_ENV}={env[TOKEN_PATH_ENV]}"
    default = Path(env.get("HOME") or Path.home()) / ".ray" / "auth_token"
    return str(default) if default.is_file() else None


def split_address(address: str) -> tuple[str, int]:
    """``(host, port)`` of a cluster address ``host[:port]`` (the port defaults to Ray's 6379).

    Raises:
        CampaignError: the port is not a number.
    """
    host, sep, port = address.strip().rpartition(":")
    if not sep:
        return address.strip(), DEFAULT_GCS_PORT
    try:
        return host.strip("[]"), int(port)
    except ValueError:
        raise CampaignError(f"cannot join the Ray cluster at {address!r}: expected host:port") from None


def cluster_auth_mode(address: str, timeout_s: float = PROBE_TIMEOUT_S) -> AuthMode | None:
    """The authentication mode of the running cluster at ``address``, asked from its GCS.

    Args:
        address: ``host:port`` of the head node (its GCS).
        timeout_s: Time allowed for the answer (s).

    Returns:
        ``"disabled"`` (it answers without a token), ``"token"`` (it answers with this machine's token), or None
        for a Ray without token authentication.

    Raises:
        CampaignError: nothing listens at ``address``; the cluster wants a token and this machine has none; it
            rejects this machine's token; or it does not answer as a Ray GCS.
    """
    host, port = split_address(address)
    where = f"cannot join the Ray cluster at {address!r}"
    try:
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise CampaignError(f"{where}: nothing accepts connections at {host}:{port} ({exc.strerror or exc}); start "
                            f"the head node with `ray start --head --port {port}`, or check the address") from None
    try:
        proc = subprocess.run([sys.executable, "-c", _PROBE, f"{host}:{port}"], capture_output=True, text=True,
                              timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired:
        raise CampaignError(f"{where}: it did not answer as a Ray cluster within {timeout_s:g} s") from None
    lines = proc.stdout.strip().splitlines()
    try:
        answer = json.loads(lines[-1])
    except (IndexError, ValueError):
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise CampaignError(f"{where}: asking it for its authentication mode failed ({tail})") from None
    log.debug("Ray cluster at %s: %s", address, answer)
    error = answer.get("error")
    if error == "no-token":
        raise CampaignError(f"{where}: it requires token authentication and this machine has no token: "
                            f"{TOKEN_HELP}")
    if error == "rejected":
        raise CampaignError(f"{where}: it rejected the token from {token_source() or 'this machine'}: {TOKEN_HELP}")
    if error is not None:
        raise CampaignError(f"{where}: it did not answer as a Ray cluster ({answer.get('detail') or error})")
    return answer.get("mode")


def _set_auth_mode(mode: str | None) -> None:
    """Set (or unset, for None) ``RAY_AUTH_MODE`` in this process and refresh Ray's cached config and token."""
    if mode is None:
        os.environ.pop(AUTH_MODE_ENV, None)
    else:
        os.environ[AUTH_MODE_ENV] = mode
    try:
        from ray._raylet import AuthenticationTokenLoader, Config
    except ImportError:  # a Ray without token authentication
        return
    Config.initialize("")  # what Ray itself does after setting the variable (authentication_token_setup.py)
    AuthenticationTokenLoader.instance().reset_cache()


def _bootstrap_address(address: str) -> str | None:
    """``host:port`` that ``ray.init(address=address)`` would join, or None to let Ray report the problem."""
    if address.startswith("ray://") or address == "local":
        return None  # Ray Client / a new local instance: nothing to probe
    if address == "auto":
        try:
            from ray._private.services import canonicalize_bootstrap_address

            return canonicalize_bootstrap_address(address)
        except Exception as exc:  # no cluster found, or a Ray without this function: ray.init reports it
            log.debug("cannot resolve Ray address 'auto': %s", exc)
            return None
    return address


@contextlib.contextmanager
def ray_session(address: str | None, num_cpus: int | None = None) -> Iterator[Any]:
    """Ray, initialized for the duration of the block: the caller's session if there is one, else a new one.

    A new session is a local instance (``address`` None, ``num_cpus`` CPUs or every core, workers at niceness
    ``LOCAL_WORKER_NICENESS`` like the local backend's processes) or a running cluster (``"host:port"``, or
    ``"auto"``: the one on this machine; its workers' niceness is the cluster's, ``RAY_worker_niceness`` when its
    nodes were started). To join a cluster, ``RAY_AUTH_MODE`` is set to the cluster's mode (see the module
    docstring); the session is shut down at the end of the block and ``RAY_AUTH_MODE`` put back as it was.

    Raises:
        CampaignError: Ray is not installed, or the cluster cannot be joined (the message says why and what to set).
    """
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    saved = os.environ.get(AUTH_MODE_ENV)
    target = _bootstrap_address(address) if address is not None else None
    try:
        if target is not None:
            mode = cluster_auth_mode(target)
            if mode is not None:
                log.info("joining the Ray cluster at %s with authentication mode %r", target, mode)
                _set_auth_mode(mode)
        opts: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        try:
            if address is None:
                ray.init(num_cpus=num_cpus or os.cpu_count() or 1,
                         _system_config={"worker_niceness": LOCAL_WORKER_NICENESS}, **opts)
            else:
                ray.init(address=address, **opts)
        except Exception as exc:  # Ray raises ConnectionError, RuntimeError, ValueError, AuthenticationError...
            where = f"join the Ray cluster at {address!r}" if address else "start a local Ray instance"
            first = (str(exc).strip().splitlines() or [""])[0]
            raise CampaignError(f"cannot {where}: {type(exc).__name__}: {first}") from exc
        try:
            yield ray
        finally:
            ray.shutdown()
    finally:
        _set_auth_mode(saved)  # ray.init() of a local instance sets it too; and forget the token it loaded


__all__ = [
    "AUTH_MODE_ENV",
    "LOCAL_WORKER_NICENESS",
    "RAY_HINT",
    "TOKEN_ENV",
    "TOKEN_PATH_ENV",
    "cluster_auth_mode",
    "import_ray",
    "ray_session",
    "split_address",
    "token_source",
]
