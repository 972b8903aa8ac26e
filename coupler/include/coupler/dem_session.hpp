#pragma once
// The DEM side's conversation with the MPM process, message by message (the sequences of
// coupler/protocol.hpp), and its failure handling: every step is collective over the DEM
// ranks, and any rank's failure becomes every rank's, with the message of the lowest failing
// rank. Host-neutral: a host's fix supplies the figures (node sums, grain sums, its grains for
// an output frame) and turns a failed outcome into its own error (LAMMPS: error->all).

#include <mpi.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "coupler/protocol.hpp"

namespace coupler {

/// How a collective step ended on one rank.
struct StepOutcome {
  enum Status : int {
    kOk = 0,
    kNoPeer = 1,       ///< the MPM process did not answer, or a message could not be passed (PeerError)
    kPeerFailed = 2,   ///< the MPM process answered with an error
  };
  int status = kOk;
  std::string what;    ///< what failed (without the host's prefix)
  bool ok() const { return status == kOk; }
  void fail(int s, std::string w) { status = s, what = std::move(w); }
};

/// Collective over comm: every rank's outcome, the lowest failing rank's (status and message)
/// where any rank failed.
StepOutcome agree_on_outcome(MPI_Comm comm, const StepOutcome &mine);

/// The DEM side of one coupled run (all DEM ranks; rank 0 is the leader that sends headers).
class DemSession {
 public:
  DemSession(Link &link, MPI_Comm comm, int rank) : link_(link), comm_(comm), rank_(rank) {}

  /// Every rank's outcome (agree_on_outcome); on a failure the link is marked for the
  /// MPI_Finalize hook (a peer that did not answer is presumed hung: the job is then aborted).
  StepOutcome settle(const StepOutcome &mine);

  /// A coupling exchange: the header (leader), this rank's node sums, the agreed node
  /// velocities (given to `apply`), the acknowledgement; then this rank's grains for an output
  /// frame. Local outcome; `ack` holds the acknowledgement.
  StepOutcome exchange(const StepHeader &header, const std::vector<NodeRecord> &records,
                       const std::function<void(const std::vector<NodeUpdate> &)> &apply,
                       const std::function<std::vector<GrainRecord>()> &frame_grains, StepAck &ack);

  /// A rezone's first round trip: the header and the zone map (given zones) or the oracle's
  /// settings and the discrete regions' cells (leader), this rank's grain volumes; the new zone
  /// map (of the grid's `ncells`) and the cells to rezone come back, and when there are none the
  /// acknowledgement that ends the rezone (in `ack`).
  template <int D>
  StepOutcome rezone_zones(const StepHeader &header, const std::vector<signed char> &given_zones,
                           const OracleSettings &oracle, const std::function<std::vector<std::uint64_t>()> &discrete,
                           const std::vector<CellGrains> &volumes, std::size_t ncells, std::vector<signed char> &zones,
                           std::vector<RezoneCell<D>> &cells, StepAck &ack);

  /// The second: the grain sums of the moving cells; what their grains become comes back.
  template <int D>
  StepOutcome rezone_corrections(const std::vector<GrainSums<D>> &sums, std::vector<GrainCorrection<D>> &corrections,
                                 StepAck &ack);

  /// The third: the grains' support force after the rezone (leader); the acknowledgement.
  StepOutcome rezone_finish(const double force[3], StepAck &ack);

  /// Saving (kStepSave) or loading (kStepLoad) the MPM state; a loaded state's zone map (of
  /// the grid's zones.size() cells) replaces `zones`.
  StepOutcome state_request(const StepHeader &header, const std::string &path, std::int64_t exchanges,
                            std::vector<signed char> &zones, StepAck &ack);

 private:
  Link &link_;
  MPI_Comm comm_;
  int rank_;
  std::string at_;    // " of the rezone at step N"
  static StepOutcome peer_failed(const StepAck &ack, const std::string &prefix);
};

// ------------------------------------------------------------------------------------------

template <int D>
StepOutcome DemSession::rezone_zones(const StepHeader &header, const std::vector<signed char> &given_zones,
                                     const OracleSettings &oracle,
                                     const std::function<std::vector<std::uint64_t>()> &discrete,
                                     const std::vector<CellGrains> &volumes, std::size_t ncells,
                                     std::vector<signed char> &zones, std::vector<RezoneCell<D>> &cells,
                                     StepAck &ack) {
  at_ = " of the rezone at step " + std::to_string(header.step);
  StepOutcome out;
  try {
    if (rank_ == 0) {
      link_.send_struct(0, kTagStep, header, "the rezone header" + at_);
      if (header.zone_source == kZonesGiven) link_.send_array(0, kTagZones, given_zones, "the zone map" + at_);
      else {
        link_.send_struct(0, kTagOracle, oracle, "the oracle settings" + at_);
        link_.send_array(0, kTagDiscreteCells, discrete(), "the cells of the discrete regions" + at_);
      }
    }
    link_.send_array(0, kTagVolumes, volumes, "the grain volumes" + at_);
    const Message m = link_.receive(0, {kTagZones, kTagStepAck}, "the new zone map" + at_);
    if (m.tag == kTagStepAck) {
      ack = m.as<StepAck>();
      return peer_failed(ack, "the MPM process could not rezone: ");
    }
    zones = m.as_array<signed char>();
    if (zones.size() != ncells)
      throw PeerError("protocol error: a zone map of " + std::to_string(zones.size()) + " cells for a grid of " +
                      std::to_string(ncells));
    cells = link_.receive(0, {kTagRezoneCells}, "the cells to rezone" + at_).as_array<RezoneCell<D>>();
    if (cells.empty()) {    // no material moves: the rezone ends with its acknowledgement
      ack = link_.receive(0, {kTagStepAck}, "the rezone's acknowledgement" + at_).as<StepAck>();
      if (ack.status != 0) return peer_failed(ack, "the MPM process could not rezone: ");
    }
  } catch (const PeerError &e) {
    out.fail(StepOutcome::kNoPeer, e.what());
  }
  return out;
}

template <int D>
StepOutcome DemSession::rezone_corrections(const std::vector<GrainSums<D>> &sums,
                                           std::vector<GrainCorrection<D>> &corrections, StepAck &ack) {
  StepOutcome out;
  try {
    link_.send_array(0, kTagGrainSums, sums, "the grain sums" + at_);
    const Message m = link_.receive(0, {kTagCorrections, kTagStepAck}, "the grain corrections" + at_);
    if (m.tag == kTagStepAck) {
      ack = m.as<StepAck>();
      return peer_failed(ack, "the MPM process could not rezone: ");
    }
    corrections = m.as_array<GrainCorrection<D>>();
  } catch (const PeerError &e) {
    out.fail(StepOutcome::kNoPeer, e.what());
  }
  return out;
}

}    // namespace coupler
