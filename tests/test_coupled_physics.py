"""Coupled LAMMPS + MPM physics (fix hybrid/mpm): conservation and velocity agreement.

Decks under input_decks/hybrid/ run through tools/hybrid_launch.py; every run has a timeout.
The totals come from the fix's thermo vector (grains' carried mass plus material points) and
the frames the MPM process writes (grains and points in one HDF5 file).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import BUILD, REPO
import mpm_results
from hgtools.logs import thermo_tables

LAUNCH = REPO / "tools" / "hybrid_launch.py"
MOMENTUM_DECK = REPO / "input_decks" / "hybrid" / "momentum_2d.lmp"


def env() -> dict:
    e = dict(os.environ, HYBRID_BUILD_DIR=str(BUILD), OMP_NUM_THREADS="1")
    if os.geteuid() == 0:
        e.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return e


def run_deck(tmp_path: Path, deck: Path, np_: int, *lammps_args: str, timeout: float = 300,
             host: str = "lammps") -> str:
    """Runs a coupled deck on the DEM host `host` (lammps: lmp_hybrid, liggghts: liggghts_hybrid);
    returns the log text (fails on a non-zero exit)."""
    log = tmp_path / "log.lammps"
    proc = subprocess.run([sys.executable, str(LAUNCH), "--host", host, "-np", str(np_), str(deck), "-log", str(log),
                           *lammps_args], capture_output=True, text=True, errors="replace", timeout=timeout,
                          env=env(), cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    text = log.read_text()
    return liggghts_headers(text, deck.read_text()) if host == "liggghts" else text


def liggghts_headers(log: str, deck: str) -> str:
    """The log with its thermo headers spelled as the deck's thermo_style names them: LIGGGHTS
    prints a header's names cut to 8 characters (f_couple[10] as "couple[1")."""
    styles = re.findall(r"^thermo_style\s+custom\s+(.*)$", deck, flags=re.M)
    names = ["Step" if w == "step" else "Atoms" if w == "atoms" else w for w in styles[-1].split()]
    return "\n".join(" ".join(names) if line.split()[:1] == ["Step"] else line for line in log.splitlines())


DECKS = {  # deck, points made from grains, hybrid grains, momentum components
    "2d": (MOMENTUM_DECK, 64, 300, 2),
    "3d": (REPO / "input_decks" / "hybrid" / "momentum_3d.lmp", 512, 876, 3),
    # the LIGGGHTS twin of the 3D deck (liggghts_hybrid; LIGGGHTS runs are 3D only)
    "3d-liggghts": (REPO / "input_decks" / "hybrid" / "momentum_3d.liggghts", 512, 876, 3),
}
# the scenes on both DEM hosts: (dim, host)
SCENES = [("2d", "lammps"), ("3d", "lammps"), ("3d", "liggghts")]


def scene(dim: str, host: str, programs: dict) -> tuple:
    """The deck and figures of a scene on a host (LIGGGHTS: its twin deck; liggghts_hybrid must be built)."""
    if host == "liggghts":
        exe = programs.get("liggghts_hybrid", "")
        assert exe and Path(exe).exists(), "liggghts_hybrid is not built (libliggghts-dev; run tools/setup.sh)"
        return DECKS[f"{dim}-liggghts"]
    return DECKS[dim]


