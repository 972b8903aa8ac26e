"""What the column collapse drivers (2D and 3D) measure alike on the final deposit, with the front
definition of tools/dem_collapse.py: the deposit is the cluster of flowing grains (type 1)
connected through contacts (gap < CONTACT_GAP d) to the grain nearest the back wall, Lf = max(x + r)
over it, and the surface profile is max(y + r) per x bin of 2 d over it. A hybrid's deposit also holds
its continuum's points (measure(points=...))."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hgtools.grains import connected_deposit, dump_positions, max_overlap, surface_profile


def measure(final: dict, initial: dict, width: float, d: float, period_z: float | None = None,
            points: dict | None = None, cell: float | None = None) -> dict:
    """The deposit's figures from the final and the initial dump (2D or 3D; period_z: the period
    of a periodic z, or None). points: a hybrid's continuum at the end ("position", "volume": its
    last HDF5 frame) on a grid of `cell`: the points join the deposit (each reaching half a cell,
    so that neighbouring points and the grains beside them connect) and its front (each as far as
    a body of its own volume). Without them a continuum reaching the front would end the deposit
    at its first point. The other figures are the grains' in the deposit."""
    if points is not None and cell is None:
        raise ValueError("measure(points=...) needs the grid's cell (cell=): a point reaches half a cell")
    g = final["type"] == 1
    pos = dump_positions(final)[g]
    r = final["radius"][g]
    bodies, reach, extent = pos, r, r
    if points is not None and len(points["position"]):
        volume = np.asarray(points["volume"], dtype=float)
        bodies = np.vstack([pos, np.asarray(points["position"], dtype=float)[:, :pos.shape[1]]])
        reach = np.concatenate([r, np.full(len(volume), 0.5 * cell)])
        extent = np.concatenate([r, np.sqrt(volume / np.pi) if pos.shape[1] == 2 else np.cbrt(0.75 * volume / np.pi)])
    connected = connected_deposit(bodies, reach, d, period_z)
    mask = connected[:len(pos)]
    edge = pos[:, 0] + r
    front = float((bodies[:, 0] + extent)[connected].max())
    gi = initial["type"] == 1
    if pos.shape[1] == 2:
        speed = np.hypot(final["vx"][g], final["vy"][g])
    else:
        speed = np.sqrt(final["vx"][g] ** 2 + final["vy"][g] ** 2 + final["vz"][g] ** 2)
    return dict(
        grains=int(g.sum()),
        runout=(front - width) / width,
        runout_p995=(float(np.percentile(edge, 99.5)) - width) / width,
        runout_max=(float(edge.max()) - width) / width,
        front=front,
        height=float((initial["y"][gi] + initial["radius"][gi]).max()),
        # 0 when no grain is at the wall (a hybrid whose continuum fills the corner)
        final_height=float(np.max((pos[:, 1] + r)[pos[:, 0] < 2 * d], initial=0.0)),
        max_speed=float(speed.max()),
        max_speed_deposit=float(speed[mask].max(initial=0.0)),
        max_overlap_initial=max_overlap(initial, d, period_z),
        max_overlap_final=max_overlap(final, d, period_z),
        detached=int((~mask).sum()),
        profile=surface_profile(pos[mask, 0], pos[mask, 1], r[mask], 2 * d, front),
    )


@dataclass(kw_only=True)
class Deposit:
    """The figures of measure(), the deck's rest criterion and the published runout range."""
    aspect: float
    width: float                   # L0, m
    d: float
    grains: int
    runout: float                  # (Lf - L0)/L0, front = connected deposit
    runout_p995: float             # front = 99.5th percentile of x + r
    runout_max: float              # front = max x + r over all grains
    front: float                   # Lf, m
    height: float                  # initial column height (max y + r), m
    final_height: float            # final deposit height at the wall (max y + r), m
    max_speed: float               # final, m/s, all flowing grains
    max_speed_deposit: float       # final, m/s, grains of the connected deposit
    max_overlap_initial: float     # largest overlap / d in the settled column
    max_overlap_final: float       # largest overlap / d in the deposit
    detached: int                  # grains outside the connected deposit
    ke_per_grain: float            # final mean kinetic energy per grain, J
    ke_rest: float                 # the deck's rest threshold on it, J
    wall_time: float               # s, the run (2D: with the preparation if not cached; 3D: pour, settle, collapse)
    published: tuple = ()
    profile: list = field(default_factory=list)   # [(x_centre, surface height)] per bin, connected deposit only
    log: str = ""

    @property
    def at_rest(self) -> bool:
        return self.ke_per_grain < self.ke_rest
