#!/usr/bin/env python3
"""A hostile DEM peer: takes LAMMPS's place in a coupled MPMD job and attacks mpm_solver --coupled.

    tools/mpirun.sh -np 1 $HYBRID_VENV/bin/python tools/hostile_peer.py MODE [--idle S] \\
                  : -np 1 build/mpm_solver/mpm_solver --coupled --timeout 10

It joins the job exactly as fix hybrid/mpm does (coupler/include/coupler/protocol.hpp): splits
MPI_COMM_WORLD with LAMMPS's colour 0, finds the MPM leader as the lowest world rank outside its
own communicator, sends a Hello over MPI_COMM_WORLD, reads the HelloReply and, when accepted,
creates the intercommunicator. The messages are the C structs of protocol.hpp, packed here with
ctypes (their layout is pinned in coupler/include/coupler/wire_layout.hpp; the sizes are checked
below). Then MODE decides what goes wrong: malformed, truncated, oversized, out-of-order and
wrong-version messages, NaNs in records, nodes off the grid, a peer that dies or hangs mid-exchange.
`--list` prints the modes.

Like the fix, the peer waits for every answer with a bound (`--reply-timeout`), prints what the
MPM process answered (`hostile_peer: the MPM process answered with an error: ...`) and ends like
LAMMPS does: one MPI_Barrier(MPI_COMM_WORLD) before MPI_Finalize (the end-of-job rule), exit
status 1 after an error, 0 after a clean finish (mode `valid`, the control).
"""
from __future__ import annotations

import argparse
import ctypes as C
import math
import os
import re
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

# ------------------------------------------------------------------------- wire structs
TEXT, VERSION = 256, 32
TAG = dict(hello=7301, hello_reply=7302, intercomm=7303, step=7310, ack=7311, zones=7312, volumes=7313,
           nodes=7314, node_reply=7315, grains=7316, state=7317, rezone_cells=7318, grain_sums=7319,
           finish=7320, corrections=7322, oracle=7323, support=7324, discrete=7325, abort=7330)
DEM_COLOR = 0
KIND_COUPLE, KIND_REZONE, KIND_SAVE, KIND_LOAD = 0, 1, 2, 3
ZONES_ORACLE, ZONES_INITIAL, ZONES_GIVEN = 0, 1, 2
GRID_PAD = 3   # coupler::kGridPad


class ContinuumSettings(C.Structure):
    _fields_ = [("youngs_modulus", C.c_double), ("poisson_ratio", C.c_double), ("friction_angle_deg", C.c_double),
                ("mu_s", C.c_double), ("mu_2", C.c_double), ("I0", C.c_double), ("grain_diameter", C.c_double),
                ("grain_density", C.c_double), ("critical_packing", C.c_double), ("gravity", C.c_double * 3),
                ("wall_contact", C.c_int32), ("pad0", C.c_int32), ("wall_friction", C.c_double),
                ("container_lo", C.c_double * 3), ("container_hi", C.c_double * 3), ("touched_faces", C.c_uint32),
                ("pad1", C.c_int32), ("cfl", C.c_double), ("grain_weight", C.c_double), ("pic", C.c_double),
                ("agreement_time", C.c_double), ("support_gain", C.c_double), ("fill_share", C.c_double),
                ("fill_modulus", C.c_double), ("packing_fraction", C.c_double), ("points_per_axis", C.c_int32),
                ("output_every", C.c_int32), ("output_path", C.c_char * TEXT)]


class Hello(C.Structure):
    _fields_ = [("protocol", C.c_int32), ("release", C.c_char * VERSION), ("host", C.c_char * VERSION),
                ("units", C.c_char * 8), ("dimension", C.c_int32), ("dem_ranks", C.c_int32), ("model", C.c_int32),
                ("mpm_every", C.c_int32), ("pad", C.c_int32), ("cell", C.c_double), ("dt", C.c_double),
                ("reply_timeout", C.c_double), ("idle_timeout", C.c_double), ("box_lo", C.c_double * 3),
                ("box_hi", C.c_double * 3), ("step", C.c_int64), ("time", C.c_double),
                ("continuum", ContinuumSettings)]


