"""The one way the tools run a deck: which code, on how many ranks, in which directory, with which
variables, for how long, into which log - and the one failure they raise.

    res = run_deck("lammps", deck, {"out": out, "seed": 1}, out / "log.lammps", np_=2)
    text = res.check("in the discharge", out / "discharge.dat", marker="DEM silo end:")

Codes:
    lammps    Debian's stock LAMMPS (`lmp`, or `exe`)
    liggghts  Debian's LIGGGHTS 3.8 (`liggghts`, or `exe`), with -nocite
    hybrid    lmp_hybrid + mpm_solver --coupled in one MPMD job (tools/hybrid_launch.py composes it)
    hybrid_liggghts  liggghts_hybrid + mpm_solver --coupled (hybrid_launch.py --host liggghts)
All run with `-log LOG -screen none -var NAME VALUE ...`, more than one rank through
tools/mpirun.sh, in the log's directory unless `cwd` says otherwise. `run_mpm` runs mpm_solver
alone on a scene file (its output is the log).

A scene with twin decks describes them once as `Forms` (its LAMMPS deck, the LIGGGHTS twin, the
hybrid include), and `Forms.run(code, ...)` picks the deck and adds the hybrid twin's variables.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

TOOLS = Path(__file__).resolve().parent.parent
REPO = TOOLS.parent
SOLVER = Path(os.environ.get("HYBRID_BUILD_DIR", REPO / "build")) / "mpm_solver" / "mpm_solver"
CODES = ("lammps", "liggghts", "hybrid", "hybrid_liggghts")
HYBRID_CODES = ("hybrid", "hybrid_liggghts")


def host_dem(code: str) -> str:
    """The pure-DEM code of `code`'s DEM host: what a hybrid is compared with on its own host."""
    return "liggghts" if code in ("liggghts", "hybrid_liggghts") else "lammps"

EXECUTABLES = {"lammps": "lmp", "liggghts": "liggghts"}


class RunFailed(RuntimeError):
    """A run that exited non-zero or left out what it should have written: the message names the
    code, what it was doing, its exit status and command, and ends with its output and log tail."""


@dataclass
class Run:
    code: str
    cmd: list
    proc: subprocess.CompletedProcess
    wall: float                      # s
    log: Path | None                 # None: the program's output is its log (mpm_solver)

    def text(self) -> str:
        """The log (empty if the run wrote none)."""
        if self.log is None:
            return self.proc.stdout + self.proc.stderr
        return self.log.read_text(errors="replace") if self.log.exists() else ""

    def failed(self, what: str) -> RunFailed:
        tail = "\n".join(self.text().splitlines()[-30:])
        return RunFailed(f"{self.code} failed {what} ({self.proc.returncode}): {' '.join(map(str, self.cmd))}\n"
                         f"{self.proc.stdout[-2000:]}\n{self.proc.stderr[-2000:]}\n{tail}")

    def check(self, what: str, *outputs: Path, marker: str | None = None) -> str:
        """The log text, after making sure the run exited 0, wrote every one of `outputs` and
        logged `marker`; raises RunFailed (naming `what`) otherwise."""
        text = self.text()
        if (self.proc.returncode != 0 or not all(Path(p).exists() for p in outputs)
                or (marker is not None and marker not in text)):
            raise self.failed(what)
        return text

    def match(self, what: str, pattern: re.Pattern, *outputs: Path) -> re.Match:
        """check(), and the match of `pattern` in the log (RunFailed naming `what` without one)."""
        m = pattern.search(self.check(what, *outputs))
        if not m:
            raise self.failed(what)
        return m


def workdir(out: str | Path | None, default: str, stale: tuple = ()) -> Path:
    """A run's output directory, absolute (the codes run in it, and the paths they are given must
    hold there too): `out`, or `default` in the current directory; made, with the `stale` files a
    former run left removed (a run must not be judged by them)."""
    out = (Path(out) if out else Path.cwd() / default).resolve()
    out.mkdir(parents=True, exist_ok=True)
    for name in stale:
        (out / name).unlink(missing_ok=True)
    return out


def command(code: str, deck: Path, variables: dict, log: Path, np_: int = 1, exe: str | None = None) -> list:
    """The command line of one run (see the module docstring)."""
    args = ["-log", str(log), "-screen", "none"]
    for k, v in variables.items():
        args += ["-var", k, str(v)]
    if code in HYBRID_CODES:
        host = ["--host", "liggghts"] if host_dem(code) == "liggghts" else []
        return [sys.executable, str(TOOLS / "hybrid_launch.py"), *host, "-np", str(np_), str(deck), *args]
    if code not in EXECUTABLES:
        raise ValueError(f"unknown code {code!r} (known: {', '.join(CODES)})")
    exe = exe or shutil.which(EXECUTABLES[code])
    if exe is None:
        raise FileNotFoundError(f"{EXECUTABLES[code]} not on PATH")
    cmd = [exe, "-in", str(deck), *args] + (["-nocite"] if code == "liggghts" else [])
    return ([str(TOOLS / "mpirun.sh"), "-np", str(np_)] + cmd) if np_ > 1 else cmd


