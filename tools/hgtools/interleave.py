"""Side-by-side timing on a shared machine: the runs of one comparison share the same minutes,
one running at a time.

Timing a DEM run and then its hybrid twin an hour later compares two machines whenever this one's
speed drifts (on 2026-11-28 the 80k-disk DEM silo's chunks of 3,800 steps took 37 to 79 s within
one run). Here each job of a comparison runs in a forked child that leads its own session, and one
job runs at a time while the others are stopped: SIGSTOP to every process of their sessions (mpirun
gives each rank a process group of its own, but not a session), SIGCONT to resume. Each quantum
goes to the job least far along (its `progress`, e.g. the simulated time of its last discharge
record; a job without one counts as least far), so every stretch of one run is timed in the same
minutes as the same stretch of the other and a drifting machine slows both alike; jobs without
progress share the machine in turns. A job's time is the sum of its running quanta, and
`Outcome.running` converts a wall interval the job measured itself (a run's wall or loop time, which
count the stops) to running time.

It evens out the machine's speed over time (other guests of its host, its clock), not a process on
this machine competing for the cores: that slows two LAMMPS ranks stepping in lockstep more than a
run whose ranks wait for an MPM process. The 40 d silo timed beside the test suite gave its hybrid
1.94x and 2.21x, alone 1.41x and 1.35x (2026-11-28): run benchmarks alone all the same.

A stopped coupled run must not take the stop for a dead peer: the fix's reply timeout (keyword
`timeout`, 30 s by default) and the MPM process's idle timeout (600 s) must exceed the longest
stop, `max_stop`, after which a job runs a quantum whatever its progress.
"""
from __future__ import annotations

import math
import os
import pickle
import signal
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable


def no_progress() -> float | None:
    return None


@dataclass
class Job:
    name: str
    run: Callable[[], Any]                           # called in the child; its result must pickle
    progress: Callable[[], float | None] = no_progress   # how far the job is (None: not started)


@dataclass
class Outcome:
    name: str
    result: Any
    cpu_s: float                        # user + system time of the child and its descendants
    spans: list[tuple[float, float]]    # time.monotonic() intervals in which the job ran
    end: float                          # time.monotonic() at the child's exit

    @property
    def running_s(self) -> float:
        return sum(b - a for a, b in self.spans)

    def running(self, wall: float) -> float:
        """The running time within the last `wall` seconds before the job ended: a wall interval
        the job measured itself and that ended with it (its run's wall time, its loop time)."""
        start = self.end - wall
        return sum(max(0.0, b - max(a, start)) for a, b in self.spans if b > start)

    def running_share(self, wall: float) -> float:
        """The share of such a wall interval in which the job ran. A ledger of wall times the job
        kept (e.g. the fix's coupling time) counts the stops in whichever term was running, in
        proportion to the terms' running times, so the ledger times this share estimates them."""
        return self.running(wall) / wall if wall > 0 else 1.0


class Terminated(Exception):
    """SIGTERM or SIGHUP reached the process running interleave(): its jobs were killed."""


def session_pids(sid: int) -> list[int]:
    """The processes of session `sid` (from /proc)."""
    pids = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            stat = Path(entry.path, "stat").read_text()
        except OSError:    # exited meanwhile
            continue
        if int(stat[stat.rindex(")") + 2:].split()[3]) == sid:    # state ppid pgrp session ...
            pids.append(int(entry.name))
    return pids


def signal_session(sid: int, sig: int) -> None:
    """`sig` to every process of session `sid`, and again to any that appear meanwhile (a fork
    under way when the first ones stopped)."""
    sent: set[int] = set()
    for _ in range(5):
        new = [pid for pid in session_pids(sid) if pid not in sent]
        if not new:
            return
        for pid in new:
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
        sent.update(new)


