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
