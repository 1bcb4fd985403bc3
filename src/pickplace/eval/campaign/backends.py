"""Where the trials run: a pool of local worker processes, or a pool of Ray actors.

Both backends keep long-lived workers that are sent one trial at a time, and count a trial's wall-clock timeout
from the moment it is handed to a worker that is already up (its imports done), so that starting workers on a
busy machine or a cluster never counts against a trial. A trial whose worker dies (segfault, ``os._exit``, OOM
kill, a lost node) or runs past the timeout (the worker is then killed) is recorded as a failed trial of phase
``WORKER`` with the reason, and a fresh worker takes its place; an exception raised by the episode is caught in
the worker and recorded the same way (:func:`~pickplace.eval.campaign.spec.execute_trial`).

Local: one process per worker (``spawn`` context), fed through a pipe; the parent waits on the pipes and the
process sentinels with the nearest per-trial deadline as timeout. Workers are spawned (not forked), so a script
that runs a campaign must do so under ``if __name__ == "__main__":``.

Ray: one actor per worker (``num_cpus=1``, no restarts, no retries), each created with the episode function and
sent a trial only once its ``ready()`` call has returned; on timeout the actor is killed (``ray.kill``) and a new one
started. Ray is imported only then (``pip install 'pickplace[ray]'``); on a cluster, every node needs pickplace
installed, in the same version as the driver. Ray runs its workers at niceness 15 unless the node was started with
``RAY_worker_niceness=0`` (a local instance is, see :mod:`~pickplace.eval.campaign.ray_cluster`): on a busy node such
workers yield to every other process, and their trials take longer against the same timeout.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing as mp
import os
import re
import signal
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any

from pickplace.eval.campaign.spec import CampaignError, RunFn, Trial, execute_trial, worker_failure

log = logging.getLogger(__name__)

#: Time allowed for the first Ray worker to come up while trials wait (s): longer means the cluster cannot
#: place a worker (no free CPU) or cannot start one.
RAY_STARTUP_TIMEOUT_S = 300.0


# --------------------------------------------------------------------------- #
# local processes
# --------------------------------------------------------------------------- #

OnResult = Callable[[dict[str, Any]], None]


@dataclass
class _Slot:
    """One local worker process and the trial it runs."""

    proc: Any  # multiprocessing.process.BaseProcess
    conn: Connection
    ready: bool = False
    trial: Trial | None = None
    started: float = 0.0


def _worker_main(conn: Connection, run_fn: RunFn) -> None:
    """Loop of a local worker: receive a trial, run it, send its results line; stop on None or EOF."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    conn.send(("ready", os.getpid()))
    while True:
        try:
            trial = conn.recv()
        except (EOFError, OSError):
            return
        if trial is None:
            return
        line = execute_trial(run_fn, trial)
        try:
            conn.send(("done", line))
        except OSError:
            return


def _exit_reason(exitcode: int | None) -> str:
    if exitcode is None:
        return "the worker process vanished"
    if exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"the worker process was killed by {name} (signal {-exitcode})"
    return f"the worker process exited with code {exitcode}"


