#include "coupler/protocol.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <sstream>
#include <thread>
#include <vector>

namespace coupler {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string format_seconds(double s) {
  std::ostringstream o;
  o << s;
  return o.str();
}

std::string mpi_error_text(int rc) {
  char buf[MPI_MAX_ERROR_STRING];
  int len = 0;
  if (MPI_Error_string(rc, buf, &len) != MPI_SUCCESS) return "MPI error " + std::to_string(rc);
  return std::string(buf, static_cast<std::size_t>(len));
}

/// Pause between polls: spin (yielding the core to anyone who wants it) for about a
/// millisecond, since exchange answers come within microseconds to a millisecond, then sleep
/// 20 us doubling up to 200 us. A longer sleep cap made every exchange wait for the sleeper's
/// wake-up (measured: 0.9 ms per exchange with a 1 ms cap, bench/coupling_overhead.py).
class Backoff {
 public:
  void wait() {
    if (spins_ < 2000) {
      ++spins_;
      std::this_thread::yield();
      return;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(us_));
    us_ = std::min(us_ * 2, 200);
  }

 private:
  int spins_ = 0;
  int us_ = 20;
};

std::string versions_text(const std::string& side, const std::string& release, int protocol) {
  return side + " is release " + release + " (protocol " + std::to_string(protocol) + ")";
}

// ---------------------------------------------------------------- DEM-side global handle
enum class DemPhase { kNotConnected, kConnected, kFinished, kRejected, kNoPeer, kUnresponsive };

struct DemGlobal {
  bool hook_installed = false;
  bool registered = false;    ///< install_dem_finalize_hook was called
  bool barrier_by_hook = false;
  bool barrier_done = false;  ///< the end-of-job MPI_COMM_WORLD barrier happened
  bool notes_sent = false;
  bool leader = false;        ///< rank 0 of the DEM local communicator
  int remote_leader = -1;     ///< MPI_COMM_WORLD rank of the MPM leader, -1 if none
  Link* link = nullptr;
  DemPhase phase = DemPhase::kNotConnected;
  std::string host = "LAMMPS";    ///< the DEM host's name (install_dem_finalize_hook)
  std::string unconnected_reason = unconnected_text(host);

  static std::string unconnected_text(const std::string& host) {
    return host + " ended before fix hybrid/mpm connected (an error in the " + host +
           " input before the first run, or no fix hybrid/mpm in the input) - see the " + host + " output";
  }
};

DemGlobal& dem() {
  static DemGlobal g;
  return g;
}

void abort_job_unresponsive() {
  if (dem().leader)
    std::fprintf(stderr,
                 "fix hybrid/mpm: the MPM process does not respond; aborting the MPI job (MPI_Finalize would wait "
                 "for it forever)\n");
  std::fflush(stderr);
  std::fflush(stdout);
  MPI_Abort(MPI_COMM_WORLD, 1);
}

/// Tells the MPM process, once, why the DEM side ends if the coupled run did not finish.
void send_end_notes() {
  DemGlobal& g = dem();
  if (g.notes_sent) return;
  g.notes_sent = true;
  if (g.link != nullptr) {
    if (g.link->state() == Link::State::kConnected && g.link->leader())
      g.link->abort_note(g.host + " stopped on an error during the coupled run - see the " + g.host +
                         " output for the ERROR line");
    if (g.link->state() == Link::State::kConnected) g.link->mark(Link::State::kAborted);
    return;
  }
  if (g.phase == DemPhase::kNotConnected && g.leader && g.remote_leader >= 0) {
    AbortNote note;
    set_text(note.reason, g.unconnected_reason);
    try {
      send_msg(MPI_COMM_WORLD, g.remote_leader, kTagAbort, note, 2.0, "the abort notice");
    } catch (const PeerError&) {
      // best effort: the MPM process also notices the end-of-job barrier
    }
  }
}

bool unresponsive() {
  const DemGlobal& g = dem();
  if (g.link != nullptr) return g.link->state() == Link::State::kUnresponsive;
  return g.phase == DemPhase::kUnresponsive;
}

/// Runs at the start of MPI_Finalize (MPI_COMM_SELF attribute deletion).
int dem_finalize_hook(MPI_Comm, int, void*, void*) {
  DemGlobal& g = dem();
  if (!g.registered) return MPI_SUCCESS;
  if (unresponsive()) abort_job_unresponsive();
  send_end_notes();
  if (g.barrier_by_hook && !g.barrier_done) {
    g.barrier_done = true;
    MPI_Barrier(MPI_COMM_WORLD);
  }
  return MPI_SUCCESS;
}

}  // namespace

