#pragma once
// Wire protocol between the DEM host (LAMMPS with fix hybrid/mpm) and the MPM process
// (mpm_solver --coupled). No LAMMPS types here: any DEM host can use it.
//
// Launch: one MPMD job, `mpirun -np P <dem> : -np 1 mpm_solver --coupled`. Every program
// splits MPI_COMM_WORLD by a fixed colour (kDemColor / kMpmColor; lmp_hybrid does it in its
// main, a stock LAMMPS does it with `-mpicolor 0`, mpm_solver with kMpmColor) and then calls
// connect_dem / connect_mpm with its local communicator.
//
// Connection, bounded at every step (no blocking MPI call waits on the other program
// before it has answered):
//   1. each side finds the other program's leader: the lowest MPI_COMM_WORLD rank outside
//      its own local communicator (local group arithmetic, no collective);
//   2. the DEM leader sends a Hello over MPI_COMM_WORLD; the MPM leader, which polls for it,
//      checks it and answers a HelloReply (ok, or an error text naming both versions);
//   3. only after an accepted Hello do both sides call MPI_Intercomm_create; all further
//      messages travel over that intercommunicator (class Link).
// Every receive polls (MPI_Iprobe + short sleep) and throws PeerError after a timeout.
//
// End of the job: every program enters MPI_Barrier(MPI_COMM_WORLD) exactly once, just before
// MPI_Finalize. LAMMPS's own main does this when started with -mpicolor (normal end and after
// a caught error alike); lmp_hybrid does the same (dem_end_of_job, or the finalize hook after a
// Debian LAMMPS error). mpm_solver enters that barrier in a helper thread from the start, so it
// notices at once when LAMMPS ends - in particular when it ends on an error without having
// told the MPM process (see mpm_solver/src/coupled.cpp).
//
// Messages are fixed-layout structs sent as bytes: both programs run on the same
// architecture and are built from the same release; kProtocolVersion guards the layouts.
#include <mpi.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "coupler/conversion.hpp"
#include "coupler/enrichment.hpp"
#include "coupler/oracle.hpp"
#include "coupler/version.hpp"