def run_local(trials: Sequence[Trial], run_fn: RunFn, workers: int, timeout_s: float, on_result: OnResult,
               on_ready: Callable[[], None]) -> None:
    """Run the trials on ``workers`` local processes; call ``on_result`` (in this process) per finished trial."""
    ctx = mp.get_context("spawn")

    def start() -> _Slot:
        parent, child = ctx.Pipe(duplex=True)
        proc = ctx.Process(target=_worker_main, args=(child, run_fn), name="pickplace-worker", daemon=True)
        proc.start()
        child.close()
        return _Slot(proc, parent)

    queue = deque(trials)
    slots = [start() for _ in range(min(workers, len(queue)))]
    announced = False

    def retire(slot: _Slot, kind: str, reason: str) -> None:
        """The slot's worker is gone (or killed): record its trial, start a fresh worker if work remains."""
        slot.conn.close()
        slot.proc.join(5.0)
        if slot.trial is not None:
            t = slot.trial
            log.warning("trial %d: %s", t.index, reason)
            on_result(worker_failure(t, kind, reason, time.monotonic() - slot.started))
        elif not slot.ready:
            raise CampaignError(f"a worker process failed to start: {_exit_reason(slot.proc.exitcode)} (see its "
                                "traceback above; workers are spawned, so a script that runs a campaign must "
                                "do so under `if __name__ == '__main__':`)")
        slots.remove(slot)
        if queue and len(slots) < workers:
            slots.append(start())

    try:
        while queue or any(s.trial is not None for s in slots):
            now = time.monotonic()
            for s in list(slots):
                if s.ready and s.trial is None and queue:
                    t = queue.popleft()
                    try:
                        s.conn.send(t)
                    except OSError:
                        queue.appendleft(t)
                        retire(s, "WorkerCrashed", _exit_reason(s.proc.exitcode))
                        continue
                    s.trial, s.started = t, now
            deadlines = [s.started + timeout_s for s in slots if s.trial is not None]
            wait([s.conn for s in slots] + [s.proc.sentinel for s in slots],
                 timeout=max(0.0, min(deadlines) - now) if deadlines else None)
            for s in list(slots):
                if s.conn.poll():
                    try:
                        tag, payload = s.conn.recv()
                    except (EOFError, OSError):
                        s.proc.join(5.0)
                        retire(s, "WorkerCrashed", _exit_reason(s.proc.exitcode))
                        continue
                    if tag == "ready":
                        s.ready = True
                        if not announced and all(x.ready for x in slots):
                            announced = True
                            on_ready()
                    else:
                        s.trial = None
                        on_result(payload)
                elif not s.proc.is_alive():
                    retire(s, "WorkerCrashed", _exit_reason(s.proc.exitcode))
                elif s.trial is not None and time.monotonic() - s.started > timeout_s:
                    s.proc.kill()
                    retire(s, "WorkerTimeout",
                           f"the trial ran past the per-trial timeout of {timeout_s:g} s (worker killed)")
    finally:
        for s in slots:
            with contextlib.suppress(OSError):
                s.conn.send(None)
        deadline = time.monotonic() + 5.0
        for s in slots:
            if s.trial is not None:  # interrupted mid-trial: do not wait for the episode to end
                s.proc.kill()
            s.proc.join(max(0.0, deadline - time.monotonic()))
            if s.proc.is_alive():
                s.proc.kill()
                s.proc.join()
            s.conn.close()


# --------------------------------------------------------------------------- #
# Ray actors
# --------------------------------------------------------------------------- #

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: Consecutive Ray workers that may fail to start (without any coming up in between) before the campaign stops.
_MAX_START_FAILURES = 3


def _ray_error_reason(exc: BaseException) -> str:
    """The informative line of a Ray error: its last line of text (Ray puts the cause last), without colours and
    without the generic advice Ray appends to a dead worker's line."""
    lines = [ln.strip() for ln in _ANSI.sub("", str(exc)).splitlines()]
    lines = [ln for ln in lines if ln and not set(ln) <= set("^~ ")]
    return lines[-1].split(" Some common causes include:")[0] if lines else type(exc).__name__


class TrialActor:
    """A long-lived Ray worker that runs trials one at a time (made a Ray actor by :func:`run_ray`).

    Args:
        run_fn: The episode function (see :func:`~pickplace.eval.campaign.spec.execute_trial`).
    """

    def __init__(self, run_fn: RunFn) -> None:
        self._run_fn = run_fn

    def ready(self) -> tuple[int, int]:
        """Answered once the actor is up, pickplace imported and the episode function loaded: (pid, niceness)."""
        return os.getpid(), os.nice(0)

    def run(self, trial: Trial) -> dict[str, Any]:
        """Run one trial; its results line (an exception raised by the episode is a ``WORKER`` failure)."""
        return execute_trial(self._run_fn, trial)


@dataclass
class _Actor:
    """One Ray actor and the trial it runs."""

    handle: Any  # ray.actor.ActorHandle
    ready_ref: Any  # ObjectRef of ready(); None once it answered
    created: float
    trial: Trial | None = None
    run_ref: Any = None  # ObjectRef of run(trial)
    started: float = 0.0

    @property
    def ready(self) -> bool:
        return self.ready_ref is None