Message recv_message(MPI_Comm comm, int source, std::initializer_list<int> tags, double timeout_s,
                     const std::string& peer, const std::string& what, const std::atomic<bool>* peer_ended) {
  const auto t0 = Clock::now();
  Backoff backoff;
  bool ended = false;
  Clock::time_point t_ended;
  for (;;) {
    int flag = 0;
    MPI_Status status;
    int rc = MPI_Iprobe(source, MPI_ANY_TAG, comm, &flag, &status);
    if (rc != MPI_SUCCESS)
      throw PeerTimeout("lost the connection to " + peer + " while waiting for " + what + " (" +
                        mpi_error_text(rc) + "); it may have crashed - check its output");
    if (flag) {
      int count = MPI_UNDEFINED;
      rc = MPI_Get_count(&status, MPI_BYTE, &count);
      if (rc != MPI_SUCCESS || count == MPI_UNDEFINED || count < 0)
        throw PeerTimeout("cannot size " + std::string(tag_name(status.MPI_TAG)) + " from " + peer +
                          " while waiting for " + what + " (MPI_Get_count: " +
                          (rc != MPI_SUCCESS ? mpi_error_text(rc) : "count undefined") + ")");
      Message m;
      m.tag = status.MPI_TAG;
      m.data.resize(static_cast<std::size_t>(std::max(count, 0)));
      rc = MPI_Recv(m.data.data(), count, MPI_BYTE, status.MPI_SOURCE, status.MPI_TAG, comm, MPI_STATUS_IGNORE);
      if (rc != MPI_SUCCESS)
        throw PeerTimeout("receiving " + what + " from " + peer + " failed (" + mpi_error_text(rc) + ")");
      if (std::find(tags.begin(), tags.end(), m.tag) == tags.end())
        throw PeerError("protocol error: received " + std::string(tag_name(m.tag)) + " (tag " +
                        std::to_string(m.tag) + ", " + std::to_string(m.data.size()) + " bytes) from " + peer +
                        " while waiting for " + what + " (are both programs from the same release?)");
      return m;
    }
    if (peer_ended != nullptr && !ended && peer_ended->load()) {
      ended = true;  // keep polling briefly: a last message may still be on its way
      t_ended = Clock::now();
    }
    if (ended && seconds_since(t_ended) > 0.5)
      throw PeerEnded(peer + " ended (it reached the end-of-job barrier) while we were waiting for " + what);
    if (timeout_s > 0 && seconds_since(t0) > timeout_s)
      throw PeerTimeout("no reply from " + peer + " within " + format_seconds(timeout_s) + " s while waiting for " +
                        what + "; it may have crashed or hung - check its output");
    backoff.wait();
  }
}

const char* tag_name(int tag) {
  switch (tag) {
    case kTagHello: return "Hello";
    case kTagHelloReply: return "HelloReply";
    case kTagIntercomm: return "Intercomm";
    case kTagStep: return "StepHeader";
    case kTagStepAck: return "StepAck";
    case kTagZones: return "ZoneMap";
    case kTagVolumes: return "CellVolumes";
    case kTagRezoneCells: return "RezoneCells";
    case kTagGrainSums: return "GrainSums";
    case kTagCorrections: return "GrainCorrections";
    case kTagOracle: return "OracleSettings";
    case kTagSupport: return "SupportForce";
    case kTagDiscreteCells: return "DiscreteCells";
    case kTagNodes: return "NodeRecords";
    case kTagNodeReply: return "NodeUpdates";
    case kTagGrains: return "GrainRecords";
    case kTagState: return "StateRequest";
    case kTagFinish: return "Finish";
    case kTagAbort: return "AbortNote";
    default: return "an unknown message";
  }
}

const char* model_name(int model) {
  switch (model) {
    case kModelDruckerPrager: return "drucker_prager";
    case kModelMuI: return "mu_i";
    default: return "unknown";
  }
}

