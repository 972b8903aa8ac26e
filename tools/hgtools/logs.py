"""The one reader of LAMMPS (and LIGGGHTS) logs: thermo tables, loop times, the figures a deck
prints on its own lines, fix hybrid/mpm's energy ledger, and the decks' record files.

The ledger is the fix's vector entries 19-29 (docs/fix_hybrid_mpm.md, "Energy ledger"); decks
that print it put all eleven in their thermo_style.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

LEDGER = {19: "total", 20: "grains", 21: "continuum", 22: "DEM steps", 23: "continuum steps",
          24: "agreement (grains)", 25: "agreement (continuum)", 26: "support force", 27: "rezones (grains)",
          28: "rezones (continuum)", 29: "residual"}


def thermo_tables(log: str | Path) -> list[list[dict]]:
    """Every thermo table of a log (text or path), in order, each a list of rows {column: value}
    (a message line of a table's width is not a row)."""
    text = log.read_text(errors="replace") if isinstance(log, Path) else log
    tables, header = [], None
    for line in text.splitlines():
        parts = line.split()
        if parts[:1] == ["Step"]:
            header = parts
            tables.append([])
        elif line.startswith("Loop time"):
            header = None
        elif header and len(parts) == len(header) and re.match(r"^-?\d", parts[0]):
            try:
                tables[-1].append(dict(zip(header, map(float, parts))))
            except ValueError:    # a message line of the same length
                continue
    return tables


def thermo_rows(log: str | Path, require: str | None = None) -> list[dict]:
    """Every thermo row of a log (text or path) as {column: value}, over all its tables (only
    those with the column `require`, if given). A row printed twice (the end of one run and the
    start of the next) counts once."""
    rows = []
    for table in thermo_tables(log):
        if not table or (require is not None and require not in table[0]):
            continue
        for row in table:
            if not rows or row["Step"] > rows[-1]["Step"]:
                rows.append(row)
    return rows


LOOP_RE = re.compile(r"^Loop time of (\S+) on \d+ procs for (\d+) steps", re.M)


def loops(text: str, after: str | None = None) -> tuple[int, float]:
    """(steps, seconds): the summed `Loop time` lines of a log, from the last line holding `after`
    on (all of them if it is None or not in the log)."""
    if after is not None:
        text = text[max(0, text.rfind(after)):]
    found = LOOP_RE.findall(text)
    return sum(int(n) for _, n in found), sum(float(t) for t, _ in found)


RUN_ATOMS_RE = re.compile(r"^Loop time of \S+ on \d+ procs for (\d+) steps with (\d+) atoms", re.M)
NEIGHS_RE = re.compile(r"^Ave neighs/atom = (\S+)$", re.M)


def neighbours(text: str) -> dict[str, float]:
    """What LAMMPS's runs in a log did per atom and per neighbour: their atom-steps and
    neighbour-steps (each run's steps times its atoms, and times its neighbours per atom at its
    end; a run without a neighbour count adds to neither), their loop and Pair (mean over the ranks)
    seconds (loops, timing_sections). A pair style's work is per neighbour, so grains with fewer
    neighbours (a surface layer, a thin deposit) cost less each."""
    out = dict(atom_steps=0.0, neighbour_steps=0.0, loop_s=loops(text)[1],
               pair_s=timing_sections(text, "MPI task timing breakdown").get("Pair", 0.0))
    runs = list(RUN_ATOMS_RE.finditer(text))
    for run, following in zip(runs, runs[1:] + [None]):
        count = NEIGHS_RE.search(text, run.end(), following.start() if following else len(text))
        if count:
            atom_steps = int(run.group(1)) * int(run.group(2))
            out["atom_steps"] += atom_steps
            out["neighbour_steps"] += atom_steps * float(count.group(1))
    return out


def timing_sections(text: str, header: str) -> dict[str, float]:
    """The mean ("avg time") seconds of each section of every timing table under a line holding
    `header` (LAMMPS's "MPI task timing breakdown", the fix's "fix hybrid/mpm timing breakdown"),
    summed over the log's runs."""
    sums: dict[str, float] = {}
    lines_ = text.splitlines()
    for i, line in enumerate(lines_):
        if header not in line:
            continue
        for row in lines_[i + 3:]:    # the header, the column names, the rule
            cells = [c.strip() for c in row.split("|")]
            if len(cells) < 3 or not cells[0]:
                break
            sums[cells[0]] = sums.get(cells[0], 0.0) + float(cells[2])    # (Other has only this column)
    return sums


MPM_LEDGER_RE = re.compile(r"^mpm_solver: wall time (\S+) s: (.*)$", re.M)


def mpm_ledger(text: str) -> dict[str, float]:
    """The MPM process's time ledger of a coupled run (its last `mpm_solver: wall time` line):
    {"wall": total, term: seconds, ...}."""
    found = MPM_LEDGER_RE.findall(text)
    if not found:
        raise RuntimeError("no 'mpm_solver: wall time' line in the output (not a coupled run that finished?)")
    total, terms = found[-1]
    out = {"wall": float(total)}
    for term in terms.split(", "):
        name, seconds = term.rsplit(" ", 1)
        out[name] = float(seconds)
    return out


REZONE_ENERGY_RE = re.compile(r"the rezones' energy on the (grains|points) \(J, J/m in 2D\): (.*); in all (\S+)$", re.M)
REZONE_TERM_RE = re.compile(r"(\w+) (\S+) \(([^)]*)\)")


def rezone_energy(text: str, side: str = "grains") -> list[dict]:
    """What the rezones did to one side's energy, from its lines (J, J/m in 2D): the fix's at the
    end of each run (side "grains": made, removed, corrected, each with its kinetic and potential
    part) or the MPM process's at its end ("points": with the elastic part, and rests); each also
    by the cells' zone change (enrichment, homogenisation, repair: the same sum). One dict per
    line: {term: {"total": .., "kinetic": .., ...}, ..., "all": the line's sum}."""
    out = []
    for found_side, terms, total in REZONE_ENERGY_RE.findall(text):
        if found_side != side:
            continue
        line = {"all": float(total)}
        for name, value, parts in REZONE_TERM_RE.findall(terms):
            line[name] = {"total": float(value), **{k: float(v) for k, v in (p.split() for p in parts.split(", "))}}
        out.append(line)
    return out


def number(pattern: str, text: str) -> float:
    """The first group of the first (multi-line) match of `pattern` in a log, as a number."""
    m = re.search(pattern, text, re.M)
    if not m:
        raise RuntimeError(f"pattern {pattern!r} not in the log")
    return float(m.group(1))


def lines(text: str, *prefixes: str) -> str:
    """A log's own lines starting with one of `prefixes` (the deck's report lines)."""
    return "\n".join(ln for ln in text.splitlines() if ln.startswith(prefixes))


def records(path: str | Path) -> np.ndarray:
    """A deck's record file (fix print or fix ave/time: # comment lines, then rows of numbers) as
    an array of rows."""
    return np.loadtxt(path, comments="#", ndmin=2)


CONTACT = ("kn", "kt", "gamma_n", "gamma_t", "gamma_n(wall)", "gamma_t(wall)")


def contact_params(text: str, prefix: str) -> dict:
    """The contact law and time step a 3D twin deck printed (`PREFIX contact: kn = ...` and
    `PREFIX timestep: ... dt = ... s`): what the twin tests compare between the codes."""
    params = {k: number(rf"^{prefix} contact:.*\b{re.escape(k)} = (\S+)", text) for k in CONTACT}
    params["dt"] = number(rf"^{prefix} timestep:.*\bdt = (\S+) s", text)
    return params


def ledger(row: dict) -> dict:
    """The energy ledger of one thermo row."""
    return {name: row[f"f_couple[{k}]"] for k, name in LEDGER.items()}


def ledger_closure(rows: list[dict]) -> float:
    """Largest |residual| over the run, relative to the largest energy figure involved (the
    total at the start, or any entry of the row)."""
    if not rows:
        return float("nan")
    first = ledger(rows[0])
    start = abs(first["total"] - first["residual"])
    worst = 0.0
    for r in rows:
        e = ledger(r)
        scale = max(start, *(abs(v) for k, v in e.items() if k != "residual"))
        worst = max(worst, abs(e["residual"]) / scale if scale > 0 else 0.0)
    return worst


def hybrid_totals(log: str) -> dict:
    """From a hybrid run's thermo table (hybrid_3d.lmp's thermo_style): the most material points
    and continuum / hybrid cells, and the largest relative change of the total mass f_couple[8]
    (grains' carried mass plus points). fix hybrid/mpm sums that total over all atoms, its group
    or not (FixHybridMPM::grain_totals), so it also holds frozen bodies (floor, blade); their mass
    is constant, so the drift is still that of grains plus points."""
    rows = thermo_rows(log, require="f_couple[8]")
    if not rows:
        return {}
    mass = np.array([r["f_couple[8]"] for r in rows])
    good = mass > 0
    return dict(points_max=int(max(r["f_couple[3]"] for r in rows)), mass_first=float(mass[good][0]) if good.any() else 0.0,
                mass_drift=float(np.max(np.abs(mass[good] - mass[good][0])) / mass[good][0]) if good.any() else 0.0,
                continuum_cells_max=int(max(r["f_couple[16]"] for r in rows)),
                hybrid_cells_max=int(max(r["f_couple[17]"] for r in rows)))


def hybrid_mass_lines(text: str) -> tuple[float, int, int]:
    """From the lines `HYBRID mass M points P cells continuum C hybrid H` a deck prints: the
    largest |M(t) - M(0)| / M(0), the most points and the most continuum + hybrid cells
    ((nan, 0, 0) without such lines)."""
    rows = re.findall(r"^HYBRID mass (\S+) points (\S+) cells continuum (\S+) hybrid (\S+)", text, re.M)
    if not rows:
        return float("nan"), 0, 0
    masses = [float(r[0]) for r in rows]
    return (max(abs(m - masses[0]) for m in masses) / masses[0], int(max(float(r[1]) for r in rows)),
            int(max(float(r[2]) + float(r[3]) for r in rows)))