class HelloReply(C.Structure):
    _fields_ = [("protocol", C.c_int32), ("release", C.c_char * VERSION), ("ok", C.c_int32),
                ("mpm_ranks", C.c_int32), ("message", C.c_char * TEXT)]


class StepHeader(C.Structure):
    _fields_ = [("step", C.c_int64), ("time", C.c_double), ("dt", C.c_double), ("kind", C.c_int32),
                ("output", C.c_int32), ("n_grains", C.c_int64), ("next_time", C.c_double),
                ("zone_source", C.c_int32), ("field_shares", C.c_int32)]


class StepAck(C.Structure):   # only the leading fields are read; the size is checked
    _fields_ = [("step", C.c_int64), ("status", C.c_int32), ("substeps", C.c_int32), ("message", C.c_char * TEXT),
                ("rest", C.c_char * (536 - 272))]


class NodeRecord(C.Structure):
    _fields_ = [("node", C.c_uint64), ("mass", C.c_double), ("momentum", C.c_double * 3)]


class CellGrains(C.Structure):
    _fields_ = [("cell", C.c_uint64), ("volume", C.c_double), ("mass", C.c_double), ("kinetic", C.c_double)]


class StateRequest(C.Structure):
    _fields_ = [("path", C.c_char * 4096), ("exchanges", C.c_int64)]


class Finish(C.Structure):
    _fields_ = [("step", C.c_int64), ("exchanges", C.c_int64)]


class AbortNote(C.Structure):
    _fields_ = [("reason", C.c_char * TEXT)]


for _t, _n in ((ContinuumSettings, 496), (Hello, 688), (HelloReply, 300), (StepHeader, 56), (StepAck, 536),
               (NodeRecord, 40), (CellGrains, 32), (StateRequest, 4104), (Finish, 16), (AbortNote, 256)):
    assert C.sizeof(_t) == _n, f"{_t.__name__} is {C.sizeof(_t)} bytes, the wire layout says {_n}"


def protocol_version() -> int:
    text = (REPO / "coupler" / "include" / "coupler" / "version.hpp").read_text()
    return int(re.search(r"kProtocolVersion = (\d+);", text).group(1))


def release_version() -> str:
    text = (REPO / "CMakeLists.txt").read_text()
    return re.search(r"project\(\s*\w+\s+VERSION\s+([0-9.]+)", text).group(1)


# --------------------------------------------------------------------------- the scene
BOX = (0.1, 0.1)        # 2D box from the origin, m
CELL = 0.01
DT = 1.0e-5
EVERY = 10


def grid_dims(box=BOX, cell=CELL) -> list[int]:
    return [math.ceil(b / cell) + 2 * GRID_PAD + 1 for b in box]


def node_index(i: int, j: int) -> int:
    return i * grid_dims()[1] + j


def num_cells() -> int:
    n = 1
    for d in grid_dims():
        n *= d - 1
    return n


def valid_hello(idle: float, reply: float) -> Hello:
    h = Hello()
    h.protocol = protocol_version()
    h.release = release_version().encode()
    h.host = b"hostile_peer.py (mpi4py)"
    h.units = b"si"
    h.dimension, h.dem_ranks, h.model, h.mpm_every = 2, 1, 0, EVERY
    h.cell, h.dt, h.reply_timeout, h.idle_timeout = CELL, DT, reply, idle
    h.box_lo[:] = [0.0, 0.0, -0.001]
    h.box_hi[:] = [BOX[0], BOX[1], 0.001]
    h.step, h.time = 0, 0.0
    c = h.continuum
    c.youngs_modulus, c.poisson_ratio, c.friction_angle_deg = 1.0e7, 0.3, 30.0
    c.mu_s, c.mu_2, c.I0 = 0.382, 0.644, 0.279
    c.grain_diameter, c.grain_density, c.critical_packing = 2e-3, 2500.0, 0.6
    c.gravity[:] = [0.0, -9.81, 0.0]
    c.wall_contact = 1
    c.container_lo[:] = list(h.box_lo)
    c.container_hi[:] = list(h.box_hi)
    c.cfl, c.grain_weight, c.pic, c.agreement_time, c.support_gain = 0.5, 0.5, 1.0, 0.0, 1.0
    c.points_per_axis, c.output_every = 2, 0
    return h