namespace coupler {

/// Colours with which the programs split MPI_COMM_WORLD (LAMMPS: `-mpicolor 0`).
inline constexpr int kDemColor = 0;
inline constexpr int kMpmColor = 1;

/// Message tags. Hello/HelloReply/Abort-before-connect travel over MPI_COMM_WORLD, the
/// rest over the intercommunicator. Values are far from anything LAMMPS uses.
enum Tag : int {
  kTagHello = 7301,       ///< DEM -> MPM, Hello (MPI_COMM_WORLD)
  kTagHelloReply = 7302,  ///< MPM -> DEM, HelloReply (MPI_COMM_WORLD)
  kTagIntercomm = 7303,   ///< tag of MPI_Intercomm_create
  kTagStep = 7310,        ///< DEM leader -> MPM, StepHeader
  kTagStepAck = 7311,     ///< MPM -> every DEM rank, StepAck (last message of an exchange)
  kTagZones = 7312,       ///< the zone map, one Zone byte per grid cell: DEM leader -> MPM (a given
                          ///< map), MPM -> every DEM rank (the new map of a rezone)
  kTagVolumes = 7313,     ///< every DEM rank -> MPM, CellGrains[]: its grains' volume and mass per cell
  kTagNodes = 7314,       ///< every DEM rank -> MPM, NodeRecord[] of its coupled grains
  kTagNodeReply = 7315,   ///< MPM -> every DEM rank, NodeUpdate[] in the order of its NodeRecords
  kTagGrains = 7316,      ///< every DEM rank -> MPM at output frames, GrainRecord[]
  kTagState = 7317,       ///< DEM leader -> MPM, StateRequest (save or load the MPM state)
  kTagRezoneCells = 7318, ///< MPM -> every DEM rank, RezoneCell<D>[]: the cells whose material moves
  kTagGrainSums = 7319,   ///< every DEM rank -> MPM, GrainSums<D>[] of its grains in those cells
  kTagCorrections = 7322, ///< MPM -> every DEM rank, GrainCorrection<D>[] for the cells holding grains
  kTagOracle = 7323,      ///< DEM leader -> MPM, OracleSettings of a rezone by the oracle
  kTagSupport = 7324,     ///< DEM leader -> MPM, 3 doubles: the grains' support force after a rezone
  kTagDiscreteCells = 7325, ///< DEM leader -> MPM, uint64 cell indices in the fix's discrete regions
  kTagFinish = 7320,      ///< DEM -> MPM, Finish: the coupled run is over, MPM exits 0
  kTagAbort = 7330,       ///< DEM -> MPM, AbortNote: DEM stopped on an error, MPM exits 1
};

/// Human-readable name of a tag, for messages.
const char* tag_name(int tag);

inline constexpr int kTextSize = 256;
inline constexpr int kVersionSize = 32;

/// Wall condition of the continuum at the faces of the DEM box.
enum WallContact : std::int32_t { kWallSticky = 0, kWallSlip = 1, kWallFriction = 2 };

/// ContinuumSettings::pic of `pic regime`: each node's share of the field rule from the flow
/// regime there (coupler/flow_regime.hpp), answered by the MPM process at every exchange.
inline constexpr double kPicRegime = -1.0;

/// The continuum the MPM process builds, from the fix line (part of Hello).
struct ContinuumSettings {
  double youngs_modulus = 1.0e7;      ///< Pa
  double poisson_ratio = 0.3;
  double friction_angle_deg = 30.0;   ///< Drucker-Prager
  double mu_s = 0.382, mu_2 = 0.644, I0 = 0.279;  ///< mu(I)
  double grain_diameter = 1e-3;       ///< m, mu(I)
  double grain_density = 2500.0;      ///< kg/m^3 (kg/m^2 in 2D), mu(I)
  double critical_packing = 0.6;      ///< mu(I): stress-free below this packing fraction
  double gravity[3] = {0, 0, 0};      ///< m/s^2 (from LAMMPS fix gravity)
  std::int32_t wall_contact = kWallSlip;
  std::int32_t pad0 = 0;              ///< explicit padding: every byte sent is defined
  double wall_friction = 0.0;
  /// Walls of the continuum (planes with wall_contact); the box faces unless the fix's
  /// `container` keyword puts them inside the box (e.g. on a DEM floor above the box bottom).
  double container_lo[3] = {0, 0, 0}, container_hi[3] = {0, 0, 0};
  /// Container faces the continuum may touch (face_bit in oracle.hpp; the fix's `touch`): the zone
  /// oracle does not count them as surfaces. The others are discrete boundaries (the default).
  std::uint32_t touched_faces = 0;
  std::int32_t pad1 = 0;
  double cfl = 0.5;                   ///< MPM substep = cfl * dx / (c + |v|max)
  double grain_weight = 0.5;          ///< share of a hybrid cell's mass its grains keep
  /// grain update: 1 = take the agreed field, 0 = impulse only, kPicRegime = per node from the
  /// flow regime (the DEM side's choice; the MPM process only checks it)
  double pic = 1.0;
  /// s: the agreement closes the sides' velocity gap by 1 - exp(-T / agreement_time) over an
  /// exchange interval T (0 = all of it at every exchange)
  double agreement_time = 0.0;
  /// Gain of the support force between exchanges (0 = none): each exchange adds
  /// support_gain * lambda / interval to the force the sides exert on each other at a node.
  double support_gain = 1.0;
  /// The fill pressure's modulus (0 = none): fill_share times the continuum's bulk modulus plus
  /// fill_modulus (Pa; the fix's `fill auto`: the calibrated packing's, coupler::compaction_modulus).
  /// A node whose points and coupled grains hold more than the packing's mass pushes its points
  /// apart (docs/design.md section 5.4).
  double fill_share = 0.0;
  double fill_modulus = 0.0;
  /// The grains' packing fraction at rest (the calibration's; 0 = not known): the fill a node
  /// of points and grains may hold, as packing_fraction * grain_density * cell volume.
  double packing_fraction = 0.0;
  std::int32_t points_per_axis = 2;   ///< material points per cell and axis
  std::int32_t output_every = 0;      ///< exchanges between output frames, 0 = none
  char output_path[kTextSize] = {};   ///< HDF5 file the MPM process writes frames to
  /// The bulk density the MPM process gives its material (its points carry their own, grain
  /// mass over their volume): the loosest packing that still carries stress.
  double nominal_density() const { return critical_packing * grain_density; }
};

/// DEM -> MPM: the first message. Units are SI ("si" in LAMMPS).
struct Hello {
  std::int32_t protocol = kProtocolVersion;
  char release[kVersionSize] = {};   ///< coupler::release_version() of the DEM side
  char host[kVersionSize] = {};      ///< e.g. "LAMMPS 29 Sep 2021"
  char units[8] = {};                ///< must be "si"
  std::int32_t dimension = 3;
  std::int32_t dem_ranks = 1;
  std::int32_t model = 0;            ///< ModelId
  std::int32_t mpm_every = 1;        ///< DEM steps per exchange
  std::int32_t pad = 0;              ///< explicit padding: every byte sent is defined
  double cell = 0;                   ///< grid cell size, m
  double dt = 0;                     ///< DEM time step, s
  double reply_timeout = 30;         ///< s the DEM side waits for each MPM reply
  double idle_timeout = 600;         ///< s the MPM side waits for the next DEM message (0 = forever)
  double box_lo[3] = {0, 0, 0};      ///< DEM simulation box, m
  double box_hi[3] = {0, 0, 0};
  std::int64_t step = 0;             ///< DEM step at connection
  double time = 0;                   ///< DEM time at connection, s
  ContinuumSettings continuum;
};

/// MPM -> DEM: answer to Hello.
struct HelloReply {
  std::int32_t protocol = kProtocolVersion;
  char release[kVersionSize] = {};
  std::int32_t ok = 0;
  std::int32_t mpm_ranks = 1;
  char message[kTextSize] = {};      ///< error text when !ok, a greeting when ok
};

/// What a StepHeader announces.
enum StepKind : std::int32_t {
  kStepCouple = 0,   ///< NodeRecords follow from every DEM rank; NodeUpdates go back
  kStepRezone = 1,   ///< new zones and the material moved between grains and points (below)
  kStepSave = 2,     ///< a StateRequest follows: write the MPM state (next to a LAMMPS restart file)
  kStepLoad = 3,     ///< a StateRequest follows: continue from a saved MPM state
};

/// Where the zones of a rezone come from (StepHeader::zone_source).
enum ZoneSource : std::int32_t {
  kZonesOracle = 0,   ///< the oracle, from the previous zones (one step at most per cell)
  kZonesInitial = 1,  ///< the oracle at the start of a run: iterated to its fixed point
  kZonesGiven = 2,    ///< the DEM leader sends the map (continuum regions of the fix line)
};

// A rezone (kStepRezone), all messages in this order:
//   DEM leader -> MPM   StepHeader; the zone map if zone_source == kZonesGiven, else the
//                       OracleSettings (the fix line's, changeable between runs) and the
//                       cells in the fix's discrete regions (boundaries for the oracle)
//   every DEM rank      CellGrains[] (its grains' volume, mass and kinetic energy per cell)
//   MPM -> every rank   the new zone map; RezoneCell<D>[] (cells whose material moves);
//                       when no cell's material moves, the StepAck, and the rezone ends
//                       here (the MPM process may then advance to the header's next_time)
//   every DEM rank      where RezoneCell::make_grains, all DEM ranks together make new grains
//                       (at their weight times their solid mass, with the points' affine
//                       velocity); then GrainSums<D>[] of its grains, old and new, in those cells
//   MPM -> every rank   GrainCorrection<D>[] for the cells holding grains
//   DEM leader -> MPM   the grains' total support force after the changes (3 doubles); the
//                       points' reaction is balanced with it (momentum stays exact)
//   MPM -> every rank   the StepAck.
// Every grain of a moving cell ends with its zone's weight (1 discrete, the grain weight hybrid)
// times its solid mass: grains never drift from their density. The points take the rest of the
// cell's material; where the cell keeps no points (or too few for the rest), the difference goes
// to the points of the nearest cells that stay continuum or hybrid. Totals exact to round-off.

/// DEM rank -> MPM: its grains whose centre lies in a cell, summed: their volume (the packing
/// fraction), carried mass (whether they can take their share of the cell's material) and
/// translational kinetic energy (whether the cell's material is at rest: the oracle holds the
/// zones of material at rest, coupler::hold_zones_at_rest).
struct CellGrains {
  std::uint64_t cell = 0;
  double volume = 0;
  double mass = 0;
  double kinetic = 0;
};

/// MPM -> DEM ranks: one cell whose material moves between grains and points.
template <int D>
struct RezoneCell {
  std::uint64_t cell = 0;
  std::int32_t zone = 0;               ///< its new Zone
  std::int32_t make_grains = 0;        ///< 1: its zone wants grains and it has too few for its material
  CellMoments<D> points;               ///< the sums of its points (make_grains: new grains fill these + old grains)
  double gradient[D * D] = {};         ///< the points' mass-averaged velocity gradient (column-major)
  Occupancy occupancy = 0;             ///< sub-cells holding points (enrichment.hpp)
  double grain_weight = 1;             ///< the weight label of grains in this cell
};

/// DEM rank -> MPM: its grains of one moving cell, summed twice: as they are (what they carry:
/// the cell's material) and at their solid mass (size times the grains' density; the bodies the
/// rigid correction scales, so that each grain ends at its new weight times its solid mass).
template <int D>
struct GrainSums {
  BodySums<D> carried;
  BodySums<D> solid;
};

/// MPM -> DEM ranks: what the grains of one cell become (a rigid correction of their solid
/// sums, or removal): each grain's new mass is mass_factor times its solid mass.
template <int D>
struct GrainCorrection {
  std::uint64_t cell = 0;
  std::int32_t remove = 0;             ///< 1: the grains become points (deleted)
  std::int32_t mechanism = 0;          ///< the cell's RezoneMechanism (zones.hpp), for the energy ledger
  double weight = 1;                   ///< their new weight label
  double mass_factor = 1;
  double velocity[D] = {};
  double omega[D == 2 ? 1 : 3] = {};
  double centre[D] = {};
};

/// DEM leader -> MPM: where to save or load the MPM state.
struct StateRequest {
  char path[4096] = {};
  std::int64_t exchanges = 0;        ///< exchanges so far (kept in the state file)
};

/// DEM leader -> MPM, at every exchange (every mpm_every steps) and at the conversion.
struct StepHeader {
  std::int64_t step = 0;
  double time = 0;                   ///< DEM time of this exchange, s
  double dt = 0;                     ///< DEM time step, s
  std::int32_t kind = kStepCouple;
  std::int32_t output = 0;           ///< 1: GrainRecords follow from every DEM rank (an output frame)
  std::int64_t n_grains = 0;         ///< coupled grains over all DEM ranks (for the log)
  /// DEM time of the next exchange if it is certain (same run, no restart file or rezone
  /// before it), else -1: the MPM process may advance to it while LAMMPS computes its steps.
  /// A rezone's: the next exchange's if the rezone moves no material.
  double next_time = -1;
  std::int32_t zone_source = kZonesOracle;  ///< kStepRezone: ZoneSource
  /// kStepCouple: 1 = answer each node's field share from the local flow regime
  /// (NodeUpdate::field_share; the fix's `pic regime`), 0 = the DEM side uses its own pic
  std::int32_t field_shares = 0;
};

/// MPM -> every DEM rank: the end of an exchange, with the continuum's totals.
struct StepAck {
  std::int64_t step = 0;
  std::int32_t status = 0;           ///< 0 = ok; otherwise message holds the error
  std::int32_t substeps = 0;         ///< MPM steps taken since the last exchange
  char message[kTextSize] = {};
  std::int64_t points = 0;           ///< material points
  std::int64_t shared_nodes = 0;     ///< nodes holding mass of both sides
  double mass = 0;                   ///< continuum mass, kg
  double momentum[3] = {0, 0, 0};    ///< continuum linear momentum after the exchange
  double angular[3] = {0, 0, 0};     ///< continuum (APIC) angular momentum about the origin
  double kinetic_energy = 0;         ///< J
  double mismatch = 0;               ///< largest |v_dem - v_mpm| at shared nodes before the agreement, m/s
  double mpm_dt = 0;                 ///< last MPM substep, s
  std::int64_t zone_cells[3] = {0, 0, 0};  ///< cells of the box per Zone (after the last rezone)
  std::int64_t moved_cells = 0;      ///< rezone: cells whose material moved between grains and points
  std::int64_t points_made = 0;      ///< rezone: material points made
  std::int64_t points_removed = 0;   ///< rezone: material points removed
  std::int64_t rests_moved = 0;      ///< rezone: cells whose rest went to the points of nearby cells
  std::int64_t rests_kept = 0;       ///< rezone: cells that kept their rest (no points near enough)
  double before[7] = {};             ///< rezone: the continuum's mass, momentum, angular momentum before it
  /// The continuum's side of the energy ledger (docs/fix_hybrid_mpm.md, "Energy ledger"), J (J/m in 2D):
  /// its kinetic (with the APIC affine part), potential and stored elastic energy at this message (the agreed grid at an exchange, the points
  /// after a rezone) and, summed since the start, what changed it.
  double energy = 0;
  double energy_physics = 0;         ///< the continuum's own steps: stress, walls, transfers, support reaction, fill
  double energy_agreement = 0;       ///< the velocity agreements on the continuum's nodes
  double energy_rezone = 0;          ///< points made, removed and corrected by rezones
  /// The shared nodes' mass above the packing's (docs/design.md section 5.4) over their mass, at the
  /// last exchange: how far points and grains overlap where they meet (0 when neither side holds
  /// more than a packed node's mass together).
  double overlap = 0;
  /// Of energy_physics, the fill pressure's work on the points (Solver::fill_work; its last
  /// substep's share comes with the next message).
  double energy_fill = 0;
};

/// DEM rank -> MPM: a coupled grain's weighted mass and momentum on one node.
struct NodeRecord {
  std::uint64_t node = 0;
  double mass = 0;
  double momentum[3] = {0, 0, 0};
};

/// MPM -> DEM rank, one per NodeRecord: the agreed node velocity and lambda_i / m_dem_i.
struct NodeUpdate {
  double velocity[3] = {0, 0, 0};
  double impulse_per_mass[3] = {0, 0, 0};
  double support[3] = {0, 0, 0};     ///< support force F_i / m_dem_i until the next exchange, m/s^2
  /// Share of the field rule in the node's grain update, when StepHeader::field_shares asked
  /// for it (else 0): the continuum's flow regime there (coupler/flow_regime.hpp) times the
  /// share of the gap the agreement closes over the interval, 1 - exp(-T / agreement_time)
  double field_share = 0;
};

/// DEM rank -> MPM at output frames: one grain.
struct GrainRecord {
  std::int64_t id = 0;
  double x[3] = {0, 0, 0};
  double v[3] = {0, 0, 0};
  double radius = 0;
  double mass = 0;                   ///< the mass the grain carries (its weight times its full mass)
  double weight = 1;                 ///< share of its material the grain carries
  std::int32_t zone = 0;             ///< Zone of its cell
  std::int32_t pad = 0;
};

/// DEM -> MPM: normal end of the coupled run.
struct Finish {
  std::int64_t step = 0;
  std::int64_t exchanges = 0;
};

/// DEM -> MPM: the DEM side is stopping on an error (sent from its MPI_Finalize hook).
struct AbortNote {
  char reason[kTextSize] = {};
};

/// Constitutive model the MPM side uses for the coupled material.
enum ModelId : std::int32_t { kModelDruckerPrager = 0, kModelMuI = 1 };
const char* model_name(int model);

/// The peer does not answer, vanished, or refused the connection. what() is a complete,
/// user-facing sentence.
class PeerError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The peer did not answer in time (or the connection broke): it may be hung, so the caller
/// must not wait for it in MPI_Finalize (call MPI_Abort instead).
class PeerTimeout : public PeerError {
 public:
  using PeerError::PeerError;
};

/// The DEM side ended (error or end of input) before it connected; what() holds its reason.
class PeerEnded : public PeerError {
 public:
  using PeerError::PeerError;
};

/// Copies `s` into a fixed char field, always NUL-terminated (truncates).
template <std::size_t N>
void set_text(char (&dst)[N], const std::string& s) {
  const std::size_t n = s.size() < N - 1 ? s.size() : N - 1;
  for (std::size_t i = 0; i < n; ++i) dst[i] = s[i];
  for (std::size_t i = n; i < N; ++i) dst[i] = '\0';
}
template <std::size_t N>
std::string get_text(const char (&src)[N]) {
  std::size_t n = 0;
  while (n < N && src[n] != '\0') ++n;
  return std::string(src, n);
}

/// Owns one intercommunicator; frees it on destruction (unless MPI is already finalized).
/// Errors on it are returned, not fatal (MPI_ERRORS_RETURN), so that callers can report them.
class Intercomm {
 public:
  Intercomm() = default;
  explicit Intercomm(MPI_Comm comm);
  ~Intercomm();
  Intercomm(const Intercomm&) = delete;
  Intercomm& operator=(const Intercomm&) = delete;
  Intercomm(Intercomm&& o) noexcept : comm_(o.comm_) { o.comm_ = MPI_COMM_NULL; }
  Intercomm& operator=(Intercomm&& o) noexcept;
  MPI_Comm get() const { return comm_; }
  explicit operator bool() const { return comm_ != MPI_COMM_NULL; }
  int remote_size() const;

