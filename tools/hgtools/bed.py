"""The settled beds the scenes start from: the 3D silo's floor lattice with the orifice left out,
what the impact and the plough measure of their bed (its surface, its packing fraction away from
the walls, the floor and the surface, grains counted by their centres), and the margin every
scene's packing fraction keeps from those boundaries."""
from __future__ import annotations

import math

import numpy as np

from hgtools.grains import FLOOR_SPACING

SURFACE_BIN = 2.0            # surface columns under an impact, in d
PACKING_MARGIN = 3.0         # packing fraction measured this many d from walls, floor, surface


def floor_with_hole(width: float, orifice: float, d: float) -> tuple[np.ndarray, float, float]:
    """Centres (x, z) of the floor spheres, the lattice spacing and the inscribed diameter of
    the orifice. Spacing s = W / ceil(W / (FLOOR_SPACING d)) <= 1.2 d (the rows fill the width;
    a 0.9 d grain cannot pass a hole of four spheres of diameter d while s < 1.34 d); the
    spheres whose centre is within D/2 + d/2 of the axis are left out."""
    n = int(math.ceil(width / (FLOOR_SPACING * d) - 1e-9))
    s = width / n
    c = (np.arange(n) + 0.5) * s
    X, Z = np.meshgrid(c, c, indexing="ij")
    xz = np.column_stack([X.ravel(), Z.ravel()])
    dist = np.hypot(xz[:, 0] - 0.5 * width, xz[:, 1] - 0.5 * width)
    keep = dist >= 0.5 * orifice + 0.5 * d
    return xz[keep], s, float(2 * dist[keep].min() - d)


def surface_near_axis(dump: dict, width: float, d: float, radius: float) -> float:
    """The bed surface under an impact on the axis of a square box (z up): the mean, over the
    SURFACE_BIN d x SURFACE_BIN d columns whose centres lie within `radius` of the axis, of the
    highest grain top (z + r, grains of type 1) in each column."""
    g = dump["type"] == 1
    x, y, top = dump["x"][g], dump["y"][g], dump["z"][g] + dump["radius"][g]
    b = SURFACE_BIN * d
    ix = np.floor(x / b).astype(int)
    iy = np.floor(y / b).astype(int)
    c = 0.5 * width
    tops = []
    for i in range(ix.min(), ix.max() + 1):
        for j in range(iy.min(), iy.max() + 1):
            if math.hypot((i + 0.5) * b - c, (j + 0.5) * b - c) > radius:
                continue
            sel = (ix == i) & (iy == j)
            if sel.any():
                tops.append(top[sel].max())
    return float(np.mean(tops))


def box_packing(dump: dict, width: float, d: float, surface: float, margin: float = PACKING_MARGIN) -> float:
    """Packing fraction of a bed in a square box (z up): grain volume over box volume in the inner
    box margin d from the walls, the floor and the surface (grains counted by their centre: exact
    on average for a box >> d); the margin shrinks for a bed shallower than 4 margins."""
    margin = min(margin, 0.25 * surface / d)
    g = dump["type"] == 1
    x, y, z, r = dump["x"][g], dump["y"][g], dump["z"][g], dump["radius"][g]
    lo, hi, ztop = margin * d, width - margin * d, surface - margin * d
    sel = (x > lo) & (x < hi) & (y > lo) & (y < hi) & (z > margin * d) & (z < ztop)
    vol = (hi - lo) ** 2 * (ztop - margin * d)
    return float((4.0 / 3.0 * math.pi * r[sel] ** 3).sum() / vol)


def slab_bed(dump: dict, bedh: float, length: float, d: float, width: float) -> dict:
    """A slab bed (y up, periodic in z, of thickness `width`): the packing fraction (grain volume
    over box volume, grains counted by their centres) away from the end walls, the floor and the
    surface (2 d), and its mean surface height (the mean over x bins of 2 d of the highest grain top)."""
    g = dump["type"] == 1
    x, y, r = dump["x"][g], dump["y"][g], dump["radius"][g]
    lo, hi = 2 * d, bedh - 2 * d
    inside = (x > 2 * d) & (x < length - 2 * d) & (y > lo) & (y < hi)
    phi = float((4.0 / 3.0 * np.pi * r[inside] ** 3).sum() / ((length - 4 * d) * (hi - lo) * width))
    bins = np.arange(0.0, length, 2 * d)
    k = np.digitize(x, bins)
    tops = [float((y + r)[k == i].max()) for i in range(1, len(bins)) if np.any(k == i)]
    return dict(packing=phi, surface=float(np.mean(tops)))