def run_ray(ray: Any, trials: Sequence[Trial], run_fn: RunFn, workers: int | None, timeout_s: float,
            on_result: OnResult, on_ready: Callable[[], None]) -> None:
    """Run the trials on Ray actors, in an open session (:func:`~pickplace.eval.campaign.ray_cluster.ray_session`).

    Args:
        ray: The ``ray`` module, initialized.
        trials: The trials to run.
        run_fn: The episode function (picklable).
        workers: Actors at once; None: the session's CPUs.
        timeout_s: Per-trial limit (s), counted from the moment the trial is sent to an actor that is up.
        on_result: Called in this process with each finished trial's results line.
        on_ready: Called once, when every actor first started is up.

    Raises:
        CampaignError: the actors cannot start (pickplace missing on a node, no free CPU for RAY_STARTUP_TIMEOUT_S).
    """
    limit = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    actor_cls = ray.remote(num_cpus=1, max_restarts=0, max_task_retries=0)(TrialActor)
    fn_ref = ray.put(run_fn)
    queue = deque(trials)
    actors: list[_Actor] = []
    start_failures = 0
    announced = niced = False

    def start() -> None:
        handle = actor_cls.remote(fn_ref)
        actors.append(_Actor(handle, handle.ready.remote(), time.monotonic()))

    def retire(a: _Actor, kind: str, reason: str) -> None:
        """Kill the actor, record its trial (if any) as failed, start a fresh actor if work remains."""
        with contextlib.suppress(Exception):
            ray.kill(a.handle, no_restart=True)
        actors.remove(a)
        if a.trial is not None:
            log.warning("trial %d: %s", a.trial.index, reason)
            on_result(worker_failure(a.trial, kind, reason, time.monotonic() - a.started))
        if queue and len(actors) < limit:
            start()

    for _ in range(min(limit, len(queue))):
        start()
    try:
        while queue or any(a.trial is not None for a in actors):
            for a in actors:
                if a.ready and a.trial is None and queue:
                    a.trial = queue.popleft()
                    a.run_ref = a.handle.run.remote(a.trial)
                    a.started = time.monotonic()
            now = time.monotonic()
            deadlines = [a.started + timeout_s for a in actors if a.trial is not None]
            if not any(a.ready for a in actors):
                deadlines.append(min(a.created for a in actors) + RAY_STARTUP_TIMEOUT_S)
            refs = [a.ready_ref if not a.ready else a.run_ref for a in actors if not a.ready or a.trial is not None]
            done, _ = ray.wait(refs, num_returns=1, timeout=max(0.0, min(deadlines) - now))
            if done:
                done, _ = ray.wait(refs, num_returns=len(refs), timeout=0)
            finished = set(done)
            for a in list(actors):
                if not a.ready and a.ready_ref in finished:
                    try:
                        pid, niceness = ray.get(a.ready_ref)
                    except Exception as exc:  # the actor could not start
                        start_failures += 1
                        reason = _ray_error_reason(exc)
                        log.warning("a Ray worker failed to start: %s", reason)
                        missing = "No module named" in str(exc)
                        if start_failures >= _MAX_START_FAILURES or missing:
                            hint = " (every node needs pickplace installed, in the driver's version)" if missing else ""
                            raise CampaignError(f"Ray workers failed to start ({start_failures} in a row): "
                                                f"{reason}{hint}") from None
                        retire(a, "WorkerCrashed", reason)
                        continue
                    a.ready_ref = None
                    start_failures = 0
                    log.debug("Ray worker %d is up (niceness %d)", pid, niceness)
                    if niceness > 0 and not niced:
                        niced = True
                        log.info("the Ray workers run at niceness %d (RAY_worker_niceness of the cluster's nodes): "
                                 "they yield to every other process on their node", niceness)
                    if not announced and all(x.ready for x in actors):
                        announced = True
                        on_ready()
                elif a.trial is not None and a.run_ref in finished:
                    try:
                        line = ray.get(a.run_ref)
                    except Exception as exc:  # the actor died: crash, OOM kill, lost node
                        kind = "WorkerCrashed" if isinstance(exc, ray.exceptions.RayActorError) else type(exc).__name__
                        retire(a, kind, f"the Ray worker died: {_ray_error_reason(exc)}")
                        continue
                    a.trial = a.run_ref = None
                    on_result(line)
            now = time.monotonic()
            for a in list(actors):
                if a.trial is not None and now - a.started > timeout_s:
                    retire(a, "WorkerTimeout",
                           f"the trial ran past the per-trial timeout of {timeout_s:g} s (Ray worker killed)")
            if actors and not any(a.ready for a in actors) and now - min(a.created for a in actors) > \
                    RAY_STARTUP_TIMEOUT_S:
                raise CampaignError(f"no Ray worker came up within {RAY_STARTUP_TIMEOUT_S:g} s (the cluster has "
                                    f"{ray.cluster_resources().get('CPU', 0):g} CPUs; each worker needs one)")
    finally:
        for a in actors:
            with contextlib.suppress(Exception):
                ray.kill(a.handle, no_restart=True)


__all__ = ["RAY_STARTUP_TIMEOUT_S", "OnResult", "TrialActor", "run_local", "run_ray"]
