"""Faults and bad input (issue 17): a fast subset of the fault campaign, and its committed table.

tools/fault_campaign.py runs the whole campaign (kill -9 of either side, bad decks, options, scene
files, restart/state/HDF5 files, NaNs, and tools/hostile_peer.py speaking the wire protocol wrongly in
LAMMPS's place) and writes docs/results/faults.{json,md}. Here a few cases of each kind run again
and must end as the campaign says they do; every run has a timeout (a hang is a failure).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

from conftest import REPO

import fault_campaign as fc   # tools/ is on sys.path (conftest)

RESULTS = REPO / "docs" / "results" / "faults.json"
CASES = {c.name: c for c in fc.all_cases(trials=10, quick_trials=3)}
# a campaign case may take this long before it counts as a hang (tools/fault_campaign.py --timeout)
CASE_TIMEOUT = 60.0


def run(name: str, tmp_path) -> dict:
    case = CASES[name]
    work = tmp_path / "work"
    shared = tmp_path / "shared"
    work.mkdir(exist_ok=True)
    shared.mkdir(exist_ok=True)
    d = work / name
    d.mkdir()
    return fc.run_case(case, fc.Ctx(d, fc.programs(), shared), CASE_TIMEOUT)


# --------------------------------------------------------------------------- the peer
def test_hostile_peer_speaks_the_protocol_in_its_valid_mode(hybrid_programs, tmp_path):
    """The control: without an attack the mpi4py peer handshakes, exchanges and finishes cleanly, so
    the errors below come from the attacks, not from a peer that gets the protocol wrong."""
    cmd = fc.Ctx(tmp_path, hybrid_programs, tmp_path).hostile("valid")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, env=fc.job_env("test-valid"))
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    assert "hostile_peer: handshake ok: mpm_solver" in text, text
    # the stand-in names no DEM host the MPM process knows in its handshake
    assert "mpm_solver: coupled run finished at the DEM host's step 30 after 3 exchange(s)" in text, text


@pytest.mark.parametrize("name, message", [
    ("peer_hello_truncated", r"refused the handshake: version mismatch: .*a 100-byte Hello"),
    ("peer_hello_huge_grid", r"refused the handshake: the grid cell size .* gives a grid of .* nodes"),
    # these used to leave the peer waiting for its reply timeout: now an error acknowledgement
    ("peer_header_truncated", r"answered with an error: protocol error: .*has 30 bytes, expected 56"),
    ("peer_out_of_order_two_headers", r"answered with an error: protocol error: received StepHeader"),
    ("peer_header_time_jump", r"answered with an error: protocol error: the step header of step 30 is at t = 1000000"),
    ("peer_records_node_off_grid", r"answered with an error: .*node 1000000000 outside the grid"),
    # these used to be accepted (NaN spread into the continuum; zone 7 indexed out of range)
    ("peer_records_nan_momentum", r"answered with an error: .*non-finite \(NaN or inf\) mass or momentum"),
    ("peer_rezone_zone_value_bad", r"answered with an error: .*the unknown zone 7"),
    ("peer_hello_container_outside", r"refused the handshake: the container along x"),
    ("peer_die_mid_exchange", r"exited on signal 9"),
])
def test_hostile_peer_message_ends_in_a_clear_error(hybrid_programs, tmp_path, name, message):
    row = run(name, tmp_path)
    assert row["outcome"] == "clear_error", row
    assert re.search(message, row["message"]), row
    assert row["seconds_to_exit"] < 30, row


# ---------------------------------------------------------------------- bad input, files
@pytest.mark.parametrize("name, message", [
    ("fix_keyword_typo", r"ERROR: Illegal fix hybrid/mpm command: unknown keyword 'evrey'"),
    # used to run on as pure DEM with 0 material points
    ("deck_region_matches_no_cell", r"ERROR: Fix hybrid/mpm: continuum region 'sliver' contains no grid cell centre"),
    # used to be a segfault of lmp_hybrid
    ("deck_nan_grain_velocity", r"ERROR: Fix hybrid/mpm: atom 1 has a non-finite \(NaN or inf\) position, velocity"),
    ("mpm_state_truncated", r"ERROR: Fix hybrid/mpm: loading the MPM state failed: .* is not an MPM state file"),
])
def test_bad_input_is_a_clear_error(hybrid_programs, tmp_path, name, message):
    row = run(name, tmp_path)
    assert row["outcome"] == "clear_error", row
    assert re.search(message, row["message"]), row


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting the small tmpfs that fills up needs root")
def test_hdf5_output_on_a_full_disk_is_a_clear_error_not_a_segfault(hybrid_programs, tmp_path):
    """The frames fill a 192 KiB tmpfs mid-run: mpm_solver used to report it and then segfault in
    HDF5's clean-up at MPI_Finalize."""
    row = run("hdf5_output_disk_full_midrun", tmp_path)
    assert row["outcome"] == "clear_error", row
    assert re.search(r"HDF5 output file .*points\.h5': cannot (flush|write)", row["message"]), row
    assert "No space left on device" in (tmp_path / "work" / "hdf5_output_disk_full_midrun" / "output.txt").read_text()


