#!/usr/bin/env python3
"""Coupling overhead of fix hybrid/mpm: LAMMPS loop time per step of a coupled run versus the
same LAMMPS run without the fix, with the hybrid (coupled) grains about 15 % of all grains.

The deck is input_decks/hybrid/overhead_2d.lmp: a 2D bed of touching 2 mm disks under gravity
on a floor, whose lower part is continuum. Both cases integrate the same grains: without the fix
(`-var couple 0`, lmp_hybrid alone through tools/mpirun.sh) the deck deletes the grains the fix
would turn into material points and puts the floor under the lowest remaining row; with the fix
(`-var couple 1`, tools/hybrid_launch.py, one MPM process) they become points at step 1. Each
run has a warm-up run (the conversion, the bed taking its weight) and then the timed run, whose
"Loop time" and timing breakdown are read from the LAMMPS log. The cases run interleaved, the
whole set repeated; the tables give medians. With --profile, one more run per case is recorded
with perf to split the fix's cost into its own DEM-side work and the wait for the MPM process.

Target (project brief): overhead <= 5 % of a LAMMPS step when hybrid grains are <= 20 %.

Usage: bench/coupling_overhead.py [--quick] [--reps N] [--every 1 10] [--np 1] [--profile] [--keep DIR]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import resource
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DECK = REPO / "input_decks" / "hybrid" / "overhead_2d.lmp"
LMP = REPO / "build" / "lammps_fix_hybrid" / "lmp_hybrid"
MPM = REPO / "build" / "mpm_solver" / "mpm_solver"
BUILD = REPO / "build"
MPIRUN = REPO / "tools" / "mpirun.sh"
LAUNCH = REPO / "tools" / "hybrid_launch.py"
TARGET = 0.05          # overhead of a LAMMPS step
DISTURBED = 0.25       # other processes kept this many cores busy on average during a run: left out
RUN_TIMEOUT = 180.0    # s, one LAMMPS job

SIZES = {  # bed width (m), timed steps, warm-up steps
    "full": {"width": 1.0, "nsteps": 2000, "warmup": 500},
    "quick": {"width": 0.5, "nsteps": 500, "warmup": 200},
}


# ----------------------------------------------------------------------------- one run

def snapshot_binaries(work: Path, settle: float = 20.0, max_wait: float = 300.0) -> dict:
    """Copies lmp_hybrid and mpm_solver into work/ so that every run of the benchmark uses the same binaries
    (build/ may be rebuilt meanwhile); waits until neither was written in the last `settle` seconds."""
    global LMP, MPM, BUILD
    t0 = time.time()
    while time.time() - t0 < max_wait:
        if all(time.time() - exe.stat().st_mtime > settle for exe in (LMP, MPM)):
            break
        time.sleep(5)
    build = work / "build"
    (build / "lammps_fix_hybrid").mkdir(parents=True)
    (build / "mpm_solver").mkdir()
    programs = json.loads((REPO / "build" / "lammps_fix_hybrid" / "hybrid_programs.json").read_text())
    info = {}
    for exe, sub in ((LMP, "lammps_fix_hybrid"), (MPM, "mpm_solver")):
        copy = build / sub / exe.name
        shutil.copy2(exe, copy)
        info[exe.name] = {"built": datetime.fromtimestamp(exe.stat().st_mtime, timezone.utc)
                          .strftime("%Y-%m-%d %H:%M:%S UTC"),
                          "sha256": hashlib.sha256(copy.read_bytes()).hexdigest()[:16]}
        programs[exe.name] = str(copy)
    (build / "lammps_fix_hybrid" / "hybrid_programs.json").write_text(json.dumps(programs, indent=1))
    LMP, MPM, BUILD = build / "lammps_fix_hybrid" / "lmp_hybrid", build / "mpm_solver" / "mpm_solver", build
    return info


def case_command(case: dict, size: dict, log: Path) -> list[str]:
    lammps_vars = ["-var", "couple", "1" if case["couple"] else "0", "-var", "trim", "1" if case["trim"] else "0",
                   "-var", "every", str(case.get("every", 1)), "-var", "width", str(size["width"]),
                   "-var", "nsteps", str(size["nsteps"]), "-var", "warmup", str(size["warmup"]),
                   "-log", str(log)]
    if case["couple"]:
        return [sys.executable, str(LAUNCH), "--build", str(BUILD), "-np", str(case["np"]), str(DECK), *lammps_vars]
    return [str(MPIRUN), "-np", str(case["np"]), str(LMP), "-in", str(DECK), *lammps_vars]


def cpu_times() -> tuple[float, float, float]:
    """(total, steal, busy) seconds of all CPUs together, from /proc/stat."""
    values = [float(x) / os.sysconf("SC_CLK_TCK") for x in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
    total = sum(values[:8])
    return total, values[7] if len(values) > 7 else 0.0, total - values[3] - values[4]


def children_cpu() -> float:
    """CPU seconds of all finished descendants (mpirun, LAMMPS, mpm_solver, ...)."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def parse_log(text: str) -> dict:
    """The last run of a LAMMPS log: loop time, timing breakdown, CPU use, last thermo line."""
    loops = list(re.finditer(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms", text))
    if not loops:
        raise ValueError("no 'Loop time' line in the log")
    last = loops[-1]
    out = {"loop_time": float(last.group(1)), "procs": int(last.group(2)), "steps": int(last.group(3)),
           "atoms": int(last.group(4))}
    tail = text[last.end():]
    m = re.search(r"([0-9.]+)% CPU use", tail)
    out["cpu_use_percent"] = float(m.group(1)) if m else None
    sections = {}
    for name in ("Pair", "Neigh", "Comm", "Output", "Modify", "Other"):
        m = re.search(rf"^{name}\s*\|([^\n]*)$", tail, re.M)
        if m:
            cols = [c.strip() for c in m.group(1).split("|")]
            # Section | min | avg | max | %varavg | %total ("Other" has min, max empty)
            sections[name] = float(cols[1]) if cols[1] else None
    out["sections"] = sections
    # the fix's own timing block of the same run (printed before its Loop line): where its time in
    # Modify went, the ranks' mean (coupler/coupling_timer.hpp: Exchange = its own work around the
    # round trip, MPM wait, Apply = the grains' velocity updates)
    run_text = text[loops[-2].end() if len(loops) > 1 else 0:last.start()]
    fix = {}
    for name in ("Exchange", "MPM wait", "Apply", "Rezone", "Oracle", "Output", "Coupling"):
        m = re.search(rf"^{name}\s*\|([^\n]*)$", run_text, re.M)
        if m:
            fix[name] = float(m.group(1).split("|")[1])
    out["fix_sections"] = fix
    # the pair style loops over the neighbour list's pairs and computes forces for the touching ones
    m = re.search(r"^Total # of neighbors = (\d+)", tail, re.M)
    out["neighbor_pairs"] = int(m.group(1)) if m else None
    # thermo block of the last run: header "Step ..." then rows, up to the Loop line
    head = text[:last.start()]
    headers = list(re.finditer(r"^\s*Step\s.*$", head, re.M))
    if headers:
        names = headers[-1].group(0).split()
        rows = [ln.split() for ln in head[headers[-1].end():].splitlines()]
        rows = [r for r in rows if len(r) == len(names) and re.fullmatch(r"-?\d+", r[0])]
        if rows:
            out["thermo"] = {n: float(v) for n, v in zip(names, rows[-1])}
            if "c_contacts" in names:   # contacts at the thermo steps of the timed run (start, ..., end)
                k = names.index("c_contacts")
                out["contacts"] = [float(r[k]) / 2 for r in rows]
    m = re.search(r"fix hybrid/mpm: step \d+: (\d+) grains became (\d+) material points, (\d+) grains are hybrid", text)
    if m:
        out["converted_grains"], out["points"], out["hybrid_grains"] = (int(g) for g in m.groups())
    return out


def busy_cores(interval: float = 1.0) -> float:
    """Cores kept busy (by anybody) over `interval` seconds, from /proc/stat."""
    def sample():
        v = [float(x) for x in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
        return sum(v[:8]), v[3] + v[4]   # total, idle + iowait
    t0, i0 = sample()
    time.sleep(interval)
    t1, i1 = sample()
    return (os.cpu_count() or 1) * (1.0 - (i1 - i0) / max(t1 - t0, 1.0))


def wait_for_quiet(limit: float, max_wait: float) -> float:
    """Waits (at most max_wait s) until other processes keep fewer than `limit` cores busy; returns the last
    measured load in cores."""
    t0 = time.time()
    while True:
        b = busy_cores()
        if b < limit or time.time() - t0 > max_wait:
            return b


def run_case(case: dict, size: dict, work: Path, tag: str, quiet: tuple[float, float] = (0.3, 0.0)) -> dict:
    log = work / f"{tag}.log"
    cmd = case_command(case, size, log)
    env = dict(os.environ, OMP_NUM_THREADS="1")   # LAMMPS and mpm_solver: one thread each
    others = wait_for_quiet(*quiet) if quiet[1] > 0 else None
    load = os.getloadavg()[0]
    tot0, st0, busy0 = cpu_times()
    own0 = children_cpu()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=RUN_TIMEOUT)
    wall = time.perf_counter() - t0
    tot1, st1, busy1 = cpu_times()
    own = children_cpu() - own0
    (work / f"{tag}.out").write_text(proc.stdout)
    if proc.returncode != 0:
        sys.exit(f"coupling_overhead: {shlex.join(cmd)} failed (exit {proc.returncode}):\n{proc.stdout[-3000:]}")
    r = parse_log(log.read_text())
    r.update(case=case["name"], job_wall_s=wall, loadavg_1min_before=load, busy_cores_before=others,
             steal_percent=100.0 * (st1 - st0) / max(tot1 - tot0, 1e-9),
             # cores kept busy by other processes during the job (all busy CPU time less this job's)
             others_cores=max(0.0, (busy1 - busy0) - own) / wall)
    r["disturbed"] = r["others_cores"] > DISTURBED
    r["step_s"] = r["loop_time"] / r["steps"]
    return r


# ----------------------------------------------------------------------------- profile (perf)

def descendants(pid: int) -> dict[int, str]:
    """pid -> comm of all processes below pid."""
    children: dict[int, list[int]] = {}
    comm: dict[int, str] = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        name = stat[stat.index("(") + 1:stat.rindex(")")]
        ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        children.setdefault(ppid, []).append(int(d.name))
        comm[int(d.name)] = name
    out, todo = {}, [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out[c] = comm[c]
            todo.append(c)
    return out


LAMMPS_GROUPS = [  # (group, regex on "dso symbol"), first match wins
    ("fix hybrid/mpm: waiting for the MPM process (poll, yield, sleep, MPI)",
     r"\[k\]|sched_yield|nanosleep|clock_gettime|mca_|libmpi|libopen-pal|libopen-rte|opal_|ompi_|PMPI_|"
     r"coupler::recv_message|coupler::Link|Backoff|libucs|libuct|libucp|libfabric|libevent|libhwloc"),
    ("fix hybrid/mpm: own DEM-side work (grains to nodes, updates, zone lookups)",
     r"FixHybridMPM|coupler::"),
    ("LAMMPS: pair", r"Pair"),
    ("LAMMPS: other (integration, walls, neighbor, ...)", r"LAMMPS_NS::"),
    ("libc (memcpy, memset, malloc; both)", r"libc|libstdc"),
]
MPM_GROUPS = [
    ("waiting for LAMMPS (poll, yield, sleep, MPI)",
     r"\[k\]|sched_yield|nanosleep|clock_gettime|mca_|libmpi|libopen-pal|opal_|ompi_|PMPI_|coupler::recv_message|"
     r"coupler::Link|libevent|libhwloc"),
    ("MPM step (P2G, grid, G2P, model) and the agreement", r"mpm::|coupler::"),
    ("libc (memcpy, memset, malloc)", r"libc|libstdc|libgomp"),
]


def perf_groups(data: Path, groups: list[tuple[str, str]]) -> dict:
    """Self samples of a perf.data file summed by groups of symbols."""
    text = subprocess.run(["perf", "report", "-i", str(data), "--stdio", "--no-children", "-n", "-g", "none",
                           "--sort", "dso,sym", "-t", "\t", "--percent-limit", "0"],
                          stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True).stdout
    sums = {g: 0 for g, _ in groups}
    sums["other"] = 0
    by_group: dict[str, dict[str, int]] = {g: {} for g, _ in groups}
    top: list[tuple[int, str]] = []
    for line in text.splitlines():
        if line.startswith("#") or not line.strip():
            continue
        parts = line.split("\t")
        if len(parts) < 4:
            continue
        try:
            samples = int(parts[1].strip())
        except ValueError:
            continue
        key = f"{parts[2].strip()} {parts[3].strip()}"
        top.append((samples, key))
        for g, rx in groups:
            if re.search(rx, key):
                sums[g] += samples
                short = short_symbol(parts[3].strip())
                by_group[g][short] = by_group[g].get(short, 0) + samples
                break
        else:
            sums["other"] += samples
    top.sort(reverse=True)
    tops = {g: sorted(d.items(), key=lambda kv: -kv[1])[:6] for g, d in by_group.items()}
    return {"groups": sums, "total": sum(sums.values()), "top": top[:12], "top_by_group": tops}


def short_symbol(sym: str) -> str:
    """'[.] std::__merge_sort_with_buffer<...coupler::grains_to_nodes<2>...>' -> 'std::__merge_sort_with_buffer
    (in coupler::grains_to_nodes)'; template arguments and parameters dropped."""
    sym = re.sub(r"^\[[.k]\]\s*", "", sym)
    head = re.split(r"[<(]", sym, maxsplit=1)[0]
    if head.startswith("std::") or "lambda" in sym:
        inner = re.findall(r"((?:coupler|mpm|LAMMPS_NS)::[A-Za-z_:]+)", sym)
        if inner and not head.startswith(inner[0]):
            return f"{head} (in {inner[0]})"
    return head


def schedstat(tid: int) -> tuple[float, float]:
    """(seconds on a CPU, seconds runnable but waiting for a CPU) of one thread."""
    try:
        on, wait, _ = Path(f"/proc/{tid}/schedstat").read_text().split()
        return float(on) * 1e-9, float(wait) * 1e-9
    except (OSError, ValueError):
        return 0.0, 0.0


def profile_case(case: dict, size: dict, work: Path, seconds: float, freq: int = 997) -> dict:
    """perf record (cpu-clock) of the main threads of the LAMMPS rank and of the MPM process during the timed
    run, with their scheduler statistics (time on a CPU, time waiting for one) over the same window."""
    tag = f"profile_{case['name']}"
    log = work / f"{tag}.log"
    cmd = case_command(case, size, log)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    wait_for_quiet(0.3, 30.0)
    out = open(work / f"{tag}.out", "w")
    proc = subprocess.Popen(cmd, cwd=work, env=env, stdout=out, stderr=subprocess.STDOUT, text=True)
    try:
        t0 = time.time()
        while True:   # the timed run has started when its thermo header is in the log
            if proc.poll() is not None:
                raise RuntimeError(f"the profiled run ended early (exit {proc.returncode})")
            if log.exists() and len(re.findall(r"^\s*Step\s", log.read_text(), re.M)) >= 2:
                break
            if time.time() - t0 > RUN_TIMEOUT:
                raise RuntimeError("the profiled run did not reach its timed run")
            time.sleep(0.05)
        targets = {name: pid for pid, name in descendants(proc.pid).items() if name in ("lmp_hybrid", "mpm_solver")}
        before = {name: schedstat(pid) for name, pid in targets.items()}
        w0 = time.perf_counter()
        perfs = [subprocess.Popen(["perf", "record", "-q", "-e", "cpu-clock", "-F", str(freq), "-t", str(pid),
                                   "-o", str(work / f"{tag}.{name}.data"), "--", "sleep", str(seconds)],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                 for name, pid in targets.items()]
        for p in perfs:
            p.wait()
        window = time.perf_counter() - w0
        after = {name: schedstat(pid) for name, pid in targets.items()}
        if any(a[0] < b[0] for a, b in zip(after.values(), before.values())) or not targets:
            raise RuntimeError(f"the profiled processes of {case['name']} ended inside the perf window "
                               f"({targets}, {before}, {after}, {time.perf_counter() - w0:.1f} s)")
        proc.wait(timeout=RUN_TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.terminate()
        out.close()
    run = parse_log(log.read_text())
    step_s = run["loop_time"] / run["steps"]
    res = {"case": case["name"], "window_s": window, "step_s": step_s, "steps_in_window": window / step_s,
           "sections": run["sections"], "processes": {}}
    for name, groups in (("lmp_hybrid", LAMMPS_GROUPS), ("mpm_solver", MPM_GROUPS)):
        data = work / f"{tag}.{name}.data"
        if name in targets and data.exists():
            g = perf_groups(data, groups)
            on = after[name][0] - before[name][0]
            runq = after[name][1] - before[name][1]
            g.update(on_cpu_s=on, runqueue_s=runq, sleep_s=max(0.0, window - on - runq))
            # per LAMMPS step (ms): the samples split the measured CPU time
            scale = 1e3 * on / max(g["total"], 1) / res["steps_in_window"]
            g["ms_per_step"] = {k: v * scale for k, v in g["groups"].items()}
            g["ms_per_step"].update(on_cpu=1e3 * on / res["steps_in_window"],
                                    runqueue=1e3 * runq / res["steps_in_window"],
                                    sleep=1e3 * g["sleep_s"] / res["steps_in_window"])
            g["top_ms_per_step"] = {k: [(n, v * scale) for n, v in items] for k, items in g["top_by_group"].items()}
            res["processes"][name] = g
    return res


# ----------------------------------------------------------------------------- report

def git(*a: str) -> str:
    """Read-only git queries (revision, status) for the report."""
    return subprocess.run(["git", *a], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                          text=True).stdout.rstrip()


def med(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def summarize(cases: list[dict], runs: list[dict]) -> dict:
    """Per case: the medians over its runs (those not disturbed by other processes, if two or more
    remain), and for a coupled case its overhead against the uncoupled case with the same ranks and the
    fix's own ledger of its cost."""
    summary = {}
    for case in cases:
        every_run = [r for r in runs if r["case"] == case["name"]]
        clean = [r for r in every_run if not r["disturbed"]]
        rs = clean if len(clean) >= 2 else every_run
        th = rs[-1].get("thermo", {})
        s = {"np": case["np"], "couple": case["couple"], "every": case["every"] if case["couple"] else None,
             "atoms": rs[-1]["atoms"], "runs": len(rs),
             "step_ms": 1e3 * med([r["step_s"] for r in rs]),
             "step_ms_all": [1e3 * r["step_s"] for r in every_run],
             "disturbed": [r["disturbed"] for r in every_run],
             "step_ms_used": [1e3 * r["step_s"] for r in rs],
             "pair_ms": 1e3 * med([(r["sections"].get("Pair") or 0) / r["steps"] for r in rs]),
             "modify_ms": 1e3 * med([(r["sections"].get("Modify") or 0) / r["steps"] for r in rs]),
             "modify_share": med([(r["sections"].get("Modify") or 0) / r["loop_time"] for r in rs]),
             "cpu_use_percent": med([r["cpu_use_percent"] for r in rs]),
             "contacts_mean": med([statistics.mean(r["contacts"]) for r in rs if r.get("contacts")]),
             "neighbor_pairs": med([r["neighbor_pairs"] for r in rs if r.get("neighbor_pairs") is not None])}
        if case["couple"]:
            s["coupled_grains"] = int(th.get("f_couple[2]", 0))
            s["points"] = int(th.get("f_couple[3]", 0))
            s["substeps_per_exchange"] = th.get("f_couple[6]")
            s["coupled_fraction"] = s["coupled_grains"] / s["atoms"] if s["atoms"] else None
            s["converted_grains"] = rs[-1].get("converted_grains")
            # the fix's own ledger of its cost: its work (Exchange + Apply) and the MPM wait, per exchange
            for key, names in (("fix_work_ms_per_exchange", ("Exchange", "Apply")),
                               ("mpm_wait_ms_per_exchange", ("MPM wait",))):
                values = [1e3 * sum(r["fix_sections"].get(n, 0.0) for n in names) * case["every"] / r["steps"]
                          for r in rs if "Exchange" in r.get("fix_sections", {})]
                s[key] = med(values) if values else None
            # the fix's whole time (its timing block's Coupling line) over the same run's loop time: a share
            # measured within one run, free of the machine's drift between the coupled and uncoupled runs
            shares = [r["fix_sections"]["Coupling"] / r["loop_time"] for r in rs if "Coupling" in r.get("fix_sections", {})]
            s["fix_share"] = med(shares) if shares else None
        summary[case["name"]] = s
    for case in cases:
        s = summary[case["name"]]
        if not case["couple"]:
            continue
        base = summary[f"np{case['np']}_lammps"]
        s["overhead"] = s["step_ms"] / base["step_ms"] - 1.0
        # paired by repetition: the two runs of one repetition were close in time
        pairs = [(c["step_s"] / b["step_s"] - 1.0, c["disturbed"] or b["disturbed"])
                 for c in runs if c["case"] == case["name"]
                 for b in runs if b["case"] == f"np{case['np']}_lammps" and b["rep"] == c["rep"]]
        s["overhead_paired"] = [p for p, _ in pairs]
        s["overhead_paired_disturbed"] = [d for _, d in pairs]
        s["overhead_fastest"] = min(s["step_ms_all"]) / min(base["step_ms_all"]) - 1.0
        s["fix_ms_per_step"] = s["modify_ms"] - base["modify_ms"]
        s["fix_ms_per_exchange"] = s["fix_ms_per_step"] * case["every"]
        s["pair_change"] = s["pair_ms"] / base["pair_ms"] - 1.0
    return summary


def main() -> int:
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--quick", action="store_true", help="smaller bed (about 10,000 grains in LAMMPS) and fewer steps")
    ap.add_argument("--reps", type=int, help="repetitions of the interleaved set (default 5, --quick 3)")
    ap.add_argument("--quiet-wait", type=float, default=60.0,
                    help="before each run wait at most this long (s) for other processes to use less than 0.3 "
                         "cores (the machine is shared; default 60, 0 = do not wait)")
    ap.add_argument("--every", type=int, nargs="+", default=[1, 10], help="exchange intervals (default 1 10)")
    ap.add_argument("--np", type=int, nargs="+", default=[1], help="LAMMPS ranks (default 1; the MPM process is extra)")
    ap.add_argument("--nsteps", type=int, help="timed steps per run (default 2000, --quick 500)")
    ap.add_argument("--no-full-dem", action="store_true",
                    help="skip the reference run of the whole bed as DEM (no continuum, no fix)")
    ap.add_argument("--profile", action="store_true",
                    help="afterwards, perf-record the LAMMPS rank and the MPM process of each coupled case once "
                         "(where the time of the fix goes: waiting for the MPM process or its own DEM-side work)")
    ap.add_argument("--keep", type=Path, help="keep the logs in this directory")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "coupling_overhead.md")
    args = ap.parse_args()
    for exe in (LMP, MPM):
        if not exe.exists():
            sys.exit(f"{exe} is not built; run tools/setup.sh first")
    size = dict(SIZES["quick" if args.quick else "full"])
    if args.reps is None:
        args.reps = 3 if args.quick else 5
    if args.nsteps:
        size["nsteps"] = args.nsteps

    cases = []
    for np_ in args.np:
        cases.append({"name": f"np{np_}_lammps", "np": np_, "couple": False, "trim": True, "every": 1})
        for e in args.every:
            cases.append({"name": f"np{np_}_coupled_every{e}", "np": np_, "couple": True, "trim": True, "every": e})
        if not args.no_full_dem:
            cases.append({"name": f"np{np_}_full_dem", "np": np_, "couple": False, "trim": False, "every": 1})

    runs: list[dict] = []
    tmp = tempfile.mkdtemp(prefix="coupling_overhead_")
    work = Path(tmp)
    try:
        head = git("rev-parse", "--short", "HEAD")
        dirty = [ln[3:] for ln in git("status", "--porcelain", "--", "coupler", "lammps_fix_hybrid",
                                      "mpm_solver").splitlines()]
        binaries = snapshot_binaries(work)
        for rep in range(args.reps):
            k = rep % len(cases)
            for case in cases[k:] + cases[:k]:   # interleaved, the order rotating between repetitions
                r = run_case(case, size, work, f"{case['name']}_rep{rep}", (0.3, args.quiet_wait))
                r["rep"] = rep
                runs.append(r)
                print(f"rep {rep} {case['name']:24s} {1e3 * r['step_s']:8.3f} ms/step{'*' if r['disturbed'] else ' '} "
                      f"(Modify {1e3 * (r['sections'].get('Modify') or 0) / r['steps']:.3f} ms/step, "
                      f"CPU use {r['cpu_use_percent']} %; other processes: {r['others_cores']:.2f} cores during "
                      f"the run, {r['busy_cores_before'] or 0:.2f} before)", flush=True)
        profiles = []
        if args.profile:
            if shutil.which("perf") is None:
                print("coupling_overhead: perf not found; no profile", file=sys.stderr)
            else:
                window = 3.0   # s of perf record, at the start of a timed run expected to last 3 times longer
                for case in cases:
                    if case["couple"] or case["trim"]:
                        step = min(r["step_s"] for r in runs if r["case"] == case["name"])
                        psize = dict(size, nsteps=max(size["nsteps"], int(3.0 * window / step)))
                        profiles.append(profile_case(case, psize, work, seconds=window))
    finally:
        if args.keep:
            args.keep.mkdir(parents=True, exist_ok=True)
            for f in work.iterdir():
                if f.suffix in (".log", ".out"):
                    shutil.copy2(f, args.keep / f.name)
        shutil.rmtree(work, ignore_errors=True)

    summary = summarize(cases, runs)

    # ---- build state (others may be rebuilding build/ from an edited tree; the runs used copies)
    build_note = ("All runs used copies of build/'s " +
                  ", ".join(f"{k} (built {v['built']})" for k, v in binaries.items()) +
                  f"; the tree was at commit {head}" +
                  (f" with uncommitted changes to {', '.join(dirty)}" if dirty else "") + ".")

    # ---- markdown
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    argv = " ".join(shlex.quote(a) for a in sys.argv[1:])
    command = f"bench/coupling_overhead.py{(' ' + argv) if argv else ''}"
    any_c = next(s for s in summary.values() if s["couple"])
    lam = summary[f"np{args.np[0]}_lammps"]
    loads = [r["loadavg_1min_before"] for r in runs]
    steal = [r["steal_percent"] for r in runs]
    busy = [r["busy_cores_before"] or 0.0 for r in runs]
    lines = [
        f"# Coupling overhead of fix hybrid/mpm ({stamp}, {os.cpu_count()} cores)", "",
        f"Measured: the LAMMPS loop time per step (the timed `run` of `input_decks/hybrid/overhead_2d.lmp`, "
        f"{size['nsteps']} steps after a {size['warmup']}-step warm-up) of a 2D bed of 2 mm disks under gravity, "
        f"{lam['atoms']} grains in LAMMPS, coupled by `fix hybrid/mpm` to one `mpm_solver --coupled` process "
        f"(tools/hybrid_launch.py; {any_c['coupled_grains']} coupled grains = "
        f"{100 * any_c['coupled_fraction']:.1f} % of the grains, {any_c['points']} material points made from "
        f"{any_c['converted_grains']} grains of the continuum), against the same grains without the fix "
        f"(lmp_hybrid alone through tools/mpirun.sh, the converted grains deleted and the floor moved under the "
        f"lowest remaining row). LAMMPS on {', '.join(map(str, args.np))} rank(s), one thread; all cases "
        f"interleaved, {args.reps} repetitions, medians. Overhead = coupled / uncoupled - 1, target <= "
        f"{100 * TARGET:.0f} % with hybrid grains <= 20 %. Made by `{command}`. The machine is shared: each "
        f"run waited (up to {args.quiet_wait:.0f} s) for other processes to use less than 0.3 cores; they used "
        f"{min(busy):.2f}-{max(busy):.2f} cores just before the runs (1-minute load average "
        f"{min(loads):.2f}-{max(loads):.2f}), steal {max(steal):.1f} % at most. Runs during which other processes "
        f"kept more than {DISTURBED} cores busy on average are marked * and left out of the medians (unless fewer "
        f"than 2 runs of the case remain); {sum(r['disturbed'] for r in runs)} of {len(runs)} were. {build_note}", "",
        "| case | grains in LAMMPS | coupled grains | MPM points | MPM substeps per exchange | ms per step, median "
        "(runs) | overhead, median (paired by repetition) | Pair ms/step | neighbour pairs | contacts | Pair ns per "
        "contact | Modify ms/step (share of the step) | fix cost per exchange | LAMMPS CPU use |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    verdicts = []
    for case in cases:
        s = summary[case["name"]]
        base = summary[f"np{case['np']}_lammps"]
        ranks = f", {case['np']} LAMMPS rank(s)" if len(args.np) > 1 else ""
        if case["couple"]:
            label = f"coupled, every {case['every']}{ranks}"
            cg = f"{s['coupled_grains']} ({100 * s['coupled_fraction']:.1f} %)"
            pts, sub = str(s["points"]), f"{s['substeps_per_exchange']:.0f}"
            paired = ", ".join(f"{100 * p:+.0f}{'*' if d else ''}"
                               for p, d in zip(s["overhead_paired"], s["overhead_paired_disturbed"]))
            ovh = f"**{100 * s['overhead']:+.1f} %** ({paired} %; fastest runs {100 * s['overhead_fastest']:+.1f} %)"
            fix = f"{s['fix_ms_per_exchange']:.3f} ms"
            if s.get("fix_work_ms_per_exchange") is not None:
                fix += f" ({s['fix_work_ms_per_exchange']:.3f} own work, {s['mpm_wait_ms_per_exchange']:.3f} MPM wait)"
            if s.get("fix_share") is not None:
                fix += f"; {100 * s['fix_share']:.1f} % of the step"
            factor = s["overhead"] / TARGET
            verdict = "met" if s["overhead"] <= TARGET else f"{factor:.1f}x the target"
            own = ""
            if s.get("fix_share") is not None:
                own_verdict = "met" if s["fix_share"] <= TARGET else f"{s['fix_share'] / TARGET:.1f}x the target"
                own = f", the fix's own time {100 * s['fix_share']:.1f} % of the step ({own_verdict})"
            verdicts.append(f"every {case['every']}{ranks}: step {100 * s['overhead']:+.1f} % against the uncoupled "
                            f"runs ({verdict}){own}")
        else:
            label = (f"LAMMPS alone, same grains{ranks}" if case["trim"]
                     else f"LAMMPS alone, whole bed as DEM (reference){ranks}")
            cg, pts, sub, ovh, fix = "-", "-", "-", "-", "-"
            if not case["trim"]:
                ovh = f"({100 * (s['step_ms'] / base['step_ms'] - 1):+.1f} % vs. the same grains)"
        runs_ms = ", ".join(f"{v:.2f}{'*' if d else ''}" for v, d in zip(s["step_ms_all"], s["disturbed"]))
        lines.append(f"| {label} | {s['atoms']} | {cg} | {pts} | {sub} | {s['step_ms']:.3f} ({runs_ms}) | {ovh} | "
                     f"{s['pair_ms']:.3f} | {s['neighbor_pairs'] or 0:.0f} | {s['contacts_mean'] or 0:.0f} | "
                     f"{1e6 * s['pair_ms'] / s['contacts_mean'] if s['contacts_mean'] else 0:.1f} | "
                     f"{s['modify_ms']:.3f} ({100 * s['modify_share']:.0f} %) | {fix} | "
                     f"{s['cpu_use_percent']:.0f} % |")
    lines += ["", f"Target <= {100 * TARGET:.0f} %: " + "; ".join(verdicts) + "."]
    lines += ["", "Modify is the LAMMPS timer section that holds the fixes (here nve/sphere, gravity, wall/gran, "
              "enforce2d and, coupled, hybrid/mpm, whose exchange runs in end_of_step and includes the wait for "
              "the MPM process); the fix cost per exchange is the coupled minus the uncoupled Modify time per step, "
              "times the exchange interval; in brackets the fix's own ledger of it (its timing block, the ranks' "
              "mean): its own work (checks, the grains' node sums, the coupled grains, the velocity updates) and the "
              "wait for the MPM process's reply; after them the fix's whole time (its timing block's 'Coupling') "
              "as a share of the same runs' loop time. That share is measured within each run, while the step's "
              "overhead compares runs minutes apart on a machine whose speed drifts (single runs of one case differ "
              "by up to 30 %) and includes any difference in the pair work between the two beds (the coupled grains "
              "move with the continuum and touch more often, see 'contacts'). 'LAMMPS CPU use' is LAMMPS's own figure (CPU time "
              "over wall time): "
              "below 100 % the rank slept (waiting) or was descheduled. 'contacts' are the touching grain pairs "
              "(mean over 11 thermo steps of the timed run, median over the runs), 'neighbour pairs' LAMMPS's "
              "'Total # of neighbors' at the end of the timed run: the pair style visits every neighbour pair and "
              "computes the force of the touching ones, so its cost follows both, and they differ a little between "
              "the cases (the coupled grains move with the continuum). "
              "The whole-bed row is the DEM run the "
              "continuum replaces; its 'overhead' column is its cost relative to the uncoupled row."]

    if profiles:
        L, M = [g for g, _ in LAMMPS_GROUPS], [g for g, _ in MPM_GROUPS]
        lines += ["", "## Where the time goes (perf, one more run per case)", "",
                  "ms per LAMMPS step, from `perf record -e cpu-clock` of the main threads of the LAMMPS rank and "
                  "the MPM process during the timed run, scaled to their CPU time in /proc/PID/schedstat; 'sleeping' "
                  "is the rest of the wall time less the time waiting for a CPU (descheduled, e.g. by other users' "
                  "processes). The profiled runs are slower than the timed ones (perf itself).", "",
                  "| case | LAMMPS ms/step | pair | other LAMMPS work | fix: own DEM-side work | fix: polling the MPM "
                  "process | libc | LAMMPS sleeping | LAMMPS descheduled | MPM: step and agreement | MPM: polling | "
                  "MPM sleeping |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for p in profiles:
            lg = p["processes"].get("lmp_hybrid", {}).get("ms_per_step", {})
            mg = p["processes"].get("mpm_solver", {}).get("ms_per_step", {})
            f = lambda d, k: f"{d[k]:.3f}" if k in d else "-"
            lines.append(f"| {p['case']} | {1e3 * p['step_s']:.3f} | {f(lg, L[2])} | {f(lg, L[3])} | {f(lg, L[1])} | "
                         f"{f(lg, L[0])} | {f(lg, L[4])} | {f(lg, 'sleep')} | {f(lg, 'runqueue')} | {f(mg, M[1])} | "
                         f"{f(mg, M[0])} | {f(mg, 'sleep')} |")
        ref = next((p for p in profiles if not next(c for c in cases if c["name"] == p["case"])["couple"]), None)
        lines.append("")
        for p in profiles:
            case = next(c for c in cases if c["name"] == p["case"])
            if not case["couple"] or "lmp_hybrid" not in p["processes"]:
                continue
            e = case["every"]
            lg = p["processes"]["lmp_hybrid"]["ms_per_step"]
            mg = p["processes"].get("mpm_solver", {}).get("ms_per_step", {})
            work_ms = lambda d: d[L[2]] + d[L[3]]
            delta = (f"{work_ms(lg) - work_ms(ref['processes']['lmp_hybrid']['ms_per_step']):+.3f} ms per step"
                     if ref and "lmp_hybrid" in ref["processes"] else "?")
            own = p["processes"]["lmp_hybrid"]["top_ms_per_step"][L[1]]
            items = ", ".join(f"{n} {e * v:.3f}" for n, v in own)
            lines.append(
                f"- {p['case']}, per exchange: the fix's own DEM-side work {e * lg[L[1]]:.3f} ms ({items}); "
                f"waiting for the MPM process {e * (lg[L[0]] + lg['sleep']):.3f} ms ({e * lg[L[0]]:.3f} polling, "
                f"{e * lg['sleep']:.3f} asleep), while the MPM process computed {e * mg.get(M[1], 0.0):.3f} ms (its "
                f"substep and the agreement); LAMMPS's own work (pair and the other fixes) {delta} against the "
                f"uncoupled profile.")
    lines.append("")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines))
    args.out.with_suffix(".json").write_text(json.dumps(
        {"command": command, "date": stamp, "cores": os.cpu_count(), "size": size, "reps": args.reps,
         "target": TARGET, "build": {"commit": head, "uncommitted": dirty, "binaries": binaries}, "summary": summary, "runs": runs, "profiles": profiles}, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