 private:
  MPI_Comm comm_ = MPI_COMM_NULL;
};

/// Lowest MPI_COMM_WORLD rank that is not in `local`, or -1 if every rank is in `local`.
/// Local computation on groups: no communication, cannot hang.
int first_world_rank_outside(MPI_Comm local);

/// A received message: tag and raw bytes (sizes are checked by the reader).
struct Message {
  int tag = 0;
  std::vector<char> data;
  template <class T>
  bool fits() const {
    return data.size() == sizeof(T);
  }
  /// The payload as T; throws PeerError if the size differs.
  template <class T>
  T as() const {
    static_assert(std::is_trivially_copyable_v<T>);
    if (!fits<T>())
      throw PeerError("protocol error: a message (tag " + std::to_string(tag) + ") has " +
                      std::to_string(data.size()) + " bytes, expected " + std::to_string(sizeof(T)) +
                      " (are both programs from the same release?)");
    T t;
    std::memcpy(static_cast<void*>(&t), data.data(), sizeof(T));
    return t;
  }
  /// The payload as an array of T; throws PeerError if the size is not a multiple of sizeof(T).
  template <class T>
  std::vector<T> as_array() const {
    static_assert(std::is_trivially_copyable_v<T>);
    if (data.size() % sizeof(T) != 0)
      throw PeerError("protocol error: a message (tag " + std::to_string(tag) + ") has " +
                      std::to_string(data.size()) + " bytes, not a multiple of " + std::to_string(sizeof(T)) +
                      " (are both programs from the same release?)");
    std::vector<T> items(data.size() / sizeof(T));
    if (!items.empty()) std::memcpy(static_cast<void*>(items.data()), data.data(), data.size());
    return items;
  }
  /// The protocol version a Hello or HelloReply of another release announces (its layout may
  /// differ everywhere else), read from that field alone: `protocol` stays the first field of
  /// both in every protocol version (wire_layout.hpp). -1 if the message is too short.
  int announced_protocol() const {
    static_assert(offsetof(Hello, protocol) == 0 && offsetof(HelloReply, protocol) == 0,
                  "the protocol version must stay the first field of Hello and HelloReply");
    static_assert(std::is_same_v<decltype(Hello::protocol), decltype(HelloReply::protocol)>);
    decltype(Hello::protocol) v = -1;
    if (data.size() < offsetof(Hello, protocol) + sizeof v) return -1;
    std::memcpy(&v, data.data() + offsetof(Hello, protocol), sizeof v);
    return v;
  }
};

/// Waits (MPI_Iprobe polling with short sleeps) at most `timeout_s` (<= 0: forever) for a
/// message from `source` on `comm`, receives it and returns it. Throws PeerTimeout on timeout
/// ("no reply from <peer> within 30 s while waiting for <what>; ...") or an MPI error, and
/// PeerError if the message's tag is not one of `tags`.
/// If `peer_ended` is given and becomes true while nothing has arrived, it keeps polling for
/// a short grace period and then throws PeerEnded ("<peer> ended while ... waiting for <what>").
Message recv_message(MPI_Comm comm, int source, std::initializer_list<int> tags, double timeout_s,
                     const std::string& peer, const std::string& what,
                     const std::atomic<bool>* peer_ended = nullptr);

/// Sends `bytes` to `dest` on `comm` and waits (polling) at most `timeout_s` for the send to
/// complete; throws PeerError naming `what` on timeout or MPI error.
void send_bytes(MPI_Comm comm, int dest, int tag, const void* data, int bytes, double timeout_s,
                const std::string& what);

/// recv_message into `data` (exactly `bytes` expected); returns the tag.
int recv_bytes(MPI_Comm comm, int source, std::initializer_list<int> tags, void* data, int bytes,
               double timeout_s, const std::string& peer, const std::string& what);

template <class T>
void send_msg(MPI_Comm comm, int dest, int tag, const T& msg, double timeout_s, const std::string& what) {
  static_assert(std::is_trivially_copyable_v<T>);
  send_bytes(comm, dest, tag, &msg, static_cast<int>(sizeof(T)), timeout_s, what);
}

/// One side's view of an established connection. Only the leader (local rank 0) of each
/// side talks; non-leaders hold an empty Link apart from the intercommunicator.
class Link {
 public:
  enum class State { kConnected, kFinished, kAborted, kUnresponsive };