@pytest.mark.parametrize("pic", [1, 0])
@pytest.mark.parametrize("np_", [1, 2])
@pytest.mark.parametrize("dim,host", SCENES)
def test_linear_momentum_of_grains_plus_points_is_conserved(tmp_path, hybrid_programs, dim, host, np_, pic):
    """No gravity, no walls in reach: grains collide, the continuum core is coupled through a
    ring (shell) of hybrid cells every step. Grains' carried momentum plus the points' momentum
    stays what the grains alone had at step 0 (before the conversion), in 2D and 3D, on 1 and
    2 DEM ranks, with either grain update, with LAMMPS and (3D) LIGGGHTS as the DEM host."""
    deck, n_points, n_hybrid, n_comp = scene(dim, host, hybrid_programs)
    nsteps = 200 if dim == "2d" else 100
    log = run_deck(tmp_path, deck, np_, "-var", "nsteps", str(nsteps), "-var", "pic", str(pic), host=host)
    m = re.search(r"grains became (\d+) material points, (\d+) grains are hybrid", log)
    assert m, log
    # the random velocities depend on the rank count, so grains near cell faces may differ
    assert int(m.group(1)) == n_points and abs(int(m.group(2)) - n_hybrid) <= 0.05 * n_hybrid
    rows = thermo_tables(log)[-1]
    assert len(rows) == nsteps // 10 + 1 and rows[-1]["Step"] == nsteps
    first = rows[0]
    assert first["f_couple[3]"] == 0  # step 0: no points yet
    # scale of the momenta that cancel: total mass times the grains' speed (0.05 m/s)
    scale = first["f_couple[8]"] * 0.05
    for r in rows[1:]:
        assert r["f_couple[3]"] == n_points and r["f_couple[2]"] >= int(m.group(2))
        assert r["f_couple[8]"] == pytest.approx(first["f_couple[8]"], rel=1e-14)
        for col in [f"f_couple[{9 + a}]" for a in range(n_comp)]:
            assert abs(r[col] - first[col]) <= 1e-13 * scale, (r["Step"], col, r[col], first[col])
    # the sides were not idle: the sides disagreed before each agreement
    assert max(r["f_couple[5]"] for r in rows[1:]) > 1e-4


def bspline_weights(frac: np.ndarray) -> np.ndarray:
    """Quadratic B-spline weights of the 3 nodes base, base+1, base+2 (frac = xi - base)."""
    return np.stack([0.5 * (1.5 - frac) ** 2, 0.75 - (frac - 1.0) ** 2, 0.5 * (frac - 0.5) ** 2], axis=-1)


def test_grain_velocities_take_the_agreed_node_velocity_field(tmp_path, hybrid_programs):
    """With pic 1 and relax 0, after each coupling step a coupled grain's velocity equals the grid velocity
    field at its position (quadratic B-splines over the agreed node velocities) to round-off.
    Checked on the frames the MPM process writes: grains after their update, grid after the
    agreement, computed here independently of the C++ transfer code."""
    deck = tmp_path / "deck.lmp"
    deck.write_text(MOMENTUM_DECK.read_text().replace(   # relax 0: both sides take the agreed velocity
        "youngs 1.0e5", "youngs 1.0e5 relax 0 output frames 5"))
    run_deck(tmp_path, deck, 2, "-var", "nsteps", "20", "-var", "pic", "1")
    out = tmp_path / "frames"
    checked = 0
    for frame in (1, 2, 3):
        grains = mpm_results.read_grains(out, frame)
        grid = mpm_results.read_grid(out, frame)
        assert grains["step"] == grid["step"] and grains["step"] > 0
        x = grains["position"][:, :2]
        xi = (x - grid["origin"]) / grid["dx"]
        base = np.floor(xi - 0.5).astype(int)
        w = bspline_weights(xi - base)
        coupled = (grains["weight"] < 1) | (grains["zone"] != 0)
        for g in np.flatnonzero(coupled):
            i0, j0 = base[g]
            masses = grid["mass"][i0:i0 + 3, j0:j0 + 3]
            if not (masses > 0).all():
                continue  # nodes without points hold no MPM velocity in the file
            field = np.einsum("i,j,ijd->d", w[g, 0], w[g, 1], grid["velocity"][i0:i0 + 3, j0:j0 + 3])
            assert np.allclose(grains["velocity"][g, :2], field, rtol=0, atol=1e-14 + 1e-12 * np.abs(field).max())
            checked += 1
        # grains of discrete cells far from the continuum did not take the field
        assert (~coupled).sum() > 0
    assert checked > 100


COLUMN_DECK = REPO / "input_decks" / "hybrid" / "settled_column_2d.lmp"


