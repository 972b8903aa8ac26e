"""What an impact into a granular bed measures of the projectile's record (the method:
tools/README.md, "dem_impact.py"): the depth below the bed surface, the first contact and the
stop, the bed's force and its Katsuragi-Durian fit, the projectile's energy."""
from __future__ import annotations

import numpy as np

from hgtools.laws import G, katsuragi_durian_fit


def projectile_record(rec: np.ndarray, surface: float, dp: float, mp: float, d: float, vstop: float,
                      samples: int = 400) -> dict:
    """The measures of a trajectory record (rows t, z_p, vz_p, fz_p, KE_p, E_mobile; z up) of a
    projectile of diameter dp and mass mp over a bed whose surface is at `surface`: the largest
    depth of its bottom, the stopping time (first contact, the bed pushing on it, to the first
    record after it where its downward speed is below vstop), the Katsuragi-Durian fit over that
    span, the peak deceleration, the energy gains, the launch gap (its bottom above the surface
    at the first record) and the history [t, depth, v, deceleration] at about `samples` records."""
    t, zp, vz, fz, kp, em = (rec[:, k] for k in range(6))
    dep = surface - (zp - 0.5 * dp)
    bed_force = fz + mp * G
    touching = np.nonzero(bed_force > 1e-9 * mp * G)[0]
    i0 = int(touching[0]) if len(touching) else 0
    up = np.nonzero((-vz < vstop) & (np.arange(len(t)) > i0))[0]
    i1 = int(up[0]) if len(up) else len(t) - 1
    fit = katsuragi_durian_fit(dep[i0:i1 + 1], -vz[i0:i1 + 1], bed_force[i0:i1 + 1], mp, d)
    ep = kp + mp * G * zp
    step = max(1, len(t) // samples)
    return dict(max_depth=float(dep.max()), stop_time=float(t[i1] - t[i0]),
                drag_k=fit["k"], drag_d1=fit["d1"], drag_r2=fit["r2"], drag_bins=fit["bins"],
                peak_decel=float(bed_force.max() / mp), ke0=float(kp[0]),
                proj_energy_gain=float((ep - ep[0]).max()), mobile_energy_gain=float((em - em[0]).max()),
                history=[[float(t[k]), float(dep[k]), float(-vz[k]), float(bed_force[k] / mp)]
                         for k in range(0, len(t), step)], launch_gap=float(dep[0] * -1.0))
