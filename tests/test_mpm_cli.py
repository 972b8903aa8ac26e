"""mpm_solver as a user meets it: help, bad scenes, unstable steps."""
from __future__ import annotations

import subprocess

from conftest import run_mpm

GOOD = """dimension = 2
end_time = 0.01
[grid]
cell_size = 0.01
lower = [0.0, 0.0]
upper = [0.3, 0.2]
[[material]]
name = "sand"
[[block]]
material = "sand"
lower = [0.0, 0.0]
upper = [0.1, 0.1]
"""


def test_help_documents_every_table_and_key(mpm_solver):
    out = subprocess.run([str(mpm_solver), "--help"], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0
    for key in ("cell_size", "friction_angle", "mu_s", "critical_density", "points_per_cell", "separating",
                "[[boundary]]", "[output]", "--threads"):
        assert key in out.stdout, key


def test_typo_in_a_key_names_the_key_and_suggests_the_fix(tmp_path, mpm_solver):
    scene = tmp_path / "typo.toml"
    scene.write_text(GOOD.replace('name = "sand"', 'name = "sand"\nfrction_angle = 35'))
    proc = run_mpm(mpm_solver, scene, check=False)
    assert proc.returncode == 2
    assert "frction_angle" in proc.stderr and "friction_angle" in proc.stderr
    assert "Traceback" not in proc.stderr and "terminate" not in proc.stderr


def test_unstable_fixed_step_is_refused_with_the_safe_step(tmp_path, mpm_solver):
    scene = tmp_path / "unstable.toml"
    scene.write_text(GOOD + "[time]\ndt = 0.01\n")
    proc = run_mpm(mpm_solver, scene, "--no-output", check=False)
    assert proc.returncode == 2
    assert "is above the stable step" in proc.stderr
    safe = float(proc.stderr.split("set [time] dt <= ")[1].split()[0])
    # The step it names is safe: the same scene runs with it.
    scene.write_text(GOOD + f"[time]\ndt = {safe * 0.99:.6e}\n")
    run_mpm(mpm_solver, scene, "--no-output")


def test_material_outside_the_grid_is_an_error_naming_the_block(tmp_path, mpm_solver):
    scene = tmp_path / "outside.toml"
    scene.write_text(GOOD.replace("upper = [0.1, 0.1]", "upper = [0.1, 0.5]"))
    proc = run_mpm(mpm_solver, scene, check=False)
    assert proc.returncode == 2
    assert "[[block]]" in proc.stderr and "upper" in proc.stderr