  Link(Intercomm comm, bool leader, double reply_timeout, std::string peer_name);

  bool leader() const { return leader_; }
  MPI_Comm comm() const { return comm_.get(); }
  int remote_size() const { return comm_.remote_size(); }
  State state() const { return state_; }
  double reply_timeout() const { return reply_timeout_; }
  const std::string& peer_name() const { return peer_name_; }
  long exchanges() const { return exchanges_; }
  /// What the peer said when the connection was accepted (its greeting).
  const std::string& peer_info() const { return peer_info_; }
  void set_peer_info(std::string s) { peer_info_ = std::move(s); }

  /// Any rank: sends `bytes` to rank `dest` of the other side within the reply timeout.
  /// Marks the peer unresponsive and rethrows on failure.
  void send(int dest, int tag, const void* data, std::size_t bytes, const std::string& what);
  template <class T>
  void send_array(int dest, int tag, const std::vector<T>& items, const std::string& what) {
    static_assert(std::is_trivially_copyable_v<T>);
    send(dest, tag, items.data(), items.size() * sizeof(T), what);
  }
  template <class T>
  void send_struct(int dest, int tag, const T& item, const std::string& what) {
    static_assert(std::is_trivially_copyable_v<T>);
    send(dest, tag, &item, sizeof(T), what);
  }
  /// Any rank: the next message from rank `source` of the other side with one of `tags`,
  /// waiting at most `timeout_s` (< 0: the reply timeout). Marks the peer unresponsive and
  /// rethrows on failure.
  Message receive(int source, std::initializer_list<int> tags, const std::string& what, double timeout_s = -1,
                  const std::atomic<bool>* peer_ended = nullptr);
  /// DEM leader: normal end. Idempotent.
  void finish(std::int64_t step);
  /// DEM leader: best effort notice that the DEM side stops on an error (waits <= 2 s).
  void abort_note(const std::string& reason) noexcept;
  /// Marks the peer unresponsive (after a PeerError), so that the finalize hook aborts the job.
  void mark_unresponsive() { state_ = State::kUnresponsive; }
  void mark(State s) { state_ = s; }
  void count_exchange() { ++exchanges_; }