def run_deck(code: str, deck: Path, variables: dict, log: Path, np_: int = 1, exe: str | None = None,
             timeout: float = 3600, cwd: Path | None = None, threads: int | None = None) -> Run:
    """Runs `deck` with `code` and returns the Run (failures are the caller's to check, as what a
    run must leave differs: Run.check); its output goes to `log`.out too. threads: OMP_NUM_THREADS
    of the run (default: inherited)."""
    log = Path(log)
    cmd = command(code, deck, variables, log, np_, exe)
    env = dict(os.environ, OMP_NUM_THREADS=str(threads)) if threads else None
    t0 = time.time()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=cwd or log.parent, env=env)
    # beside the log: what the log does not hold (the MPM process's lines, e.g. its time ledger)
    log.with_name(log.name + ".out").write_text(proc.stdout + proc.stderr)
    return Run(code, cmd, proc, time.time() - t0, log)


def run_mpm(scene: Path, *args: str, threads: int | None = None, timeout: float = 3600,
            cwd: Path | None = None) -> Run:
    """Runs mpm_solver on a scene file (`--quiet`, then `args`) with `threads` OpenMP threads."""
    cmd = [str(SOLVER), str(scene), "--quiet", *map(str, args)]
    env = dict(os.environ, OMP_NUM_THREADS=str(threads)) if threads else None
    t0 = time.time()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=cwd, env=env)
    return Run("mpm_solver", cmd, proc, time.time() - t0, None)


@dataclass(frozen=True)
class Forms:
    """The decks of one scene, under input_decks/<scene>/: the LAMMPS deck, its LIGGGHTS twin and
    the hybrid twin's include (the hybrid runs the LAMMPS deck with `hybrid 1` and `hdeck` the
    include; None: the deck holds its hybrid twin itself); hybrid_liggghts: the LIGGGHTS-hosted
    hybrid twin's include (code hybrid_liggghts runs the LIGGGHTS deck with it)."""
    scene: str
    lammps: str = "dem_3d.lmp"
    liggghts: str | None = "liggghts_3d.in"
    hybrid: str | None = "hybrid_3d.lmp"
    hybrid_liggghts: str | None = None

    def deck(self, code: str) -> Path:
        name = self.liggghts if host_dem(code) == "liggghts" else self.lammps
        return REPO / "input_decks" / self.scene / name

    def hybrid_deck(self, code: str = "hybrid") -> Path:
        name = self.hybrid_liggghts if code == "hybrid_liggghts" else self.hybrid
        if name is None:
            raise ValueError(f"scene {self.scene} has no {code} twin")
        return REPO / "input_decks" / self.scene / name

    def variables(self, code: str, variables: dict, hybrid_vars: dict | None = None) -> dict:
        """The deck variables of `code`: the hybrid twin's (hybrid 1, hdeck, then hybrid_vars, which
        may override them) added for the hybrids."""
        if code not in HYBRID_CODES:
            return dict(variables)
        if code == "hybrid_liggghts":    # always its own include (an error for a scene without one)
            twin = {"hybrid": 1, "hdeck": self.hybrid_deck(code)}
        else:
            twin = {"hybrid": 1} | ({"hdeck": self.hybrid_deck()} if self.hybrid else {})
        return {**variables, **twin, **(hybrid_vars or {})}

    def run(self, code: str, variables: dict, log: Path, hybrid_vars: dict | None = None, **kwargs) -> Run:
        """run_deck of `code`'s form with these variables (kwargs: np_, exe, timeout, cwd, threads)."""
        return run_deck(code, self.deck(code), self.variables(code, variables, hybrid_vars), log, **kwargs)


class BackgroundJob:
    """A job (e.g. a coupled mpirun) running in its own process group while the caller watches
    its merged output, which a thread collects line by line: for kill trials and for waiting
    on a message before acting."""

    def __init__(self, cmd: list, cwd: Path | None = None, env: dict | None = None):
        self.t0 = time.monotonic()
        self.proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, errors="replace", start_new_session=True)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line)

    @property
    def text(self) -> str:
        return "".join(self.lines)

    def wait_for(self, pattern: str, timeout: float) -> re.Match | None:
        """The first match of `pattern` in the output, or None once the job has ended (and all
        its output is read) or `timeout` s have passed."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = re.search(pattern, self.text)
            if m:
                return m
            if self.proc.poll() is not None and not self.reader.is_alive():
                return None
            time.sleep(0.02)
        return None

    def wait(self, timeout: float) -> int | None:
        """The exit status, all output read; None if the job is still running after `timeout` s."""
        try:
            rc = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return None
        self.reader.join(timeout=10)
        return rc

    def kill(self):
        """SIGKILL to the whole process group (mpirun and every program it started, also
        those left behind by an mpirun that has already exited)."""
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