def read_dumps(path: Path) -> dict:
    """LAMMPS custom dump -> {step: {column: array}}."""
    out, lines, i = {}, path.read_text().splitlines(), 0
    while i < len(lines):
        if lines[i].startswith("ITEM: TIMESTEP"):
            step, n = int(lines[i + 1]), int(lines[i + 3])
            cols = lines[i + 8].split()[2:]
            data = np.array([[float(v) for v in ln.split()] for ln in lines[i + 9:i + 9 + n]])
            out[step] = {c: data[:, k] for k, c in enumerate(cols)}
            i += 9 + n
        else:
            i += 1
    return out


@pytest.mark.parametrize("support", [1, 0])
def test_settled_hybrid_column_stays_at_rest_with_continuous_vertical_stress(tmp_path, hybrid_programs, support):
    """A settled 2D column (hex packing, 546 grains, frictionless side walls) whose lower half
    becomes continuum stays at rest for 10,000 coupled steps (no drift, no kinetic-energy
    growth), with and without the support force between exchanges. With frictionless walls
    every horizontal section carries the whole weight above it, so the vertical stress over
    the lithostatic stress is 1 on both sides of the border: in the grains just above the
    hybrid band and in the continuum just below the band where the coupling's loads enter
    (the nodes of the hybrid grains' stencils reach two cells into the continuum)."""
    deck = tmp_path / "deck.lmp"
    deck.write_text(COLUMN_DECK.read_text().replace("wall slip output", f"wall slip support {support} output"))
    log = run_deck(tmp_path, deck, 2, "-var", "nsteps", "10000")
    rows = [r for r in thermo_tables(log)[-1] if r["Step"] > 0]
    assert rows[-1]["Step"] == 10000 and rows[-1]["f_couple[3]"] == 240
    width, g, d, dx = 0.04, 9.81, 0.002, 0.004
    # energy: tiny against the column's potential energy scale (the settled packing alone keeps
    # about 4e-6 of it as vibration, see the settling thermo), and not growing
    mass = rows[-1]["f_couple[8]"]
    scale = mass * g * 0.05
    ke = np.array([r["c_ke"] + r["f_couple[15]"] for r in rows])
    assert ke.max() < 2e-5 * scale
    half = len(ke) // 2
    assert ke[half:].mean() <= 1.2 * ke[len(ke) // 10:half].mean()
    # no drift of grains or points
    dumps = read_dumps(tmp_path / "grains.dump")
    first, last = dumps[0], dumps[10000]
    _, ia, ib = np.intersect1d(first["id"], last["id"], return_indices=True)
    assert len(ia) == 331
    drift = np.hypot(first["x"][ia] - last["x"][ib], first["y"][ia] - last["y"][ib])
    assert drift.max() < 0.05 * d
    run = mpm_results.Run(tmp_path / "frames")
    p0, p1 = run.frame(0), run.frame(-1)
    assert np.abs(p1["position"] - p0["position"]).max() < 0.05 * d
    # vertical stress over the lithostatic stress of the mass above (grains' carried mass + points)
    grains = mpm_results.read_grains(tmp_path / "frames", -1)
    all_y = np.concatenate([p1["position"][:, 1], grains["position"][:, 1]])
    all_m = np.concatenate([p1["mass"], grains["mass"]])

    def lithostatic(y: float) -> float:
        return -g * all_m[all_y > y].sum() / width

    hybrid_bottom = p1["position"][p1["zone"] == 1, 1].min() - dx / 4   # lower edge of the hybrid band
    below = (p1["zone"] == 2) & (p1["position"][:, 1] < hybrid_bottom - 2 * dx) & \
        (p1["position"][:, 1] > hybrid_bottom - 3 * dx)  # the continuum cell row just below the band
    y_mpm = p1["position"][below, 1].mean()
    ratio_mpm = p1["stress"][below, 1, 1].mean() / lithostatic(y_mpm)
    # grains: rows of the hex packing (spacing sqrt(3)/2 d), per-grain virial over row area
    y, syy = last["y"], last["c_stress[2]"]
    discrete_bottom = grains["position"][grains["zone"] == 0, 1].min()
    h = np.sqrt(3) / 2 * d
    row = np.round((y - y.min()) / h).astype(int)
    ratios = []
    for r in np.unique(row):
        in_row = row == r
        y_row = y[in_row].mean()
        if discrete_bottom + h < y_row < discrete_bottom + dx + h:  # first rows clear of the hybrid band
            ratios.append(syy[in_row].sum() / (width * h) / lithostatic(y_row))
    assert len(ratios) >= 2
    ratio_dem = float(np.mean(ratios))
    print(f"support {support}: vertical stress over lithostatic: continuum {ratio_mpm:.3f} at y = {y_mpm:.4f}, "
          f"grains {ratio_dem:.3f}; KE max {ke.max() / scale:.2e} of m g H")
    assert abs(ratio_mpm - 1) < 0.05 and abs(ratio_dem - 1) < 0.05, (ratio_mpm, ratio_dem)
    assert abs(ratio_mpm - ratio_dem) < 0.05, (ratio_mpm, ratio_dem)


def test_restart_continues_the_coupled_run(tmp_path, hybrid_programs):
    """A coupled run that writes a LAMMPS restart file at step 30 (the MPM process saves its
    state next to it, restart.bin.mpm.h5) and a second job that reads both and runs on reach
    the same state at step 60 as the uninterrupted run: the same totals and grain positions
    (to round-off: LAMMPS's own restart reorders atoms, so sums may differ in the last bits)."""
    full = MOMENTUM_DECK.read_text()
    marker = "run             ${nsteps}"
    assert marker in full
    head = full.replace(marker, "")
    dump = "dump d all custom 60 grains_{0}.dump id x y vx vy\ndump_modify d sort id format float %.17g\n"
    straight = tmp_path / "straight"
    straight.mkdir()
    (straight / "deck.lmp").write_text(head + dump.format("a") +
                                       "run 30\nwrite_restart restart.bin\nrun 30\n")
    log_a = run_deck(straight, straight / "deck.lmp", 2)
    assert "MPM state saved to restart.bin.mpm.h5" in log_a
    restarted = tmp_path / "restarted"
    restarted.mkdir()
    for name in ("restart.bin", "restart.bin.mpm.h5"):
        (restarted / name).write_bytes((straight / name).read_bytes())
    fix_line = next(ln for ln in full.splitlines() if ln.startswith("fix             couple"))
    region_line = next(ln for ln in full.splitlines() if ln.startswith("region          core"))
    thermo = [ln for ln in full.splitlines() if ln.startswith("thermo")]
    deck_b = "\n".join([
        "read_restart    restart.bin",
        "comm_modify     vel yes",
        "neighbor        0.0005 bin",
        "neigh_modify    delay 0",
        "variable every index 1",
        "variable pic index 1",
        "fix             integ all nve/sphere disc",
        "fix             2d all enforce2d",
        region_line,  # LAMMPS restart files do not keep regions
        fix_line + " mpm_state restart.bin.mpm.h5",
        *thermo,
        dump.format("b"),
        "run 30",
    ]) + "\n"
    (restarted / "deck.lmp").write_text(deck_b)
    log_b = run_deck(restarted, restarted / "deck.lmp", 2)
    assert "MPM state loaded from restart.bin.mpm.h5 (64 material points)" in log_b
    a = [r for r in thermo_tables(log_a)[-1] if r["Step"] == 60][-1]
    b = [r for r in thermo_tables(log_b)[-1] if r["Step"] == 60][-1]
    scale = a["f_couple[8]"] * 0.05
    for col in ("f_couple[9]", "f_couple[10]"):
        assert abs(a[col] - b[col]) <= 1e-13 * scale, (col, a[col], b[col])
    for col in ("f_couple[2]", "f_couple[3]", "f_couple[8]"):
        assert a[col] == pytest.approx(b[col], rel=1e-13), col
    ga = read_dumps(straight / "grains_a.dump")[60]
    gb = read_dumps(restarted / "grains_b.dump")[60]
    assert np.array_equal(ga["id"], gb["id"])
    # LAMMPS's own restart is not bit-exact for granular contacts (the same decks without the
    # fix, run here with lmp_hybrid alone, differ too): the coupled restart may differ no more
    plain = tmp_path / "plain"
    plain.mkdir()
    strip = lambda text: "\n".join(ln for ln in text.splitlines()
                                    if not ln.startswith(("fix             couple", "region          core", "thermo"))
                                    and "mpm_state" not in ln)
    (plain / "a.lmp").write_text(strip((straight / "deck.lmp").read_text()))
    (plain / "b.lmp").write_text(strip((restarted / "deck.lmp").read_text()))
    lmp = [hybrid_programs["lmp_hybrid"]]
    mpirun = [str(REPO / "tools" / "mpirun.sh"), "-np", "2"]
    for deck in ("a.lmp", "b.lmp"):
        subprocess.run(mpirun + lmp + ["-in", deck, "-log", "none"], cwd=plain, check=True, capture_output=True,
                       timeout=120, env=env())
    pa = read_dumps(plain / "grains_a.dump")[60]
    pb = read_dumps(plain / "grains_b.dump")[60]
    lammps_dv = np.abs(pa["vx"] - pb["vx"]).max() + np.abs(pa["vy"] - pb["vy"]).max()
    coupled_dv = np.abs(ga["vx"] - gb["vx"]).max() + np.abs(ga["vy"] - gb["vy"]).max()
    print(f"restart: largest velocity difference coupled {coupled_dv:.3g} m/s, LAMMPS alone {lammps_dv:.3g} m/s")
    assert coupled_dv <= 2 * lammps_dv + 1e-12


def test_output_frames_do_not_change_the_run(tmp_path, hybrid_programs):
    """The same deck run in four LAMMPS runs (steps 0-25, 25-50, 50-67, 67-69, exchanging every
    10), with and without output frames, ends with the same grains to the last bit: a frame is
    written at the last exchange of each run (steps 20, 50 and 60), not by an extra exchange at
    the run's end, whose agreement would change the run. The last run has no exchange, so no
    frame, and the fix says so."""
    deck = MOMENTUM_DECK.read_text()
    marker, fix = "run             ${nsteps}", "every ${every} pic ${pic} youngs 1.0e5"
    assert marker in deck and fix in deck
    runs = "run 25\nrun 25\nrun 17\nrun 2\nwrite_dump all custom final.dump id x y vx vy modify sort id format float %.17g\n"
    finals, logs = {}, {}
    for name, output in (("plain", ""), ("frames", " output frames 1000")):
        out = tmp_path / name
        out.mkdir()
        (out / "deck.lmp").write_text(deck.replace(marker, runs).replace(fix, fix + output))
        logs[name] = run_deck(out, out / "deck.lmp", 2, "-var", "every", "10")
        finals[name] = (out / "final.dump").read_text()
    assert finals["frames"] == finals["plain"]
    frameless = "this run of 2 step(s) had no exchange (every 10), so it wrote no output frame"
    assert frameless in logs["frames"] and frameless not in logs["plain"]
    frames = mpm_results.load_run(tmp_path / "frames" / "frames")
    steps = [round(info.time / 1.0e-5) for info in frames.frames]
    assert steps == [10, 20, 50, 60], steps    # the first exchange's (every 1000th), then each run's last
    grains = mpm_results.read_grains(tmp_path / "frames" / "frames", -1)
    assert round(float(grains["time"]) / 1.0e-5) == 60


@pytest.mark.parametrize("dim,host", SCENES)
def test_conversion_keeps_mass_momentum_and_angular_momentum_exactly(tmp_path, hybrid_programs, dim, host):
    """Grains that do not touch (a lattice looser than their diameter), spinning and moving at
    random, no gravity: the DEM host conserves their totals exactly, so the totals just after the
    conversion at step 1 (grains' carried mass plus the new points, before any exchange) equal
    those at step 0 to round-off: mass, linear momentum and angular momentum (orbital plus spin
    of the grains; APIC for the points). LAMMPS and (3D) LIGGGHTS as the DEM host."""
    deck_in, *_ = scene(dim, host, hybrid_programs)
    if host == "liggghts":
        log = run_deck(tmp_path, LIGGGHTS_CONVERSION_DECK, 2, "-var", "data",
                       str(spinning_lattice_data(tmp_path / "grains.data")), host=host)
        check_conversion_totals(log)
        return
    text = deck_in.read_text()
    text = text.replace("lattice         sq 0.002 ", "lattice         sq 0.0025 ")
    text = text.replace("lattice         sc 0.004 ", "lattice         sc 0.005 ")
    spin = "variable        wz atom 20*random(-1,1,${seed})\nset             type 1 omega 0 0 v_wz\n"
    if dim == "3d":
        spin = ("variable        wx atom 20*random(-1,1,${seed})\nvariable        wz atom 20*random(-1,1,${seed})\n"
                "set             type 1 omega v_wx 0 v_wz\n")
    text = text.replace("timestep        1.0e-5", spin + "timestep        1.0e-5")
    text = re.sub(r"^thermo_style .*$", "thermo_style    custom step atoms f_couple[3] f_couple[8] f_couple[9] "
                  "f_couple[10] f_couple[11] f_couple[12] f_couple[13] f_couple[14]", text, flags=re.M)
    text = text.replace("thermo          10", "thermo          1")
    deck = tmp_path / "deck.lmp"
    deck.write_text(text)
    check_conversion_totals(run_deck(tmp_path, deck, 2, "-var", "nsteps", "2", "-var", "every", "10"))


LIGGGHTS_CONVERSION_DECK = REPO / "input_decks" / "hybrid" / "conversion_3d.liggghts"


def spinning_lattice_data(path: Path, seed: int = 7731) -> Path:
    """The grains of the 3D conversion scene (momentum_3d's patch on the looser lattice sc 0.005,
    diameter 0.004, density 2500, velocities within +-0.05 m/s, spins wx, wz within +-20 rad/s) as
    a LIGGGHTS data file (LIGGGHTS 3.8's set command cannot set spins)."""
    rng = np.random.default_rng(seed)
    axis = (np.arange(4, 16) + 0.5) * 0.005    # the lattice points inside [0.02, 0.08]
    x = np.array(np.meshgrid(axis, axis, axis, indexing="ij")).reshape(3, -1).T
    v = rng.uniform(-0.05, 0.05, x.shape)
    w = np.zeros_like(x)
    w[:, [0, 2]] = rng.uniform(-20, 20, (len(x), 2))
    lines = ["grains of conversion_3d.liggghts (tests/test_coupled_physics.py)", "", f"{len(x)} atoms", "1 atom types",
             "0 0.1 xlo xhi", "0 0.1 ylo yhi", "0 0.1 zlo zhi", "", "Atoms", ""]
    lines += [f"{i + 1} 1 0.004 2500 " + " ".join(repr(float(c)) for c in p) for i, p in enumerate(x)]
    lines += ["", "Velocities", ""]
    lines += [f"{i + 1} " + " ".join(repr(float(c)) for c in (*v[i], *w[i])) for i in range(len(x))]
    path.write_text("\n".join(lines) + "\n")
    return path


def check_conversion_totals(log: str):
    """Step 0 (grains only) against step 1 (grains' carried mass plus the new points)."""
    rows = thermo_tables(log)[-1]
    before, after = rows[0], rows[1]
    assert before["f_couple[3]"] == 0 and after["f_couple[3]"] > 0 and after["Step"] == 1
    assert after["f_couple[8]"] == pytest.approx(before["f_couple[8]"], rel=1e-14)
    mass = before["f_couple[8]"]
    p_scale, l_scale = mass * 0.05, mass * (0.05 * 0.15 + 20 * 0.004 ** 2)
    for k in (9, 10, 11):
        assert abs(after[f"f_couple[{k}]"] - before[f"f_couple[{k}]"]) <= 1e-13 * p_scale, k
    for k in (12, 13, 14):
        assert abs(after[f"f_couple[{k}]"] - before[f"f_couple[{k}]"]) <= 1e-13 * l_scale, k
    assert abs(before["f_couple[14]"]) > 1e-6 * l_scale  # there was angular momentum to keep


def test_new_points_stress_is_that_of_their_grains_when_another_fix_reorders_atoms(tmp_path, hybrid_programs):
    """The Love-Weber stress of the points made at step 1 comes from the grains' per-atom
    virial of step 0, held by the fix until the rezone at step 1's pre_exchange. A fix whose
    pre_exchange runs first and reorders the atoms in between (here fix evaporate, which
    deletes the column's top rows and fills their slots with the last atoms: the bottom
    grains, created last so they are the ones that become points) must not change it: the
    points' stress equals that of the same deck with fix evaporate defined after
    hybrid/mpm (its deletions then follow the rezone). Held by local index, the moved
    grains took the deleted top grains' stress. One LAMMPS rank, no atom sorting, so the
    order of the atoms is the order of their creation."""
    text = COLUMN_DECK.read_text()
    text = text.replace("create_box      1 box\n", "create_box      1 box\natom_modify     sort 0 0.0\n")
    bed = ("region          bed block 0.0009 0.0391 0.0009 0.05 -0.001 0.001 units box\n"
           "create_atoms    1 region bed\n")
    assert bed in text
    text = text.replace(bed, "".join(  # top rows first, the core's bottom rows last
        f"region          bed{k} block 0.0009 0.0391 {lo} {hi} -0.001 0.001 units box\n"
        f"create_atoms    1 region bed{k}\n"
        for k, (lo, hi) in enumerate([(0.0265, 0.05), (0.0125, 0.0265), (0.0009, 0.0125)])) +
        # the bottom row (at sqrt(3)/2 d) onto the floor: the deck's damped settling would take
        # far longer than its steps to let the column fall there, and its grains would not touch
        "displace_atoms  all move 0 -0.000732 0 units box\n")
    evaporate = ("region          top block INF INF 0.045 INF -0.001 0.001 units box\n"
                 "fix             evap all evaporate 1 1000 top 4711\n")
    couple = "fix             couple all hybrid/mpm"
    assert couple in text
    text = re.sub(r"^(thermo_style    custom step atoms f_couple.*)$", r"\1 f_evap", text, flags=re.M)
    # the step count restarts before the fixes are defined (fix evaporate counts from its definition)
    assert "reset_timestep  0\n" in text
    text = text.replace("reset_timestep  0\n", "").replace("region          core", "reset_timestep  0\nregion          core")
    decks = {"first": text.replace(couple, evaporate + couple),
             "after": re.sub(r"(fix\s+couple all hybrid/mpm.*?\n(?!\s))", r"\1" + evaporate, text, flags=re.S)}
    assert decks["after"] != text
    points, atoms = {}, {}
    for name, deck_text in decks.items():
        run_dir = tmp_path / name
        run_dir.mkdir()
        (run_dir / "deck.lmp").write_text(deck_text)
        # (every 1: the frame of the exchange at step 1, right after the rezone)
        log = run_deck(run_dir, run_dir / "deck.lmp", 1, "-var", "nsteps", "1", "-var", "every", "1")
        rows = thermo_tables(log)[-1]
        assert rows[-1]["Step"] == 1 and rows[-1]["f_couple[3]"] > 0
        assert rows[-1]["f_evap"] >= 20  # the top rows went at step 1
        atoms[name] = rows[-1]["Atoms"]
        frame = mpm_results.Run(run_dir / "frames").frame(-1)
        order = np.lexsort((frame["position"][:, 0], frame["position"][:, 1]))
        points[name] = {k: frame[k][order] for k in ("position", "stress")}
    assert atoms["first"] == atoms["after"]
    first, after = points["first"], points["after"]
    assert first["position"].shape == after["position"].shape
    assert np.abs(first["position"] - after["position"]).max() < 1e-12
    scale = np.abs(after["stress"]).max()
    assert scale > 0.1 * 9.81 * 0.0055 / 0.04  # the grains touch: a tenth of the column's weight per width
    diff = np.abs(first["stress"] - after["stress"]).max()
    assert diff <= 1e-9 * scale, f"points' stress differs by {diff / scale:.3g} of its largest value"
