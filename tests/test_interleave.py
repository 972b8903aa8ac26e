"""tools/hgtools/interleave.py: jobs timed side by side, one running at a time (bench/scale_speed.py).

Each job here starts a worker in a process group of its own, as mpirun starts its ranks, which
burns CPU in ticks of a fixed CPU time and writes the monotonic time of each tick to its file.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from hgtools.interleave import Job, Outcome, interleave

WORKER = """
import sys, time
path, ticks, tick = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
with open(path, "w") as f:
    for _ in range(ticks):
        end = time.process_time() + tick
        while time.process_time() < end:
            pass
        f.write(f"{time.monotonic()}\\n")
        f.flush()
"""


def worker_job(name: str, path: Path, ticks: int, tick: float, fail: bool = False) -> Job:
    def run() -> int:
        proc = subprocess.Popen([sys.executable, "-c", WORKER, str(path), str(ticks), str(tick)], process_group=0)
        (path.parent / f"{name}.pid").write_text(str(proc.pid))
        if fail:
            time.sleep(0.3)
            raise ValueError(f"{name} gave up")
        return proc.wait()

    def progress() -> float | None:    # ticks done
        return len(path.read_text().split()) if path.exists() else None

    return Job(name, run, progress)


def ticks(path: Path) -> list[float]:
    return [float(x) for x in path.read_text().split()]


def test_jobs_run_one_at_a_time_in_step_and_are_timed_by_their_running_time(tmp_path):
    fast = worker_job("fast", tmp_path / "fast.txt", 30, 0.04)     # 1.2 s of CPU
    slow = worker_job("slow", tmp_path / "slow.txt", 30, 0.12)     # 3.6 s
    t0 = time.monotonic()
    out = interleave([fast, slow], quantum=0.3)
    total = time.monotonic() - t0
    assert [o.result for o in out] == [0, 0]
    # no worker ticked while the other job held the machine (a stop that missed the worker's own
    # process group would let it run on)
    for mine, other in ((out[0], out[1]), (out[1], out[0])):
        for t in ticks(tmp_path / f"{mine.name}.txt"):
            assert not any(a + 0.05 < t < b - 0.05 for a, b in other.spans), (mine.name, t)
    # the quanta went to the job less far along: the fast one kept pace with the slow one and
    # ended near the end, not after about twice its own time as in plain turns
    assert out[0].end - t0 > 0.75 * total
    # each job's time is its running quanta: the worker's CPU work, reaped through the job, fits in
    # them (a worker that ran on while stopped would use more; the machine may be shared, so no
    # upper bound on the quanta)
    for o, work in zip(out, (1.2, 3.6)):
        assert work <= o.cpu_s <= o.running_s + 0.1, (o.name, o.cpu_s, o.running_s)
        assert o.running(o.end - o.spans[0][0]) == pytest.approx(o.running_s)
        assert o.running(o.end - o.spans[-1][0]) == pytest.approx(o.spans[-1][1] - o.spans[-1][0])
    assert out[0].running_s + out[1].running_s == pytest.approx(total, rel=0.15)


def test_a_failing_job_stops_the_others_and_is_named(tmp_path):
    good = worker_job("good", tmp_path / "good.txt", 1000, 0.05)    # would take 50 s
    bad = worker_job("bad", tmp_path / "bad.txt", 1000, 0.05, fail=True)
    t0 = time.monotonic()
    with pytest.raises(RuntimeError, match="(?s)job 'bad' failed .*ValueError: bad gave up"):
        interleave([good, bad], quantum=0.3)
    assert time.monotonic() - t0 < 20
    # nothing of either job runs on: the good one's worker was stopped with it, the bad one's
    # (which its job left behind) killed as the job ended
    for name in ("good", "bad"):
        assert not running(int((tmp_path / f"{name}.pid").read_text())), name


def test_sigterm_to_the_caller_kills_every_job(tmp_path, repo):
    """A bench told to end (SIGTERM) leaves no job behind, stopped or running: a stopped process
    would act on the SIGTERM only once continued, and nothing would continue it."""
    script = f"""
import sys
sys.path[:0] = [{str(repo / 'tools')!r}, {str(Path(__file__).parent)!r}]
from pathlib import Path
from hgtools.interleave import Terminated, interleave
from test_interleave import worker_job
out = Path({str(tmp_path)!r})
try:
    interleave([worker_job(n, out / f"{{n}}.txt", 1000, 0.05) for n in ("one", "two")], quantum=0.3)
except Terminated as e:
    print(e)
    sys.exit(3)
"""
    caller = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 20
    while not all((tmp_path / f"{n}.txt").exists() for n in ("one", "two")) and time.monotonic() < deadline:
        time.sleep(0.1)    # both jobs started: one of them is stopped now
    caller.terminate()
    out, _ = caller.communicate(timeout=30)
    assert caller.returncode == 3 and "SIGTERM while the jobs ran" in out
    for name in ("one", "two"):
        assert not running(int((tmp_path / f"{name}.pid").read_text())), name


def running(pid: int) -> bool:
    """The process exists and is not a zombie (a killed orphan waits for init to reap it)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def test_running_share_of_an_interval_that_ended_with_the_job():
    # ran 0-10 s and 30-40 s, stopped between: of its whole 40 s half ran, of its last 15 s two thirds
    o = Outcome(name="hybrid", result=None, cpu_s=0.0, spans=[(0.0, 10.0), (30.0, 40.0)], end=40.0)
    assert o.running(40.0) == pytest.approx(20.0)
    assert o.running_share(40.0) == pytest.approx(0.5)
    assert o.running_share(15.0) == pytest.approx(10.0 / 15.0)
    assert o.running_share(0.0) == 1.0