 private:
  Intercomm comm_;
  bool leader_;
  double reply_timeout_;
  std::string peer_name_;
  State state_ = State::kConnected;
  long exchanges_ = 0;
  std::string peer_info_;
};

/// DEM side, collective over `local` (all DEM ranks): finds the MPM leader, handshakes and
/// creates the intercommunicator. Throws PeerError on every rank of `local` alike (the
/// leader's outcome is broadcast), with a message naming the cause.
std::unique_ptr<Link> connect_dem(MPI_Comm local, Hello hello);

/// MPM side, collective over `local` (all MPM ranks): waits at most `hello_timeout_s` for
/// the Hello, validates it with `check` (returns "" if acceptable, else the error text),
/// replies, and creates the intercommunicator. Returns the accepted Hello through `hello`.
/// Throws PeerError when nothing arrives in time, when the DEM side sent an AbortNote
/// instead (it stopped before connecting), or when `check` rejected the Hello.
/// `peer_ended` as in recv_message.
std::unique_ptr<Link> connect_mpm(MPI_Comm local, double hello_timeout_s, Hello& hello,
                                  const std::string& greeting,
                                  std::string (*check)(const Hello&),
                                  const std::atomic<bool>* peer_ended = nullptr);

// ----------------------------------------------------------------------------------------
// The one process-wide handle (the only global state of the coupling): the DEM program's
// current Link and local communicator, registered so that the MPI_Finalize hook can tell the
// MPM process why the DEM side stops. Set by the DEM host (fix hybrid/mpm, lmp_hybrid).

/// Registers the DEM side's local communicator (LAMMPS's world) and installs, once per
/// process, a hook that runs at the very start of MPI_Finalize (an attribute delete
/// callback on MPI_COMM_SELF, as the MPI standard provides). At finalize the hook
///   - peer unresponsive: calls MPI_Abort(MPI_COMM_WORLD, 1), because MPI_Finalize would
///     wait for the hung peer forever;
///   - otherwise sends what dem_end_of_job sends (an AbortNote unless the coupled run
///     finished) and, if the host program leaves the end-of-job barrier to the hook
///     (set_world_barrier_by_hook) and it has not happened yet, enters it.
/// Idempotent; later calls only refresh the communicator data.
/// `host` names the DEM host in what the MPM process is told ("LAMMPS", "LIGGGHTS").
void install_dem_finalize_hook(MPI_Comm local, const std::string& host);

/// What the MPM process calls its DEM host: the program the handshake's host text names
/// ("LAMMPS 29 Sep 2021" -> "LAMMPS", "LIGGGHTS 3.8.0" -> "LIGGGHTS"), else kUnknownDemHost (a
/// peer that names no known host, or before the handshake).
inline constexpr const char* kUnknownDemHost = "the DEM host";
std::string dem_host_name(const std::string& host_text);
/// lmp_hybrid: its LAMMPS library (Debian's, without exceptions) calls MPI_Finalize directly
/// on errors, so the hook must enter the end-of-job MPI_COMM_WORLD barrier. A stock LAMMPS
/// main enters it itself (default: false).
void set_world_barrier_by_hook(bool by_hook);
/// DEM host's orderly end (lmp_hybrid after its input is done): on the leader, an AbortNote
/// to the MPM process if the coupled run did not finish (reason below when it never
/// connected), then MPI_Barrier(MPI_COMM_WORLD) on all DEM ranks. Call once, before
/// MPI_Finalize; collective over the DEM ranks.
void dem_end_of_job();
/// The DEM side's current link (nullptr if none) - set by the DEM host.
Link* peer();
void set_peer(Link* link);
/// Text that the finalize hook sends when the DEM side ends before connecting; a DEM host
/// that knows better (lmp_hybrid after a normal end) may set it.
void set_unconnected_exit_reason(const std::string& reason);

}  // namespace coupler

#include "coupler/wire_layout.hpp"  // pins the layout of every struct above