// ---------------------------------------------------------------------------- Intercomm
Intercomm::Intercomm(MPI_Comm comm) : comm_(comm) {
  if (comm_ != MPI_COMM_NULL) MPI_Comm_set_errhandler(comm_, MPI_ERRORS_RETURN);
}

Intercomm::~Intercomm() {
  int finalized = 1;
  MPI_Finalized(&finalized);
  if (comm_ != MPI_COMM_NULL && !finalized) MPI_Comm_free(&comm_);
}

Intercomm& Intercomm::operator=(Intercomm&& o) noexcept {
  if (this != &o) {
    Intercomm old(comm_);
    comm_ = o.comm_;
    o.comm_ = MPI_COMM_NULL;
  }
  return *this;
}

int Intercomm::remote_size() const {
  int n = 0;
  if (comm_ != MPI_COMM_NULL) MPI_Comm_remote_size(comm_, &n);
  return n;
}

// ------------------------------------------------------------------------------ helpers
int first_world_rank_outside(MPI_Comm local) {
  MPI_Group world_group, local_group;
  MPI_Comm_group(MPI_COMM_WORLD, &world_group);
  MPI_Comm_group(local, &local_group);
  int nlocal = 0, nworld = 0;
  MPI_Group_size(local_group, &nlocal);
  MPI_Group_size(world_group, &nworld);
  std::vector<int> ranks(static_cast<std::size_t>(nlocal)), in_world(static_cast<std::size_t>(nlocal));
  for (int i = 0; i < nlocal; ++i) ranks[static_cast<std::size_t>(i)] = i;
  MPI_Group_translate_ranks(local_group, nlocal, ranks.data(), world_group, in_world.data());
  MPI_Group_free(&world_group);
  MPI_Group_free(&local_group);
  std::vector<char> mine(static_cast<std::size_t>(nworld), 0);
  for (int r : in_world)
    if (r >= 0 && r < nworld) mine[static_cast<std::size_t>(r)] = 1;
  for (int r = 0; r < nworld; ++r)
    if (!mine[static_cast<std::size_t>(r)]) return r;
  return -1;
}

void send_bytes(MPI_Comm comm, int dest, int tag, const void* data, int bytes, double timeout_s,
                const std::string& what) {
  // Sent from a private copy: after a timeout MPI may still hold the request, and the copy is
  // left to it (a few hundred bytes, once, on the way to MPI_Abort).
  auto copy = std::make_unique<std::vector<char>>(static_cast<const char*>(data),
                                                  static_cast<const char*>(data) + bytes);
  MPI_Request req;
  int rc = MPI_Isend(copy->data(), bytes, MPI_BYTE, dest, tag, comm, &req);
  if (rc != MPI_SUCCESS) throw PeerTimeout("sending " + what + " failed (" + mpi_error_text(rc) + ")");
  const auto t0 = Clock::now();
  Backoff backoff;
  for (;;) {
    int done = 0;
    rc = MPI_Test(&req, &done, MPI_STATUS_IGNORE);
    if (rc != MPI_SUCCESS) throw PeerTimeout("sending " + what + " failed (" + mpi_error_text(rc) + ")");
    if (done) return;
    if (timeout_s > 0 && seconds_since(t0) > timeout_s) {
      MPI_Request_free(&req);
      copy.release();
      throw PeerTimeout("could not deliver " + what + " within " + format_seconds(timeout_s) +
                        " s; the other program may have crashed or hung - check its output");
    }
    backoff.wait();
  }
}

int recv_bytes(MPI_Comm comm, int source, std::initializer_list<int> tags, void* data, int bytes,
               double timeout_s, const std::string& peer, const std::string& what) {
  Message m = recv_message(comm, source, tags, timeout_s, peer, what);
  if (m.data.size() != static_cast<std::size_t>(bytes))
    throw PeerError("protocol error: " + std::string(tag_name(m.tag)) + " from " + peer + " has " +
                    std::to_string(m.data.size()) + " bytes, expected " + std::to_string(bytes) +
                    " (are both programs from the same release?)");
  std::memcpy(data, m.data.data(), m.data.size());
  return m.tag;
}

// --------------------------------------------------------------------------------- Link
Link::Link(Intercomm comm, bool leader, double reply_timeout, std::string peer_name)
    : comm_(std::move(comm)), leader_(leader), reply_timeout_(reply_timeout), peer_name_(std::move(peer_name)) {}

