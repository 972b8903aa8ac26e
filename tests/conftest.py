"""Shared fixtures: where the built programs are, and how to run them."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
BUILD = Path(os.environ.get("HYBRID_BUILD_DIR", REPO / "build"))
sys.path.insert(0, str(REPO / "tools"))


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def mpm_solver() -> Path:
    exe = BUILD / "mpm_solver" / "mpm_solver"
    if not exe.exists():
        pytest.fail(f"{exe} is not built; run tools/setup.sh first")
    return exe


def run_mpm(exe: Path, scene: Path, *args: str, timeout: float = 900, check: bool = True,
            threads: int = 2) -> subprocess.CompletedProcess:
    """Runs mpm_solver on `scene` and returns the completed process (text output)."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    proc = subprocess.run([str(exe), str(scene), "--quiet", *args], capture_output=True, text=True,
                          timeout=timeout, env=env)
    if check and proc.returncode != 0:
        raise AssertionError(f"mpm_solver failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    return proc


def assert_twin_params_agree(results: dict, rel: float = 1e-9) -> None:
    """The LAMMPS deck and its LIGGGHTS twin printed the same contact parameters and time step
    (`results[code].params`, the values each deck prints)."""
    a, b = results["lammps"].params, results["liggghts"].params
    assert a.keys() == b.keys()
    for k in a:
        assert a[k] == pytest.approx(b[k], rel=rel), (k, a[k], b[k])


@pytest.fixture(scope="session")
def lmp() -> str:
    """Debian's stock LAMMPS; a missing one fails the test (never skips)."""
    exe = shutil.which("lmp")
    if exe is None:
        pytest.fail("Debian's LAMMPS (lmp) is not on PATH; run tools/setup.sh")
    return exe


@pytest.fixture(scope="session")
def liggghts() -> str:
    """Debian's LIGGGHTS, the second pure-DEM reference; a missing one fails the test."""
    exe = shutil.which("liggghts")
    if exe is None:
        pytest.fail("LIGGGHTS cannot run the reference: `liggghts` is not on PATH (Debian package "
                    "liggghts, installed by tools/setup.sh)")
    return exe


# ---- coupled LAMMPS + MPM runs (tests/test_coupled_launch.py) ----------------------------

@pytest.fixture(scope="session")
def hybrid_programs() -> dict:
    """Paths of lmp_hybrid, mpm_solver, the PLUGIN-enabled lmp and hybridmpmplugin.so, as
    lammps_fix_hybrid/CMakeLists.txt wrote them (empty strings for the plugin pair if the
    PLUGIN-enabled LAMMPS was not found at configure time)."""
    import json
    path = BUILD / "lammps_fix_hybrid" / "hybrid_programs.json"
    if not path.exists():
        pytest.fail(f"{path} is missing; run tools/setup.sh first")
    programs = json.loads(path.read_text())
    for key in ("lmp_hybrid", "mpm_solver"):
        if not Path(programs[key]).exists():
            pytest.fail(f"{programs[key]} is not built; run tools/setup.sh first")
    return programs


@pytest.fixture(scope="session")
def hybrid_plugin(hybrid_programs) -> tuple[Path, Path]:
    """(lmp_plugin, hybridmpmplugin.so); skips if the PLUGIN-enabled LAMMPS is not built."""
    lmp, plugin = hybrid_programs.get("lmp_plugin", ""), hybrid_programs.get("plugin", "")
    if not lmp or not Path(lmp).exists():
        pytest.skip("the PLUGIN-enabled LAMMPS is not built (tools/setup.sh builds it into "
                    "$HYBRID_CACHE/lammps-plugin; reconfigure afterwards)")
    if not plugin or not Path(plugin).exists():
        pytest.fail(f"hybridmpmplugin.so is not built although {lmp} exists; run tools/setup.sh")
    return Path(lmp), Path(plugin)