def header(step: int, kind: int = KIND_COUPLE, next_time: float = -1.0) -> StepHeader:
    h = StepHeader()
    h.step, h.time, h.dt, h.kind, h.output, h.n_grains, h.next_time = step, step * DT, DT, kind, 0, 1, next_time
    return h


def record(node: int, mass: float = 1e-5, momentum=(0.0, -1e-7, 0.0)) -> NodeRecord:
    r = NodeRecord()
    r.node, r.mass = node, mass
    r.momentum[:] = list(momentum)
    return r


def records(*items: NodeRecord) -> bytes:
    return b"".join(bytes(r) for r in items)


# ------------------------------------------------------------------------------ the peer
class Peer:
    def __init__(self, args):
        from mpi4py import MPI   # imported here so that --list works without MPI
        self.MPI = MPI
        self.args = args
        world = MPI.COMM_WORLD
        self.world = world
        self.local = world.Split(DEM_COLOR, world.Get_rank())   # as lmp_hybrid's main
        self.remote = self.first_world_rank_outside()
        self.inter = None

    def say(self, text: str) -> None:
        print(f"hostile_peer: {text}", flush=True)

    def first_world_rank_outside(self) -> int:
        """coupler::first_world_rank_outside: local group arithmetic, no communication."""
        MPI = self.MPI
        mine = MPI.Group.Translate_ranks(self.local.Get_group(), list(range(self.local.Get_size())),
                                         self.world.Get_group())
        for r in range(self.world.Get_size()):
            if r not in mine:
                return r
        return -1

    # bounded point-to-point, as coupler::send_bytes / recv_message
    def send(self, comm, dest: int, tag: int, data: bytes, what: str) -> None:
        buf = bytearray(data)
        req = comm.Isend([buf, self.MPI.BYTE], dest=dest, tag=tag)
        t0 = time.monotonic()
        while not req.Test():
            if time.monotonic() - t0 > self.args.reply_timeout:
                self.say(f"could not deliver {what} within {self.args.reply_timeout} s; giving up (MPI_Abort)")
                self.MPI.COMM_WORLD.Abort(4)
            time.sleep(0.001)

    def recv(self, comm, source: int, what: str) -> tuple[int, bytes] | None:
        MPI = self.MPI
        status = MPI.Status()
        t0 = time.monotonic()
        while not comm.Iprobe(source=source, tag=MPI.ANY_TAG, status=status):
            if time.monotonic() - t0 > self.args.reply_timeout:
                return None
            time.sleep(0.001)
        n = status.Get_count(MPI.BYTE)
        buf = bytearray(n)
        comm.Recv([buf, MPI.BYTE], source=status.Get_source(), tag=status.Get_tag())
        return status.Get_tag(), bytes(buf)

    # the protocol's steps
    def hello(self, h: Hello | bytes, tag: int = TAG["hello"]) -> bool:
        """Sends the Hello and reads the reply; True if accepted (the intercommunicator exists then)."""
        data = bytes(h)
        self.send(self.world, self.remote, tag, data, "the Hello")
        got = self.recv(self.world, self.remote, "the HelloReply")
        if got is None:
            self.say(f"no HelloReply within {self.args.reply_timeout} s")
            return False
        tag, data = got
        if tag != TAG["hello_reply"] or len(data) != C.sizeof(HelloReply):
            self.say(f"unexpected reply: tag {tag}, {len(data)} bytes")
            return False
        reply = HelloReply.from_buffer_copy(data)
        text = reply.message.decode(errors="replace")
        if not reply.ok:
            self.say(f"the MPM process refused the handshake: {text}")
            return False
        self.inter = self.local.Create_intercomm(0, self.world, self.remote, TAG["intercomm"])
        self.say(f"handshake ok: {text}")
        return True

    def to_mpm(self, tag: str | int, data: bytes, what: str) -> None:
        self.send(self.inter, 0, TAG[tag] if isinstance(tag, str) else tag, data, what)

    def answer(self, expect: str, what: str) -> bytes | None:
        """The next message from the MPM process; None (after saying why) if it is an error
        acknowledgement, something else than `expect`, or nothing within the reply timeout."""
        got = self.recv(self.inter, 0, what)
        if got is None:
            self.say(f"no answer from the MPM process within {self.args.reply_timeout} s while waiting for {what}")
            return None
        tag, data = got
        if tag == TAG["ack"] and len(data) == C.sizeof(StepAck):
            ack = StepAck.from_buffer_copy(data)
            if ack.status != 0:
                self.say(f"the MPM process answered with an error: {ack.message.decode(errors='replace')}")
                return None
        if tag != TAG[expect]:
            self.say(f"unexpected message while waiting for {what}: tag {tag}, {len(data)} bytes")
            return None
        return data

    def exchange(self, step: int, recs: bytes, hdr: StepHeader | None = None) -> bool:
        """One regular exchange; True if acknowledged without error."""
        self.to_mpm("step", bytes(hdr if hdr is not None else header(step)), f"the step header of step {step}")
        self.to_mpm("nodes", recs, f"the node sums of step {step}")
        if self.answer("node_reply", f"the node velocities of step {step}") is None:
            return False
        return self.answer("ack", f"the acknowledgement of step {step}") is not None

    def finish(self, step: int, exchanges: int) -> None:
        f = Finish()
        f.step, f.exchanges = step, exchanges
        self.to_mpm("finish", bytes(f), "the finish message")

    def end_of_job(self, rc: int) -> int:
        """LAMMPS's end: MPI_Barrier(MPI_COMM_WORLD), then MPI_Finalize (mpi4py at exit)."""
        self.world.Barrier()
        return rc