def start(job: Job, result: Path) -> int:
    """Forks a child that leads a new session, runs the job and pickles (ok, result or
    traceback) to `result`; returns its pid (= its session id)."""
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid:
        return pid
    status = 1
    try:
        os.setsid()
        for sig in (signal.SIGTERM, signal.SIGHUP):    # not the parent's handlers (interleave)
            signal.signal(sig, signal.SIG_DFL)
        payload, status = (True, job.run()), 0
    except BaseException:    # noqa: B036 - reported to the parent, which raises it
        payload = (False, traceback.format_exc())
    try:
        result.write_bytes(pickle.dumps(payload))
    finally:
        os._exit(status)


def interleave(jobs: list[Job], quantum: float = 5.0, max_stop: float = 120.0, poll: float = 0.1) -> list[Outcome]:
    """Runs `jobs` one at a time in quanta of `quantum` s (module docstring) and returns their
    outcomes in order; if any job fails, the others are killed and RuntimeError names it; SIGTERM
    or SIGHUP kill them all and raise Terminated. Call it from the main thread (signal handlers)."""
    pids: dict[int, int] = {}
    spans: dict[int, list[tuple[float, float]]] = {i: [] for i in range(len(jobs))}
    ended: dict[int, tuple[int, float, float]] = {}    # job -> (wait status, CPU s, exit time)
    stopped_at: dict[int, float] = {}
    current: int | None = None

    def reap(i: int, block: bool = False) -> bool:
        pid, status, usage = os.wait4(pids[i], 0 if block else os.WNOHANG)
        if pid:
            ended[i] = (status, usage.ru_utime + usage.ru_stime, time.monotonic())
            signal_session(pid, signal.SIGKILL)    # what the job left behind does not run on
        return bool(pid)

    def order(i: int) -> tuple[float, float]:
        progress = jobs[i].progress() if i in pids else None
        return (-math.inf if progress is None else progress, sum(b - a for a, b in spans[i]))

    def terminated(signum, _frame):
        raise Terminated(f"interleave: {signal.Signals(signum).name} while the jobs ran")

    with tempfile.TemporaryDirectory(prefix="interleave_") as tmp:
        results = [Path(tmp) / f"job{i}.pickle" for i in range(len(jobs))]
        # a stopped process acts on SIGTERM only once continued: the jobs must not be left behind
        # stopped (or running) when this process is told to end
        previous = {sig: signal.signal(sig, terminated) for sig in (signal.SIGTERM, signal.SIGHUP)}
        try:
            while len(ended) < len(jobs):
                live = [i for i in range(len(jobs)) if i not in ended]
                now = time.monotonic()
                overdue = [i for i in live if i in stopped_at and now - stopped_at[i] >= max_stop]
                chosen = min(overdue, key=stopped_at.get) if overdue else min(live, key=order)
                if chosen != current:
                    if current is not None:
                        signal_session(pids[current], signal.SIGSTOP)
                        stopped_at[current] = time.monotonic()
                    if chosen in pids:
                        signal_session(pids[chosen], signal.SIGCONT)
                        del stopped_at[chosen]
                    else:
                        pids[chosen] = start(jobs[chosen], results[chosen])
                    current = chosen
                began = time.monotonic()
                while time.monotonic() - began < quantum and not reap(current):
                    time.sleep(poll)
                spans[current].append((began, ended[current][2] if current in ended else time.monotonic()))
                if current in ended:
                    if ended[current][0] != 0:    # no point in timing the others
                        break
                    current = None
        finally:    # a failure, or an exception here (KeyboardInterrupt): no job outlives the call
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            killed = [i for i in pids if i not in ended]
            for i in killed:
                signal_session(pids[i], signal.SIGKILL)
                reap(i, block=True)
        payloads = {i: pickle.loads(results[i].read_bytes()) if results[i].exists() else (False, "(no result)")
                    for i in ended}
        for i, (status, _, _) in ended.items():
            if i not in killed and (status != 0 or not payloads[i][0]):
                raise RuntimeError(f"job {jobs[i].name!r} failed (wait status {status}); the others were "
                                   f"stopped:\n{payloads[i][1]}")
        return [Outcome(job.name, payloads[i][1], ended[i][1], spans[i], ended[i][2]) for i, job in enumerate(jobs)]