# --------------------------------------------------------------------------------- kills
@pytest.mark.parametrize("name", ["kill_mpm_np2_0", "kill_lammps_np2_0"])
def test_kill_9_of_either_side_stops_both_within_10_s_with_files_readable(hybrid_programs, tmp_path, name):
    row = run(name, tmp_path)
    assert row["outcome"] == "stopped_both", row["message"]
    assert row["seconds_to_exit"] <= fc.KILL_LIMIT, row
    assert "exited on signal 9 (Killed)" in row["message"], row
    # the newest restart with its MPM state, or (the MPM process killed between the two writes)
    # without it and the previous restart's state readable, or (LAMMPS killed while it wrote
    # the newest) the one before whole with its state
    assert re.search(r"(restart\.\d+\.bin cut short by the kill; )?restart\.\d+\.bin ok; "
                     r"(its|not written; restart\.\d+\.bin's) \.mpm\.h5 ok; points\.h5 ok", row["message"]), row


def test_a_restart_cut_short_by_the_kill_passes_only_when_the_one_before_reads_back(hybrid_programs, tmp_path):
    """LAMMPS writes restart files in place, so a kill -9 while it writes one leaves it cut short (a
    kill trial once landed there); the campaign then asks for the restart before it, whole."""
    deck = tmp_path / "write.lmp"
    deck.write_text("region box block 0 1 0 1 0 1\ncreate_box 1 box\ncreate_atoms 1 single 0.5 0.5 0.5\n"
                    "mass 1 1.0\nwrite_restart restart.100.bin\nwrite_restart restart.200.bin\n")
    subprocess.run([hybrid_programs["lmp_hybrid"], "-in", str(deck), "-log", "none", "-screen", "none"],
                   cwd=tmp_path, check=True, timeout=60, env=fc.job_env("test-restarts"))
    ctx = fc.Ctx(tmp_path, hybrid_programs, tmp_path)
    ok, notes = fc.readable_files(ctx)
    assert ok and notes.startswith("restart.200.bin ok;"), notes

    def cut(name):
        f = tmp_path / name
        f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])

    cut("restart.200.bin")
    ok, notes = fc.readable_files(ctx)
    assert ok and notes.startswith("restart.200.bin cut short by the kill; restart.100.bin ok;"), notes
    cut("restart.100.bin")
    ok, notes = fc.readable_files(ctx)
    assert not ok and notes.startswith("restart.200.bin unreadable"), notes


# ------------------------------------------------------------------ the committed table
def committed() -> dict:
    return json.loads(RESULTS.read_text())


def test_committed_campaign_has_40_distinct_bad_inputs_and_no_hang_or_crash():
    data = committed()
    rows = data["rows"]
    names = [r["case"] for r in rows]
    assert len(names) == len(set(names)), "duplicate case names"
    bad_inputs = [r for r in rows if r["kind"] != "kill"]
    assert len(bad_inputs) >= 40, len(bad_inputs)
    assert all(r["kind"] in fc.KINDS and r["outcome"] in fc.OUTCOMES for r in rows)
    failed = [r for r in rows if r["outcome"] in ("hang", "crash", "wrong_result")]
    assert not failed, failed
    assert all(r["message"] for r in rows), [r["case"] for r in rows if not r["message"]]


def test_committed_campaign_kills_all_stopped_both_sides_within_10_s():
    kills = [r for r in committed()["rows"] if r["kind"] == "kill"]
    # 10 trials per side (MPM process, a LAMMPS rank) and LAMMPS rank count (1, 2)
    assert len(kills) == 40, len(kills)
    for side in ("mpm", "lammps"):
        for np_ in (1, 2):
            assert sum(1 for r in kills if r["case"].startswith(f"kill_{side}_np{np_}_")) == 10
    assert all(r["outcome"] == "stopped_both" and r["seconds_to_exit"] <= fc.KILL_LIMIT for r in kills), \
        [r for r in kills if r["outcome"] != "stopped_both"]


def test_committed_campaign_covers_every_case_of_the_campaign():
    """The table is the whole campaign, not a stale or partial run: same case names."""
    assert {r["case"] for r in committed()["rows"]} == set(CASES)
    md = (REPO / "docs" / "results" / "faults.md").read_text()
    assert all(f"`{name}`" in md for name in CASES)


def test_campaign_lists_its_cases_from_the_command_line():
    proc = subprocess.run([sys.executable, str(REPO / "tools" / "fault_campaign.py"), "--list", "--quick"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    listed = [ln.split()[0] for ln in proc.stdout.splitlines()]
    assert listed and set(listed) == {n for n, c in CASES.items() if c.quick}
