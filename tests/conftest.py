"""Shared fixtures: where the built programs are, and how to run them."""
from __future__ import annotations

import os
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