void Link::send(int dest, int tag, const void* data, std::size_t bytes, const std::string& what) {
  try {
    send_bytes(comm(), dest, tag, data, static_cast<int>(bytes), reply_timeout_, what + " to " + peer_name_);
  } catch (const PeerError&) {
    state_ = State::kUnresponsive;
    throw;
  }
}

Message Link::receive(int source, std::initializer_list<int> tags, const std::string& what, double timeout_s,
                      const std::atomic<bool>* peer_ended) {
  try {
    return recv_message(comm(), source, tags, timeout_s < 0 ? reply_timeout_ : timeout_s, peer_name_, what,
                        peer_ended);
  } catch (const PeerError&) {
    state_ = State::kUnresponsive;
    throw;
  }
}

void Link::finish(std::int64_t step) {
  if (state_ != State::kConnected) return;
  if (leader_) {
    Finish f;
    f.step = step;
    f.exchanges = exchanges_;
    try {
      send_msg(comm(), 0, kTagFinish, f, reply_timeout_, "the finish message to " + peer_name_);
    } catch (const PeerError&) {
      state_ = State::kUnresponsive;
      throw;
    }
  }
  state_ = State::kFinished;
}

void Link::abort_note(const std::string& reason) noexcept {
  if (!leader_ || state_ != State::kConnected) return;
  AbortNote note;
  set_text(note.reason, reason);
  try {
    send_msg(comm(), 0, kTagAbort, note, 2.0, "the abort notice");
  } catch (...) {
  }
  state_ = State::kAborted;
}

// ----------------------------------------------------------------------------- connect
namespace {

struct Outcome {
  std::int32_t status = 0;  // 0 ok, 1 rejected, 2 no reply / lost, 3 AbortNote before connecting, 4 peer ended
  char message[2 * kTextSize] = {};
};

/// The release this process announces: coupler::release_version(), or for tests of the
/// mismatch handling the value of HYBRID_COUPLER_FAKE_RELEASE.
std::string wire_release() {
  const char* fake = std::getenv("HYBRID_COUPLER_FAKE_RELEASE");
  return fake != nullptr && *fake != '\0' ? std::string(fake) : std::string(release_version());
}

Intercomm make_intercomm(MPI_Comm local, int remote_leader) {
  MPI_Comm inter = MPI_COMM_NULL;
  const int rc = MPI_Intercomm_create(local, 0, MPI_COMM_WORLD, remote_leader, kTagIntercomm, &inter);
  if (rc != MPI_SUCCESS) throw PeerError("MPI_Intercomm_create failed: " + mpi_error_text(rc));
  return Intercomm(inter);
}

}  // namespace