# ------------------------------------------------------------------------------- modes
GOOD = records(record(node_index(8, 8)), record(node_index(8, 9)), record(node_index(9, 8)))
NAN = float("nan")


def handshake_mode(make):
    """A mode that attacks the handshake: make(args) -> (bytes to send as Hello, tag)."""
    def run(peer: Peer) -> int:
        data, tag = make(peer.args)
        if peer.hello(data, tag):
            peer.say("the MPM process ACCEPTED a bad handshake")
            peer.finish(0, 0)
            return peer.end_of_job(0)
        return peer.end_of_job(1)
    return run


def hello_with(**changes):
    """A valid Hello with fields changed (continuum fields as c_<name>)."""
    def make(args):
        h = valid_hello(args.idle, args.reply_timeout)
        for k, v in changes.items():
            target = h.continuum if k.startswith("c_") else h
            name = k[2:] if k.startswith("c_") else k
            if isinstance(v, tuple):
                getattr(target, name)[:] = list(v)
            else:
                setattr(target, name, v)
        return bytes(h), TAG["hello"]
    return make


def exchange_mode(attack, warmup: int = 2):
    """A mode that attacks after a valid handshake and `warmup` good exchanges.
    attack(peer, step) sends the bad messages and returns True if the MPM process accepted them."""
    def run(peer: Peer) -> int:
        if not peer.hello(valid_hello(peer.args.idle, peer.args.reply_timeout)):
            return peer.end_of_job(1)
        step = 0
        for _ in range(warmup):
            step += EVERY
            if not peer.exchange(step, GOOD):
                return peer.end_of_job(1)
        peer.say(f"{warmup} good exchange(s) done; attacking at step {step + EVERY}")
        if attack(peer, step + EVERY):
            peer.say("the MPM process ACCEPTED the attack")
            peer.finish(step + EVERY, warmup + 1)
            return peer.end_of_job(0)
        return peer.end_of_job(1)
    return run


def bad_header(data_of):
    def attack(peer, step):
        peer.to_mpm("step", data_of(step), "a bad step header")
        peer.to_mpm("nodes", GOOD, "the node sums")
        return peer.answer("node_reply", "the node velocities") is not None and \
            peer.answer("ack", "the acknowledgement") is not None
    return attack


def header_with(**changes):
    def data_of(step):
        h = header(step)
        for k, v in changes.items():
            setattr(h, k, v)
        return bytes(h)
    return bad_header(data_of)


