#include "coupler/dem_session.hpp"

namespace coupler {

StepOutcome agree_on_outcome(MPI_Comm comm, const StepOutcome &mine) {
  int worst = 0, status = mine.status;
  MPI_Allreduce(&status, &worst, 1, MPI_INT, MPI_MAX, comm);
  if (worst == 0) return {};
  int me = 0, nprocs = 1;
  MPI_Comm_rank(comm, &me);
  MPI_Comm_size(comm, &nprocs);
  int rank = status != 0 ? me : nprocs, first = 0;
  MPI_Allreduce(&rank, &first, 1, MPI_INT, MPI_MIN, comm);
  char text[kTextSize * 2] = {};
  if (me == first) set_text(text, mine.what);
  MPI_Bcast(text, sizeof(text), MPI_CHAR, first, comm);
  MPI_Bcast(&status, 1, MPI_INT, first, comm);
  StepOutcome all;
  all.fail(status, text);
  return all;
}

StepOutcome DemSession::settle(const StepOutcome &mine) {
  StepOutcome all = agree_on_outcome(comm_, mine);
  // a peer that did not answer is presumed hung: the finalize hook aborts the job
  if (all.status == StepOutcome::kNoPeer) link_.mark_unresponsive();
  else if (!all.ok()) link_.mark(Link::State::kConnected);
  return all;
}

StepOutcome DemSession::peer_failed(const StepAck &ack, const std::string &prefix) {
  StepOutcome out;
  out.fail(StepOutcome::kPeerFailed, prefix + get_text(ack.message));
  return out;
}

StepOutcome DemSession::exchange(const StepHeader &header, const std::vector<NodeRecord> &records,
                                 const std::function<void(const std::vector<NodeUpdate> &)> &apply,
                                 const std::function<std::vector<GrainRecord>()> &frame_grains, StepAck &ack) {
  const std::string at_step = " of step " + std::to_string(header.step);
  StepOutcome out;
  try {
    if (rank_ == 0) link_.send_struct(0, kTagStep, header, "the step header" + at_step);
    link_.send_array(0, kTagNodes, records, "the grain node sums" + at_step);
    Message m = link_.receive(0, {kTagNodeReply, kTagStepAck}, "the node velocities" + at_step);
    if (m.tag == kTagNodeReply) {
      const auto updates = m.as_array<NodeUpdate>();
      if (updates.size() != records.size())
        throw PeerError("protocol error: " + std::to_string(updates.size()) + " node velocities for " +
                        std::to_string(records.size()) + " nodes");
      apply(updates);
      m = link_.receive(0, {kTagStepAck}, "the acknowledgement" + at_step);
    }
    ack = m.as<StepAck>();
    if (ack.status != 0)
      return peer_failed(ack, "the MPM process reported an error at step " + std::to_string(header.step) + ": ");
    if (header.output) link_.send_array(0, kTagGrains, frame_grains(), "the grains of the output frame" + at_step);
  } catch (const PeerError &e) {
    out.fail(StepOutcome::kNoPeer, e.what());
  }
  return out;
}

StepOutcome DemSession::rezone_finish(const double force[3], StepAck &ack) {
  StepOutcome out;
  try {
    if (rank_ == 0)
      link_.send_array(0, kTagSupport, std::vector<double>(force, force + 3), "the grains' support force" + at_);
    ack = link_.receive(0, {kTagStepAck}, "the rezone's acknowledgement" + at_).as<StepAck>();
    if (ack.status != 0) return peer_failed(ack, "the MPM process could not rezone: ");
  } catch (const PeerError &e) {
    out.fail(StepOutcome::kNoPeer, e.what());
  }
  return out;
}

StepOutcome DemSession::state_request(const StepHeader &header, const std::string &path, std::int64_t exchanges,
                                      std::vector<signed char> &zones, StepAck &ack) {
  const std::string verb = header.kind == kStepSave ? "saving" : "loading";
  StepOutcome out;
  try {
    if (rank_ == 0) {
      StateRequest request;
      if (path.size() >= sizeof(request.path)) throw PeerError("the MPM state path " + path + " is too long");
      set_text(request.path, path);
      request.exchanges = exchanges;
      link_.send_struct(0, kTagStep, header, "the state request header");
      link_.send_struct(0, kTagState, request, "the state request");
    }
    Message m = link_.receive(0, {kTagStepAck, kTagZones}, "the MPM process " + verb + " its state");
    if (m.tag == kTagZones) {    // a loaded state's zones come first
      auto loaded = m.as_array<signed char>();
      if (loaded.size() != zones.size())
        throw PeerError("protocol error: a zone map of " + std::to_string(loaded.size()) + " cells for a grid of " +
                        std::to_string(zones.size()));
      zones = std::move(loaded);
      m = link_.receive(0, {kTagStepAck}, "the MPM process " + verb + " its state");
    }
    ack = m.as<StepAck>();
    if (ack.status != 0) return peer_failed(ack, verb + " the MPM state failed: ");
  } catch (const PeerError &e) {
    out.fail(StepOutcome::kNoPeer, e.what());
  }
  return out;
}

}    // namespace coupler
