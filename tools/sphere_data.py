"""LAMMPS data files of spheres (atom_style sphere: id type diameter density x y z), which both
LAMMPS and LIGGGHTS read: the 3D scene drivers write their initial grains, frozen floors and
bodies with this one writer."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def write_spheres(path: str | Path, title: str, box, bodies, types: int) -> dict:
    """Writes `bodies` into a data file and returns the atom ids each body got (first, last).

    box: ((xlo, xhi), (ylo, yhi), (zlo, zhi)); bodies: (name, type, diameters, density,
    positions N x 3) with diameters an array of N or one number; ids run in the bodies' order."""
    lines = [title, "", f"{sum(len(b[4]) for b in bodies)} atoms", f"{types} atom types", ""]
    lines += [f"{lo:.9g} {hi:.9g} {a}lo {a}hi" for (lo, hi), a in zip(box, "xyz")]
    lines += ["", "Atoms # sphere", ""]
    ids, k = {}, 0
    for name, atom_type, diameters, density, positions in bodies:
        positions = np.asarray(positions, dtype=float).reshape(-1, 3)
        diam = np.broadcast_to(np.asarray(diameters, dtype=float), (len(positions),))
        ids[name] = (k + 1, k + len(positions))
        for dia, p in zip(diam, positions):
            k += 1
            lines.append(f"{k} {atom_type} {dia:.9g} {density:g} {p[0]:.9g} {p[1]:.9g} {p[2]:.9g}")
    Path(path).write_text("\n".join(lines) + "\n")
    return ids