def bad_records(data):
    def attack(peer, step):
        return peer.exchange(step, data)
    return attack


def send_then_wait(messages):
    """Sends (tag, bytes) pairs, then waits for any answer: an error acknowledgement is the expected one."""
    def attack(peer, step):
        for tag, data in messages(step):
            peer.to_mpm(tag, data, f"a message with tag {tag}")
        got = peer.recv(peer.inter, 0, "an answer")
        if got is None:
            peer.say(f"no answer from the MPM process within {peer.args.reply_timeout} s")
            return False
        tag, data = got
        if tag == TAG["ack"] and len(data) == C.sizeof(StepAck):
            ack = StepAck.from_buffer_copy(data)
            if ack.status != 0:
                peer.say(f"the MPM process answered with an error: {ack.message.decode(errors='replace')}")
                return False
        peer.say(f"the MPM process answered tag {tag} ({len(data)} bytes)")
        return True
    return attack


def die(after):
    """Sends what `after` sends, then the peer process dies (SIGKILL to itself)."""
    def attack(peer, step):
        for tag, data in after(step):
            peer.to_mpm(tag, data, f"a message with tag {tag}")
        peer.say("dying now (SIGKILL) in the middle of the exchange")
        sys.stdout.flush()
        os.kill(os.getpid(), 9)
        return False
    return attack


def hang(after):
    """Sends what `after` sends, then never sends anything again (until killed)."""
    def attack(peer, step):
        for tag, data in after(step):
            peer.to_mpm(tag, data, f"a message with tag {tag}")
        peer.say("hanging in the middle of the exchange")
        while True:
            time.sleep(1)
    return attack


def rezone_given(zone_map: bytes, volumes: bytes = b""):
    def attack(peer, step):
        h = header(step, KIND_REZONE)
        h.zone_source = ZONES_GIVEN
        peer.to_mpm("step", bytes(h), "the rezone header")
        peer.to_mpm("zones", zone_map, "the zone map")
        peer.to_mpm("volumes", volumes, "the grain volumes")
        return peer.answer("zones", "the new zone map") is not None
    return attack


def silent(peer: Peer) -> int:
    peer.say("sending nothing, staying alive")
    while True:
        time.sleep(1)


def die_before_hello(peer: Peer) -> int:
    peer.say("dying (SIGKILL) before the handshake")
    sys.stdout.flush()
    os.kill(os.getpid(), 9)
    return 9


def valid(peer: Peer) -> int:
    """The control: a correct session (handshake, exchanges, finish); the MPM process exits 0."""
    if not peer.hello(valid_hello(peer.args.idle, peer.args.reply_timeout)):
        return peer.end_of_job(1)
    for k in range(1, 4):
        if not peer.exchange(k * EVERY, GOOD):
            return peer.end_of_job(1)
    peer.finish(3 * EVERY, 3)
    peer.say("3 exchanges and finish: ok")
    return peer.end_of_job(0)


def oversized_records(step):
    n = 2_000_000   # 80 MB of records, nodes all over the index range
    recs = (NodeRecord * n)()
    for k in range(0, n, 997):
        recs[k].node = 10 ** 12 + k
    return bytes(recs)


