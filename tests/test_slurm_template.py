"""docs/slurm_hybrid.sh, the Slurm job template, serves both DEM hosts: HOST chooses lmp_hybrid
(default) or liggghts_hybrid and its default deck, anything else is refused naming it. Run with a
stand-in srun that keeps the --multi-prog file it is given, over a stand-in checkout."""
from __future__ import annotations

import os
import stat
import subprocess
from pathlib import Path

import pytest

from conftest import REPO

TEMPLATE = REPO / "docs" / "slurm_hybrid.sh"


def executable(path: Path, text: str = "#!/bin/sh\nexit 0\n") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)


@pytest.fixture
def job(tmp_path):
    """Runs the template as sbatch would (3 tasks) with HOST; returns the process and the
    multi-prog file srun was given ("" if none)."""
    repo = tmp_path / "repo"
    for program in ("lammps_fix_hybrid/lmp_hybrid", "lammps_fix_hybrid/liggghts_hybrid", "mpm_solver/mpm_solver"):
        executable(repo / "build" / program)
    kept = tmp_path / "multiprog.conf"
    executable(tmp_path / "bin" / "srun", f'#!/bin/sh\nfor a; do last="$a"; done\ncp "$last" "{kept}"\n')

    def run(host: str | None, missing: str | None = None):
        if missing:
            (repo / "build" / missing).unlink()
        env = {k: v for k, v in os.environ.items() if k not in ("HOST", "DECK")}
        env.update(REPO=str(repo), SLURM_NTASKS="3", PATH=f"{tmp_path / 'bin'}:{env['PATH']}")
        if host is not None:
            env["HOST"] = host
        proc = subprocess.run(["bash", str(TEMPLATE)], capture_output=True, text=True, env=env, cwd=tmp_path,
                              timeout=30)
        return proc, kept.read_text() if kept.exists() else "", repo
    return run


@pytest.mark.parametrize("host, program, deck", [
    (None, "lmp_hybrid", "handshake.lmp"),
    ("lammps", "lmp_hybrid", "handshake.lmp"),
    ("liggghts", "liggghts_hybrid", "momentum_3d.liggghts"),
])
def test_slurm_template_starts_the_chosen_dem_host(job, host, program, deck):
    proc, conf, repo = job(host)
    assert proc.returncode == 0, proc.stderr
    assert conf.splitlines() == [
        f"0-1 {repo}/build/lammps_fix_hybrid/{program} -in {repo}/input_decks/hybrid/{deck} -log log.lammps",
        f"2 env OMP_NUM_THREADS=1 {repo}/build/mpm_solver/mpm_solver --coupled",
    ], conf


def test_slurm_template_refuses_an_unknown_host_naming_it(job):
    proc, conf, _ = job("lammmps")
    assert proc.returncode == 2 and conf == "", proc.stderr
    assert "HOST=lammmps is not a DEM host of fix hybrid/mpm: use HOST=lammps or HOST=liggghts" in proc.stderr


def test_slurm_template_says_when_the_host_program_is_not_built(job):
    proc, conf, repo = job("liggghts", missing="lammps_fix_hybrid/liggghts_hybrid")
    assert proc.returncode == 2 and conf == "", proc.stderr
    assert f"{repo}/build/lammps_fix_hybrid/liggghts_hybrid is not built (tools/setup.sh in {repo})" in proc.stderr
