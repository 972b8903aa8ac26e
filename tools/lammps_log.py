"""Thermo tables of LAMMPS logs, and fix hybrid/mpm's energy ledger in them.

The ledger is the fix's vector entries 19-29 (docs/fix_hybrid_mpm.md, "Energy ledger"); decks
that print it put all eleven in their thermo_style.
"""
from __future__ import annotations

import re
from pathlib import Path

LEDGER = {19: "total", 20: "grains", 21: "continuum", 22: "DEM steps", 23: "continuum steps",
          24: "agreement (grains)", 25: "agreement (continuum)", 26: "support force", 27: "rezones (grains)",
          28: "rezones (continuum)", 29: "residual"}


def thermo_rows(log: str | Path, require: str | None = None) -> list[dict]:
    """Every thermo row of a log (text or path) as {column: value}, over all its tables (only
    those with the column `require`, if given). A row printed twice (the end of one run and the
    start of the next) counts once."""
    text = log.read_text() if isinstance(log, Path) else log
    rows, header = [], None
    for line in text.splitlines():
        parts = line.split()
        if parts[:1] == ["Step"]:
            header = parts if require is None or require in parts else None
        elif line.startswith("Loop time"):
            header = None
        elif header and len(parts) == len(header) and re.match(r"^-?\d", parts[0]):
            try:
                row = dict(zip(header, map(float, parts)))
            except ValueError:    # a message line of the same length
                continue
            if not rows or row["Step"] > rows[-1]["Step"]:
                rows.append(row)
    return rows


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
