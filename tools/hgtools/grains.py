"""Grains on disk and their contacts: LAMMPS dumps and sphere data files (atom_style sphere: id
type diameter density x y z, which LAMMPS and LIGGGHTS both read), the loose pouring lattice the
3D scenes start from, and the contact measures every scene takes (overlaps, the deposit connected
to the back wall, the free surface)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

CONTACT_GAP = 0.05       # grains closer than this fraction of d are in contact (front cluster)
FLOOR_SPACING = 1.2      # floor sphere spacing in x and z, in d (a 0.9 d grain cannot pass)
LATTICE_SPACING = 1.16   # loose pouring lattice spacing, in d (> dmax + 2 * jitter)
LATTICE_JITTER = 0.025   # random offset of the lattice sites, +- in d, per axis
PHI_EST = 0.60           # packing fraction assumed to size the pour (trimmed 8 % extra)


def pour_margin(d: float) -> float:
    """Distance of the outermost lattice sites from a wall: the largest radius plus the jitter."""
    return 0.55 * 1.1 * d + LATTICE_JITTER * d


def grains_needed(volume: float, d: float) -> int:
    """Grains (diameters uniform in [0.9, 1.1] d) that fill `volume` at PHI_EST, 8 % extra to trim."""
    vmean = math.pi / 6 * d ** 3 * 1.01          # <D^3> for D uniform in [0.9, 1.1] d
    return int(math.ceil(1.08 * PHI_EST * volume / vmean))


def jittered(rng: np.random.Generator, sites: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    """The grains of a pouring lattice: the sites offset by up to +-LATTICE_JITTER d per axis, and
    their diameters, uniform in [0.9, 1.1] d (in that order from `rng`)."""
    grains = sites + rng.uniform(-LATTICE_JITTER * d, LATTICE_JITTER * d, sites.shape)
    return grains, rng.uniform(0.9 * d, 1.1 * d, len(grains))


def pour_lattice(length: float, W: float, d: float, volume: float) -> tuple:
    """The loose pouring lattice of a slab (periodic or walled) of thickness W: x sites from
    `margin` to length - margin at LATTICE_SPACING d, z sites filling W (no two closer than
    the largest grain plus the jitter), and the number of grains that fill `volume` at
    PHI_EST, 8 % extra to trim. Returns (xs, zs, margin, need)."""
    s = LATTICE_SPACING * d
    nz = max(1, int(round(W / s)))
    sz = W / nz
    if sz < 1.1 * d + 2 * LATTICE_JITTER * d:
        nz -= 1
        sz = W / nz
    margin = pour_margin(d)
    xs = np.arange(margin, length - margin + 1e-12, s)
    zs = (np.arange(nz) + 0.5) * sz
    return xs, zs, margin, grains_needed(volume, d)


def slab_floor(x_end: float, thickness_d: int, d: float) -> np.ndarray:
    """Frozen floor spheres of a slab: a square lattice of FLOOR_SPACING d in x (from -2 d up to
    x_end) and z (thickness_d rows), centres at y = -d/2."""
    fs = FLOOR_SPACING * d
    fx = np.arange(0.5 * fs - 2 * d, x_end, fs)
    fz = (np.arange(thickness_d) + 0.5) * fs
    FX, FZ = np.meshgrid(fx, fz, indexing="ij")
    return np.column_stack([FX.ravel(), np.full(FX.size, -0.5 * d), FZ.ravel()])


def read_dump(path: Path) -> dict:
    """A single-frame LAMMPS custom dump as a dict of numpy columns."""
    lines = Path(path).read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("ITEM: ATOMS"))
    cols = lines[i].split()[2:]
    data = np.loadtxt(lines[i + 1:], ndmin=2)
    return {c: data[:, k] for k, c in enumerate(cols)}


def contact_pairs(pos, r, cutoff, period_z=None):
    """Index pairs (i < j) with gap (centre distance - r_i - r_j) below cutoff, and the gaps.
    pos: N x 2 or N x 3 centres; a numpy cell list over x and y; period_z: the period of a
    periodic z (minimum image), or None."""
    pos = np.asarray(pos, dtype=float)
    n = len(pos)
    cell = 2 * r.max() + cutoff
    ix = np.floor((pos[:, 0] - pos[:, 0].min()) / cell).astype(np.int64)
    iy = np.floor((pos[:, 1] - pos[:, 1].min()) / cell).astype(np.int64)
    ny = iy.max() + 3
    key = ix * ny + iy
    order = np.argsort(key)
    skey = key[order]
    out_i, out_j = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            nkey = (ix + dx) * ny + (iy + dy)
            lo = np.searchsorted(skey, nkey, "left")
            hi = np.searchsorted(skey, nkey, "right")
            counts = hi - lo
            if counts.sum() == 0:
                continue
            ii = np.repeat(np.arange(n), counts)
            jj = order[np.concatenate([np.arange(a, b) for a, b in zip(lo, hi)])]
            keep = ii < jj
            out_i.append(ii[keep])
            out_j.append(jj[keep])
    i = np.concatenate(out_i)
    j = np.concatenate(out_j)
    delta = pos[i] - pos[j]
    if period_z is not None:
        delta[:, 2] -= period_z * np.round(delta[:, 2] / period_z)
    gap = np.linalg.norm(delta, axis=1) - r[i] - r[j]
    keep = gap < cutoff
    return i[keep], j[keep], gap[keep]


def dump_positions(dump: dict) -> np.ndarray:
    """Centres of a dump as N x 2 (x, y) or N x 3 when it has z."""
    return np.column_stack([dump[c] for c in ("x", "y", "z") if c in dump])


def max_overlap(dump: dict, d: float, period_z=None) -> float:
    """Largest grain-grain overlap (including the floor grains), as a fraction of d."""
    _, _, gap = contact_pairs(dump_positions(dump), dump["radius"], 0.0, period_z)
    return float(max(0.0, -gap.min())) / d if len(gap) else 0.0


def connected_deposit(pos, r, d, period_z=None) -> np.ndarray:
    """Boolean mask of the grains connected, through contacts (gap < CONTACT_GAP d), to the
    grain nearest the back wall (pos: N x 2 or N x 3 centres)."""
    pos = np.asarray(pos, dtype=float)
    n = len(pos)
    i, j, _ = contact_pairs(pos, r, CONTACT_GAP * d, period_z)
    parent = np.arange(n)

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in zip(i.tolist(), j.tolist()):
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[ra] = rb
    roots = np.array([find(a) for a in range(n)])
    return roots == roots[np.argmin(pos[:, 0])]


def surface_profile(x, y, r, bin_width, length):
    """Final free-surface height max(y + r) per x bin of width bin_width (NaN: empty)."""
    edges = np.arange(0.0, length + bin_width, bin_width)
    idx = np.clip(np.digitize(x, edges) - 1, 0, len(edges) - 2)
    top = np.full(len(edges) - 1, np.nan)
    np.fmax.at(top, idx, y + r)
    centres = 0.5 * (edges[:-1] + edges[1:])
    return [(float(c), float(h)) for c, h in zip(centres, top) if np.isfinite(h)]


def covered_fraction(pos, r, lo, hi, cell: float) -> float:
    """The fraction of the box [lo, hi] (2D or 3D) that the disks or spheres (centres pos, N x dim;
    radii r) cover, rasterised on square (cubic) cells of side `cell`."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    n = np.maximum(((hi - lo) / cell).astype(int), 1)
    centres = [lo[k] + (np.arange(n[k]) + 0.5) * cell for k in range(len(n))]
    covered = np.zeros(n, dtype=bool)
    for p, ri in zip(np.asarray(pos, dtype=float), r):
        span = [(np.searchsorted(c, p[k] - ri), np.searchsorted(c, p[k] + ri)) for k, c in enumerate(centres)]
        if any(a == b for a, b in span):
            continue
        dist2 = sum((centres[k][a:b] - p[k]).reshape([-1 if j == k else 1 for j in range(len(n))]) ** 2
                    for k, (a, b) in enumerate(span))
        covered[tuple(slice(a, b) for a, b in span)] |= dist2 <= ri * ri
    return float(covered.mean())


def read_data(path: Path) -> dict:
    """The Atoms section of a data file (written by this driver or by write_data of either
    code: id type diameter density x y z [ix iy iz]) as numpy columns, with radius and mass."""
    lines = Path(path).read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.split()[:1] == ["Atoms"])
    rows = []
    for ln in lines[i + 2:]:
        if not ln.strip():
            break
        rows.append([float(v) for v in ln.split()[:7]])
    a = np.array(rows)
    out = {c: a[:, k] for k, c in enumerate(("id", "type", "diameter", "density", "x", "y", "z"))}
    out["radius"] = 0.5 * out["diameter"]
    out["mass"] = out["density"] * math.pi / 6 * out["diameter"] ** 3
    return out


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
