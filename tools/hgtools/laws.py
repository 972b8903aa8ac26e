"""Published laws the scenes are compared with, and the fits that measure their parameters:
Beverloo's discharge rate (2D and 3D), the Uehara et al. penetration depth, the Katsuragi-Durian
drag fit and Rankine's passive earth pressure."""
from __future__ import annotations

import math

import numpy as np

G = 9.81
BEVERLOO_K = 1.5             # docs/design.md section 6
BEVERLOO_C3D = 0.58          # docs/design.md section 6 (3D, circular orifice)
BEVERLOO_C2D = math.pi / 4   # free-fall arch with Janda et al. 2012's outlet profiles (tools/dem_silo.py)
UEHARA_C = 0.14              # Uehara et al. 2003, d = (0.14/mu) (rho_p/rho_b)^(1/2) D^(2/3) H^(1/3)


def beverloo_2d(rho_b: float, orifice: float, d: float, c: float = BEVERLOO_C2D,
                k: float = BEVERLOO_K, g: float = G) -> float:
    """2D Beverloo rate W = C rho_b sqrt(g) (D - k d)^(3/2), kg/s per m of depth."""
    return c * rho_b * math.sqrt(g) * max(orifice - k * d, 0.0) ** 1.5


def beverloo_3d(rho_b: float, orifice: float, d: float, c: float = BEVERLOO_C3D, k: float = BEVERLOO_K,
                g: float = G) -> float:
    """3D Beverloo rate W = C rho_b sqrt(g) (D - k d)^(5/2), kg/s."""
    return c * rho_b * math.sqrt(g) * max(orifice - k * d, 0.0) ** 2.5


def uehara_depth(rho_p: float, rho_b: float, dp: float, h: float, mu: float) -> float:
    """Uehara et al. (PRL 90, 194301, 2003): solves d = (0.14/mu) (rho_p/rho_b)^(1/2) dp^(2/3)
    (h + d)^(1/3) for d (fixed point: the map is a contraction, its slope A/(3 (h+d)^(2/3)) < 1
    for these sizes)."""
    a = UEHARA_C / mu * math.sqrt(rho_p / rho_b) * dp ** (2.0 / 3.0)
    dpen = a * h ** (1.0 / 3.0)
    for _ in range(200):
        dpen = a * (h + dpen) ** (1.0 / 3.0)
    return dpen


def katsuragi_durian_fit(depth: np.ndarray, v: np.ndarray, force: np.ndarray, mp: float, d: float,
                         nbins: int = 20, g: float = G) -> dict:
    """Katsuragi-Durian F = m g + k z + m v^2/d1 by least squares on depth bins of the
    penetration records (the bins' mean z, v^2 and F). Returns k, d1, the fit's R^2 on the
    bins, and the binned curve."""
    sel = depth > 0
    z, v2, f = depth[sel], v[sel] ** 2, force[sel] - mp * g
    if len(z) < 2 * nbins:
        return dict(k=float("nan"), d1=float("nan"), r2=float("nan"), bins=[])
    edges = np.linspace(0.0, z.max(), nbins + 1)
    idx = np.clip(np.digitize(z, edges) - 1, 0, nbins - 1)
    zb, vb, fb = [], [], []
    for i in range(nbins):
        s = idx == i
        if s.sum() >= 3:
            zb.append(z[s].mean()), vb.append(v2[s].mean()), fb.append(f[s].mean())
    zb, vb, fb = map(np.asarray, (zb, vb, fb))
    a = np.column_stack([zb, mp * vb])
    coef, *_ = np.linalg.lstsq(a, fb, rcond=None)
    pred = a @ coef
    ss = float(((fb - fb.mean()) ** 2).sum())
    r2 = 1.0 - float(((fb - pred) ** 2).sum()) / ss if ss > 0 else float("nan")
    k, inv_d1 = float(coef[0]), float(coef[1])
    return dict(k=k, d1=(1.0 / inv_d1) if inv_d1 > 0 else float("inf"), r2=r2,
                bins=[[float(p), float(q), float(w) + mp * g] for p, q, w in zip(zb, np.sqrt(vb), fb)])


def rankine_drag(rho_b: float, depth: float, phi_deg: float, g: float = G) -> float:
    """Rankine's passive earth pressure per unit width on a vertical wall of depth h,
    1/2 K_p rho_b g h^2 with K_p = (1 + sin phi)/(1 - sin phi), N/m."""
    s = math.sin(math.radians(phi_deg))
    return 0.5 * (1 + s) / (1 - s) * rho_b * g * depth ** 2