std::unique_ptr<Link> connect_dem(MPI_Comm local, Hello hello) {
  DemGlobal& g = dem();
  if (g.phase == DemPhase::kFinished)
    throw PeerError("the coupled run with the MPM process has already finished (a fix hybrid/mpm was deleted); "
                    "only one coupled run per MPI job is possible");
  int me = 0, n = 0;
  MPI_Comm_rank(local, &me);
  MPI_Comm_size(local, &n);
  const int remote = first_world_rank_outside(local);
  if (remote < 0) {
    g.phase = DemPhase::kNoPeer;
    const bool lammps = g.host == "LAMMPS";
    throw PeerError("no MPM process in this MPI job: MPI_COMM_WORLD holds only the " + std::to_string(n) + " " +
                    g.host + " rank(s). Start both programs in one mpirun, e.g. 'mpirun -np " + std::to_string(n) +
                    (lammps ? " lmp_hybrid" : " liggghts_hybrid") +
                    " -in deck : -np 1 mpm_solver --coupled' (tools/hybrid_launch.py composes it" +
                    (lammps ? "; a LAMMPS with the plugin also needs '-mpicolor 0')" : ")"));
  }
  hello.protocol = kProtocolVersion;
  set_text(hello.release, wire_release());
  hello.dem_ranks = n;

  Outcome out;
  HelloReply reply;
  if (me == 0) {
    try {
      send_msg(MPI_COMM_WORLD, remote, kTagHello, hello, hello.reply_timeout,
               "the handshake (Hello) to the MPM process");
      Message m = recv_message(MPI_COMM_WORLD, remote, {kTagHelloReply}, hello.reply_timeout, "the MPM process",
                               "the reply to the handshake (Hello)");
      if (!m.fits<HelloReply>()) {
        out.status = 1;
        set_text(out.message, "version mismatch: " + versions_text("fix hybrid/mpm", wire_release(), kProtocolVersion) +
                                  ", the MPM process answered in protocol " + std::to_string(m.announced_protocol()) +
                                  "; rebuild both from the same source tree");
      } else {
        reply = m.as<HelloReply>();
        const std::string peer_release = get_text(reply.release);
        if (!reply.ok) {
          out.status = 1;
          set_text(out.message, "the MPM process refused the connection: " + get_text(reply.message));
        } else if (reply.protocol != kProtocolVersion || peer_release != wire_release()) {
          out.status = 1;
          set_text(out.message,
                   "version mismatch: " + versions_text("fix hybrid/mpm", wire_release(), kProtocolVersion) + ", " +
                       versions_text("mpm_solver", peer_release, reply.protocol) +
                       "; rebuild both from the same source tree");
        } else {
          set_text(out.message, get_text(reply.message));
        }
      }
    } catch (const PeerError& e) {
      out.status = 2;
      set_text(out.message, e.what());
    }
  }
  MPI_Bcast(&out, sizeof out, MPI_BYTE, 0, local);
  MPI_Bcast(&reply, sizeof reply, MPI_BYTE, 0, local);
  if (out.status != 0) {
    g.phase = out.status == 2 ? DemPhase::kUnresponsive : DemPhase::kRejected;
    if (out.status == 2) throw PeerTimeout(get_text(out.message));
    throw PeerError(get_text(out.message));
  }
  auto link = std::make_unique<Link>(make_intercomm(local, remote), me == 0, hello.reply_timeout, "the MPM process");
  link->set_peer_info(get_text(out.message));
  return link;
}

std::unique_ptr<Link> connect_mpm(MPI_Comm local, double hello_timeout_s, Hello& hello, const std::string& greeting,
                                  std::string (*check)(const Hello&), const std::atomic<bool>* peer_ended) {
  int me = 0;
  MPI_Comm_rank(local, &me);
  const int remote = first_world_rank_outside(local);
  if (remote < 0)
    throw PeerError("no DEM host process in this MPI job (mpm_solver --coupled runs alongside LAMMPS or LIGGGHTS in "
                    "one mpirun: 'mpirun -np 2 lmp_hybrid -in deck : -np 1 mpm_solver --coupled', or liggghts_hybrid "
                    "in its place; see tools/hybrid_launch.py)");
  Outcome out;
  if (me == 0) {
    try {
      Message m = recv_message(MPI_COMM_WORLD, remote, {kTagHello, kTagAbort}, hello_timeout_s, kUnknownDemHost,
                               "the handshake (Hello) from fix hybrid/mpm", peer_ended);
      if (m.tag == kTagAbort) {
        out.status = 3;
        set_text(out.message, get_text(m.as<AbortNote>().reason));
      } else {
        HelloReply reply;
        set_text(reply.release, wire_release());
        std::string error;
        if (!m.fits<Hello>()) {
          error = "version mismatch: fix hybrid/mpm speaks protocol " + std::to_string(m.announced_protocol()) + " (a " +
                  std::to_string(m.data.size()) + "-byte Hello), " +
                  versions_text("mpm_solver", wire_release(), kProtocolVersion) +
                  "; rebuild both from the same source tree";
        } else {
          hello = m.as<Hello>();
          const std::string peer_release = get_text(hello.release);
          if (hello.protocol != kProtocolVersion || peer_release != wire_release())
            error = "version mismatch: " + versions_text("fix hybrid/mpm", peer_release, hello.protocol) + ", " +
                    versions_text("mpm_solver", wire_release(), kProtocolVersion) +
                    "; rebuild both from the same source tree";
          else if (check != nullptr)
            error = check(hello);
        }
        reply.ok = error.empty() ? 1 : 0;
        set_text(reply.message, error.empty() ? greeting : error);
        send_msg(MPI_COMM_WORLD, remote, kTagHelloReply, reply, 10.0, "the handshake reply to the DEM host");
        if (!error.empty()) {
          out.status = 1;
          set_text(out.message, error);
        }
      }
    } catch (const PeerEnded& e) {
      out.status = 4;
      set_text(out.message, e.what());
    } catch (const PeerError& e) {
      out.status = 2;
      set_text(out.message, e.what());
    }
  }
  MPI_Bcast(&out, sizeof out, MPI_BYTE, 0, local);
  MPI_Bcast(&hello, sizeof hello, MPI_BYTE, 0, local);
  if (out.status == 4)
    throw PeerEnded(std::string(kUnknownDemHost) + " ended before connecting: it reached the end of the job without "
                    "a handshake (an error in its input or command line, or no run with fix hybrid/mpm - see its "
                    "output)");
  if (out.status == 3) throw PeerEnded(std::string(kUnknownDemHost) + " ended before connecting: " + get_text(out.message));
  if (out.status == 2) throw PeerTimeout(get_text(out.message));
  if (out.status != 0) throw PeerError(get_text(out.message));
  // The MPM side waits for the DEM host (receiving or sending) at most the DEM's idle timeout.
  auto link = std::make_unique<Link>(make_intercomm(local, remote), me == 0, hello.idle_timeout,
                                     dem_host_name(get_text(hello.host)));
  link->set_peer_info(get_text(hello.host));
  return link;
}

