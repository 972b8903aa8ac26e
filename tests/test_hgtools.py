"""tools/hgtools: the one runner, log reader and settled-state cache the scene drivers share."""
from __future__ import annotations

import hashlib
import json

import pytest

from hgtools import logs
from hgtools.cache import Settled
from hgtools.runner import TOOLS, Forms, RunFailed, command, run_deck

LOG = """LAMMPS (7 Jan 2022)
Step Time KinEng
       0            0            1
     100          0.1          0.5
WARNING: 3 atoms lost (src/thermo.cpp:444)
Loop time of 1.5 on 2 procs for 100 steps with 10 atoms
label           collapse_stage
Step Time KinEng f_couple[8]
     100          0.1          0.5            2
     200          0.2         0.25            2
Loop time of 2.5 on 2 procs for 100 steps with 10 atoms
DEM3D contact: kn = 1000 N/m, kt = 285.7 N/m, gamma_n = 5 1/s, gamma_t = 2.5 1/s, gamma_n(wall) = 7 1/s, gamma_t(wall) = 3.5 1/s
DEM3D timestep: tc = 1e-4 s, dt = 5e-6 s, rest KE/grain < 1e-9 J
"""


def test_thermo_tables_rows_and_loops():
    tables = logs.thermo_tables(LOG)
    assert [len(t) for t in tables] == [2, 2]            # the warning line is no row
    rows = logs.thermo_rows(LOG)
    assert [r["Step"] for r in rows] == [0, 100, 200]    # step 100, printed twice, counts once
    assert [r["Step"] for r in logs.thermo_rows(LOG, require="f_couple[8]")] == [100, 200]
    assert logs.loops(LOG) == (200, 4.0)
    assert logs.loops(LOG, after="label           collapse_stage") == (100, 2.5)
    params = logs.contact_params(LOG, "DEM3D")
    assert params["gamma_n(wall)"] == 7 and params["kt"] == 285.7 and params["dt"] == 5e-6
    with pytest.raises(RuntimeError, match="not in the log"):
        logs.number(r"^IMPACT end: (\S+)", LOG)


def test_command_lines_of_the_three_codes(tmp_path):
    deck, log = tmp_path / "deck.lmp", tmp_path / "log.txt"
    one = command("lammps", deck, {"out": tmp_path, "seed": 3}, log, exe="lmp")
    assert one == ["lmp", "-in", str(deck), "-log", str(log), "-screen", "none", "-var", "out", str(tmp_path),
                   "-var", "seed", "3"]
    two = command("liggghts", deck, {}, log, np_=2, exe="liggghts")
    assert two[:3] == [str(TOOLS / "mpirun.sh"), "-np", "2"] and two[-1] == "-nocite"
    hybrid = command("hybrid", deck, {"a": 1}, log, np_=2)
    assert hybrid[1:5] == [str(TOOLS / "hybrid_launch.py"), "-np", "2", str(deck)]
    forms = Forms("plough")
    assert forms.deck("liggghts").name == "liggghts_3d.in" and forms.deck("hybrid").name == "dem_3d.lmp"
    assert forms.variables("hybrid", {"d": 1}, {"hybrid": 2}) == {"d": 1, "hybrid": 2, "hdeck": forms.hybrid_deck()}
    assert forms.variables("lammps", {"d": 1}, {"hcell": 2}) == {"d": 1}


def test_a_failed_run_names_the_code_the_stage_and_the_log_tail(tmp_path, lmp):
    deck = tmp_path / "bad.lmp"
    deck.write_text("units si\nnot_a_command 1\n")
    done = run_deck("lammps", deck, {}, tmp_path / "log.txt", exe=lmp, timeout=60)
    with pytest.raises(RunFailed, match=r"(?s)lammps failed to prepare the test \(1\).*not_a_command"):
        done.check("to prepare the test")


def test_cache_keys_stay_those_of_the_existing_entries(tmp_path):
    """The shared cache is keyed as before the runner existed, so every clone's settled states stay valid."""
    deck = tmp_path / "deck.lmp"
    deck.write_bytes(b"deck")
    params = dict(a=2.0, w=0.1, d=0.002, seed=12345)
    entry = Settled.entry("dem_column", "a2_w0.1_d0.002_s12345", params, (deck,), "settled.restart", tmp_path)
    key = hashlib.sha1(json.dumps(params, sort_keys=True).encode()).hexdigest()[:10]
    assert entry.path == (tmp_path / "dem_column" / f"a2_w0.1_d0.002_s12345_{key}_{hashlib.sha1(b'deck').hexdigest()[:10]}"
                          / "settled.restart")
    assert not entry.cached()
    state = tmp_path / "settled.restart"
    state.write_text("state")
    entry.store(state, {"grains": 5})
    assert entry.cached(with_info=True) and entry.info() == {"grains": 5} and entry.path.read_text() == "state"