MODES = {
    "valid": (valid, "control: a correct session, the MPM process exits 0"),
    # --- handshake
    "hello_wrong_protocol": (handshake_mode(hello_with(protocol=protocol_version() - 1)),
                             "Hello announcing the previous protocol version"),
    "hello_wrong_release": (handshake_mode(hello_with(release=b"9.9.9")), "Hello from another release"),
    "hello_truncated": (handshake_mode(lambda a: (bytes(valid_hello(a.idle, a.reply_timeout))[:100], TAG["hello"])),
                        "Hello cut to 100 bytes"),
    "hello_empty": (handshake_mode(lambda a: (b"", TAG["hello"])), "empty Hello (0 bytes)"),
    "hello_oversized": (handshake_mode(lambda a: (bytes(valid_hello(a.idle, a.reply_timeout)) + bytes(1 << 20),
                                                  TAG["hello"])), "Hello followed by 1 MiB of zeros"),
    "hello_wrong_tag": (handshake_mode(lambda a: (bytes(valid_hello(a.idle, a.reply_timeout)), 4242)),
                        "the Hello sent with an unknown tag"),
    "hello_step_first": (handshake_mode(lambda a: (bytes(header(0)), TAG["step"])),
                         "a step header before any Hello (out of order)"),
    "hello_units_lj": (handshake_mode(hello_with(units=b"lj")), "units lj"),
    "hello_dimension_4": (handshake_mode(hello_with(dimension=4)), "dimension 4"),
    "hello_cell_nan": (handshake_mode(hello_with(cell=NAN)), "NaN cell size"),
    "hello_dt_negative": (handshake_mode(hello_with(dt=-1e-5)), "negative DEM time step"),
    "hello_model_unknown": (handshake_mode(hello_with(model=7)), "unknown constitutive model id"),
    "hello_every_zero": (handshake_mode(hello_with(mpm_every=0)), "exchange interval 0"),
    "hello_box_inverted": (handshake_mode(hello_with(box_lo=(0.1, 0.1, 0.001), box_hi=(0.0, 0.0, -0.001))),
                           "box with lo > hi"),
    "hello_box_nan": (handshake_mode(hello_with(box_hi=(NAN, 0.1, 0.001))), "NaN in the box"),
    "hello_huge_grid": (handshake_mode(hello_with(cell=1e-6)), "cell 1e-6 m on a 0.1 m box (1e10 nodes)"),
    "hello_poisson_bad": (handshake_mode(hello_with(c_poisson_ratio=0.7)), "Poisson ratio 0.7"),
    "hello_gravity_nan": (handshake_mode(hello_with(c_gravity=(0.0, NAN, 0.0))), "NaN gravity"),
    "hello_cfl_zero": (handshake_mode(hello_with(c_cfl=0.0)), "Courant number 0"),
    "hello_container_outside": (handshake_mode(hello_with(c_container_lo=(-5.0, 0.0, -0.001))),
                                "container wall outside the box"),
    "hello_points_per_axis_0": (handshake_mode(hello_with(c_points_per_axis=0)), "0 points per cell"),
    "hello_silent": (silent, "the peer never sends the Hello (the MPM --timeout ends it)"),
    "hello_die": (die_before_hello, "the peer dies before the handshake"),
    # --- exchanges
    "header_truncated": (exchange_mode(bad_header(lambda s: bytes(header(s))[:30])), "step header cut to 30 bytes"),
    "header_oversized": (exchange_mode(bad_header(lambda s: bytes(header(s)) + bytes(64))),
                         "step header with 64 extra bytes"),
    "header_time_nan": (exchange_mode(header_with(time=NAN)), "NaN time in a step header"),
    "header_time_backwards": (exchange_mode(header_with(time=-1.0)), "time going backwards"),
    "header_time_jump": (exchange_mode(header_with(time=1.0e6)), "time jumping by 1e6 s in one exchange"),
    "header_next_time_inf": (exchange_mode(header_with(next_time=float("inf"))), "infinite next exchange time"),
    "header_kind_unknown": (exchange_mode(header_with(kind=99)), "unknown step kind 99"),
    "records_node_off_grid": (exchange_mode(bad_records(records(record(10 ** 9)))), "node index off the grid"),
    "records_node_max": (exchange_mode(bad_records(records(record(2 ** 64 - 1)))), "node index 2^64-1"),
    "records_nan_momentum": (exchange_mode(bad_records(records(record(node_index(8, 8), momentum=(NAN, 0, 0))))),
                             "NaN momentum in a node record"),
    "records_nan_mass": (exchange_mode(bad_records(records(record(node_index(8, 8), mass=NAN)))),
                         "NaN mass in a node record"),
    "records_negative_mass": (exchange_mode(bad_records(records(record(node_index(8, 8), mass=-1.0)))),
                              "negative mass in a node record"),
    "records_inf_momentum": (exchange_mode(bad_records(records(record(node_index(8, 8),
                                                                      momentum=(0, float("inf"), 0))))),
                             "infinite momentum in a node record"),
    "records_ragged": (exchange_mode(bad_records(GOOD + b"\x01\x02\x03")), "node records plus 3 stray bytes"),
    "records_oversized": (exchange_mode(lambda p, s: p.exchange(s, oversized_records(s))),
                          "80 MB of node records, nodes off the grid"),
    "out_of_order_records_first": (exchange_mode(send_then_wait(lambda s: [("nodes", GOOD)])),
                                   "node records where a step header is due"),
    "out_of_order_two_headers": (exchange_mode(send_then_wait(lambda s: [("step", bytes(header(s))),
                                                                         ("step", bytes(header(s)))])),
                                 "a second step header where the node records are due"),
    "unknown_tag": (exchange_mode(send_then_wait(lambda s: [(4242, b"hostile")])), "a message with an unknown tag"),
    "reply_tag_from_dem": (exchange_mode(send_then_wait(lambda s: [("ack", bytes(StepAck()))])),
                           "a StepAck sent to the MPM process"),
    "finish_truncated": (exchange_mode(send_then_wait(lambda s: [("finish", b"\0" * 8)])),
                         "a Finish of 8 bytes"),
    "abort_note_oversized": (exchange_mode(send_then_wait(lambda s: [("abort", b"x" * 1000)])),
                             "an AbortNote of 1000 bytes"),
    "state_save_bad_path": (exchange_mode(send_then_wait(lambda s: [
        ("step", bytes(header(s, KIND_SAVE))),
        ("state", bytes(StateRequest(path=b"/nonexistent/dir/state.mpm.h5")))])),
        "save the MPM state into a missing directory"),
    "state_load_missing": (exchange_mode(send_then_wait(lambda s: [
        ("step", bytes(header(s, KIND_LOAD))),
        ("state", bytes(StateRequest(path=b"/nonexistent/state.mpm.h5")))])),
        "load an MPM state that does not exist"),
    "state_load_not_hdf5": (exchange_mode(send_then_wait(lambda s: [
        ("step", bytes(header(s, KIND_LOAD))),
        ("state", bytes(StateRequest(path=str(REPO / "README.md").encode())))])),
        "load an MPM state that is not HDF5"),
    "rezone_zone_map_short": (exchange_mode(rezone_given(bytes(10))), "a zone map of 10 cells"),
    "rezone_zone_value_bad": (exchange_mode(rezone_given(bytes([7]) * num_cells())), "zone value 7 in a zone map"),
    "rezone_volume_off_grid": (exchange_mode(rezone_given(bytes(num_cells()), bytes(CellGrains(10 ** 9, 1e-6, 1e-6)))),
                               "grain volume of a cell off the grid"),
    "rezone_volume_nan": (exchange_mode(rezone_given(bytes(num_cells()), bytes(CellGrains(40, NAN, 1e-6)))),
                          "NaN grain volume in a rezone"),
    "die_mid_exchange": (exchange_mode(die(lambda s: [("step", bytes(header(s)))])),
                         "the peer dies between the step header and its node records"),
    "hang_mid_exchange": (exchange_mode(hang(lambda s: [("step", bytes(header(s)))])),
                          "the peer hangs between the step header and its node records (idle timeout)"),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="A hostile stand-in for LAMMPS in a coupled MPMD job (mpi4py).")
    ap.add_argument("mode", nargs="?", help="what goes wrong (--list)")
    ap.add_argument("--list", action="store_true", help="print the modes and exit")
    ap.add_argument("--idle", type=float, default=5.0,
                    help="idle timeout announced in the Hello: s the MPM process waits for this peer (default 5)")
    ap.add_argument("--reply-timeout", type=float, default=15.0,
                    help="s this peer waits for each answer of the MPM process (default 15)")
    args = ap.parse_args(argv)
    if args.list:
        for name, (_, text) in MODES.items():
            print(f"{name:28s} {text}")
        return 0
    if args.mode not in MODES:
        ap.error(f"unknown mode {args.mode!r}; --list prints the modes")
    peer = Peer(args)
    if peer.remote < 0:
        peer.say("no MPM process in this MPI job")
        return 2
    peer.say(f"mode {args.mode}: {MODES[args.mode][1]}")
    return MODES[args.mode][0](peer)


if __name__ == "__main__":
    sys.exit(main())