// ----------------------------------------------------------------- DEM global handle
std::string dem_host_name(const std::string& host_text) {
  for (const char* known : {"LAMMPS", "LIGGGHTS"}) {
    const std::string name(known);
    if (host_text.compare(0, name.size(), name) == 0 && (host_text.size() == name.size() || host_text[name.size()] == ' '))
      return name;
  }
  return kUnknownDemHost;
}

void install_dem_finalize_hook(MPI_Comm local, const std::string& host) {
  DemGlobal& g = dem();
  if (g.host != host) {
    g.host = host;
    g.unconnected_reason = DemGlobal::unconnected_text(host);
  }
  int me = 0;
  MPI_Comm_rank(local, &me);
  g.leader = me == 0;
  g.remote_leader = first_world_rank_outside(local);
  g.registered = true;
  if (!g.hook_installed) {
    // Without the hook an error in LAMMPS would leave the MPM process waiting for its idle
    // timeout, so a failure here is an error, not something to skip.
    int keyval = MPI_KEYVAL_INVALID;
    int rc = MPI_Comm_create_keyval(MPI_COMM_NULL_COPY_FN, dem_finalize_hook, &keyval, nullptr);
    if (rc != MPI_SUCCESS)
      throw std::runtime_error("cannot install the MPI_Finalize hook that tells the MPM process about " + host +
                               " errors (MPI_Comm_create_keyval: " + mpi_error_text(rc) + ")");
    rc = MPI_Comm_set_attr(MPI_COMM_SELF, keyval, nullptr);
    if (rc != MPI_SUCCESS) {
      MPI_Comm_free_keyval(&keyval);
      throw std::runtime_error("cannot install the MPI_Finalize hook that tells the MPM process about " + host +
                               " errors (MPI_Comm_set_attr on MPI_COMM_SELF: " + mpi_error_text(rc) + ")");
    }
    g.hook_installed = true;
  }
}

Link* peer() { return dem().link; }

void set_peer(Link* link) {
  DemGlobal& g = dem();
  if (link == nullptr && g.link != nullptr) {
    switch (g.link->state()) {
      case Link::State::kFinished:
      case Link::State::kAborted: g.phase = DemPhase::kFinished; break;
      case Link::State::kUnresponsive: g.phase = DemPhase::kUnresponsive; break;
      case Link::State::kConnected: g.phase = DemPhase::kFinished; break;
    }
  } else if (link != nullptr) {
    g.phase = DemPhase::kConnected;
  }
  g.link = link;
}

void set_unconnected_exit_reason(const std::string& reason) { dem().unconnected_reason = reason; }

void set_world_barrier_by_hook(bool by_hook) { dem().barrier_by_hook = by_hook; }

void dem_end_of_job() {
  DemGlobal& g = dem();
  if (unresponsive()) abort_job_unresponsive();
  send_end_notes();
  if (!g.barrier_done) {
    g.barrier_done = true;
    MPI_Barrier(MPI_COMM_WORLD);
  }
}

}  // namespace coupler
