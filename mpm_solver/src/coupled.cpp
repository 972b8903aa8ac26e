#include "mpm/coupled.hpp"

#include <cxxabi.h>
#include <mpi.h>
#include <omp.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <typeinfo>

#include "coupler/protocol.hpp"
#include "coupler/version.hpp"
#include "mpm/coupled_continuum.hpp"
#include "mpm/materials.hpp"

namespace mpm {

namespace {

/// Bytes per grid node the coupled continuum holds (grid mass and momentum, the DEM side's node
/// sums, support forces and bookkeeping), generously: for the memory check of the handshake.
constexpr double kBytesPerNode = 160.0;

/// `x` to `digits` significant digits (%g).
std::string format_digits(double x, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, x);
  return buf;
}

std::string format_count(double x) { return format_digits(x, x >= 100 ? 3 : 2); }

/// Parameters of the DEM side this MPM side cannot work with ("" if acceptable).
std::string check_hello(const coupler::Hello& h) {
  const std::string units = coupler::get_text(h.units);
  if (units != "si") return "fix hybrid/mpm runs with units '" + units + "', mpm_solver needs units si";
  if (h.dimension != 2 && h.dimension != 3)
    return "dimension " + std::to_string(h.dimension) + " is not supported (2 or 3)";
  if (!(h.cell > 0)) return "the grid cell size must be > 0 (got " + std::to_string(h.cell) + ")";
  if (!(h.dt > 0)) return "the DEM time step must be > 0 (got " + std::to_string(h.dt) + ")";
  if (h.model != coupler::kModelDruckerPrager && h.model != coupler::kModelMuI)
    return "unknown constitutive model id " + std::to_string(h.model);
  if (h.mpm_every < 1) return "the exchange interval must be >= 1 step";
  if (!std::isfinite(h.cell)) return "the grid cell size must be finite (got " + std::to_string(h.cell) + ")";
  if (!std::isfinite(h.dt)) return "the DEM time step must be finite (got " + std::to_string(h.dt) + ")";
  if (!std::isfinite(h.time) || h.step < 0)
    return "the DEM step and time at the connection must be finite and >= 0 (got step " + std::to_string(h.step) +
           ", time " + std::to_string(h.time) + " s)";
  if (!(h.reply_timeout >= 0) || !(h.idle_timeout >= 0))
    return "the timeouts must be >= 0 s (got timeout " + std::to_string(h.reply_timeout) + ", idle " +
           std::to_string(h.idle_timeout) + ")";
  for (int a = 0; a < h.dimension; ++a)
    if (!std::isfinite(h.box_lo[a]) || !std::isfinite(h.box_hi[a]) || !(h.box_hi[a] > h.box_lo[a]))
      return "the box is empty or not finite along " + std::string(1, "xyz"[a]) + " (from " +
             std::to_string(h.box_lo[a]) + " to " + std::to_string(h.box_hi[a]) + " m)";
  for (int a = 0; a < h.dimension; ++a)
    if (!(h.box_hi[a] - h.box_lo[a] >= 2 * h.cell))
      return "the grid cell size " + std::to_string(h.cell) + " m is more than half the box along " +
             std::string(1, "xyz"[a]) + " (" + std::to_string(h.box_hi[a] - h.box_lo[a]) +
             " m): choose a smaller 'cell' on the fix line";
  // The grid's memory: a cell far too small for the box would otherwise end in an allocation
  // failure or the kernel's out-of-memory killer rather than a message.
  double nodes = 1;
  for (int a = 0; a < h.dimension; ++a)
    nodes *= std::ceil((h.box_hi[a] - h.box_lo[a]) / h.cell) + 2 * coupler::kGridPad + 1;
  const double bytes = nodes * kBytesPerNode;
  const double physical = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * static_cast<double>(sysconf(_SC_PAGESIZE));
  if (nodes > 2e9 || (physical > 0 && bytes > 0.5 * physical))
    return "the grid cell size " + std::to_string(h.cell) + " m gives a grid of " + format_count(nodes) +
           " nodes, which needs about " + format_count(bytes / 1e9) + " GB (this machine has " +
           format_count(physical / 1e9) + " GB): choose a larger 'cell' on the fix line";
  const coupler::ContinuumSettings& c = h.continuum;
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(c.gravity[a])) return "the gravity is not finite (component " + std::to_string(a) + ")";
  if (!(c.cfl > 0 && c.cfl <= 1)) return "the Courant number cfl must be in (0, 1] (got " + std::to_string(c.cfl) + ")";
  if (!(c.grain_weight > 0 && c.grain_weight < 1))
    return "the grain weight must be between 0 and 1 (got " + std::to_string(c.grain_weight) + ")";
  if (!(c.pic >= 0 && c.pic <= 1) && c.pic != coupler::kPicRegime)
    return "pic must be in [0, 1] or 'regime' (got " + std::to_string(c.pic) + ")";
  if (!(c.support_gain >= 0 && c.support_gain <= 1))
    return "the support gain must be in [0, 1] (got " + std::to_string(c.support_gain) + ")";
  if (!(c.agreement_time >= 0) || !std::isfinite(c.agreement_time))
    return "the agreement's relaxation time must be finite and >= 0 (got " + std::to_string(c.agreement_time) + ")";
  if (c.points_per_axis < 1 || c.points_per_axis > 4)
    return "points per cell and axis must be 1 to 4 (got " + std::to_string(c.points_per_axis) + ")";
  if (c.output_every < 0) return "the output interval must be >= 0 (got " + std::to_string(c.output_every) + ")";
  if (c.wall_contact != coupler::kWallSticky && c.wall_contact != coupler::kWallSlip &&
      c.wall_contact != coupler::kWallFriction)
    return "unknown wall condition id " + std::to_string(c.wall_contact);
  if (!(c.wall_friction >= 0) || !std::isfinite(c.wall_friction))
    return "the wall friction must be finite and >= 0 (got " + std::to_string(c.wall_friction) + ")";
  if (c.touched_faces >= (1u << (2 * h.dimension)))
    return "the touched container faces name a face the " + std::to_string(h.dimension) + "D box does not have";
  for (int a = 0; a < h.dimension; ++a) {
    const double slack = 1e-9 * (h.box_hi[a] - h.box_lo[a]);
    if (!(c.container_lo[a] >= h.box_lo[a] - slack && c.container_hi[a] <= h.box_hi[a] + slack &&
          c.container_hi[a] > c.container_lo[a]))
      return "the container along " + std::string(1, "xyz"[a]) + " (" + std::to_string(c.container_lo[a]) + " to " +
             std::to_string(c.container_hi[a]) + " m) is empty or leaves the box (" + std::to_string(h.box_lo[a]) +
             " to " + std::to_string(h.box_hi[a]) + " m)";
  }
  try {
    MaterialModel model(coupled_scene(h).materials.at(0));  // the material checks of pure MPM scenes
  } catch (const UserError& e) {
    return std::string("the continuum's material (fix hybrid/mpm keywords youngs, poisson, friction, mu_s, mu_2, "
                       "I0, diameter, grain_density, critical_packing): ") + e.what();
  }
  return "";
}

void say(const CoupledOptions& opt, const std::string& line) {
  if (opt.quiet) return;
  std::printf("mpm_solver: %s\n", line.c_str());
  std::fflush(stdout);
}

void error_line(const std::string& line) {
  std::fprintf(stderr, "mpm_solver: error: %s\n", line.c_str());
  std::fflush(stderr);
  std::fflush(stdout);
}

/// Lowest scheduling priority for the calling thread.
void lower_priority() {
  sched_param param{};
  param.sched_priority = 0;
  if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &param) != 0)
    setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 19);
}

/// The end-of-job MPI_Barrier(MPI_COMM_WORLD) (coupler/protocol.hpp), entered by a helper
/// thread at start-up: `done` turns true once the DEM host has entered it too, i.e. it is ending.
/// Open MPI busy-polls inside MPI_Barrier, so the thread runs with the idle scheduling policy
/// (SCHED_IDLE; nice 19 if that is refused): it takes only CPU time nobody else wants.
class EndOfJobBarrier {
 public:
  EndOfJobBarrier() : thread_([this] {
    lower_priority();
    MPI_Barrier(MPI_COMM_WORLD);
    done_ = true;
  }) {}
  ~EndOfJobBarrier() {
    if (thread_.joinable()) thread_.join();
  }
  const std::atomic<bool>* flag() const { return &done_; }
  /// Waits for the DEM host to reach the barrier; false after `timeout_s` (<= 0: forever).
  bool wait(double timeout_s) {
    const auto t0 = std::chrono::steady_clock::now();
    while (!done_) {
      if (timeout_s > 0 && std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > timeout_s)
        return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    thread_.join();
    return true;
  }

 private:
  std::atomic<bool> done_{false};
  std::thread thread_;
};

/// The MPM process's OpenMP threads for the handshake line, with their wait policy when there
/// are several (main.cpp makes it passive unless the environment sets it: idle threads that
/// spin take the cores from LAMMPS's steps).
std::string threads_text() {
  const int n = omp_get_max_threads();
  if (n == 1) return "1 OpenMP thread";
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  return std::to_string(n) + " OpenMP threads, OMP_WAIT_POLICY=" + (policy != nullptr ? policy : "unset");
}

/// The demangled name of a type, for messages.
std::string type_name(const std::type_info& type) {
  int status = 0;
  char* name = abi::__cxa_demangle(type.name(), nullptr, nullptr, &status);
  std::string out = status == 0 && name != nullptr ? name : type.name();
  std::free(name);
  return out;
}

}  // namespace

// Every failure of the continuum goes through here (an HDF5 or Eigen failure, a bug alike), so
// that none leaves the DEM host waiting for an answer until its timeout.
std::string describe_exception(const std::exception_ptr& error) {
  try {
    std::rethrow_exception(error);
  } catch (const UserError& e) {
    return e.what();
  } catch (const std::bad_alloc& e) {
    return "out of memory (" + type_name(typeid(e)) + ")";
  } catch (const std::exception& e) {
    return std::string(e.what()) + " (" + type_name(typeid(e)) + ")";
  } catch (...) {
    return "an exception of unknown type (not a std::exception)";
  }
}

namespace {

/// Test hook for tests/test_coupled_launch.py: HYBRID_MPM_TEST_FAULT=<where>@<step> throws once,
/// at the first exchange at or after DEM step <step>: `exchange` a std::runtime_error while
/// the exchange is computed, `after` one in the work after its acknowledgement, `unknown` a
/// non-standard exception outside the exchange's own handlers. Unset: does nothing.
class TestFault {
 public:
  TestFault() {
    const char* v = std::getenv("HYBRID_MPM_TEST_FAULT");
    if (v == nullptr || *v == '\0') return;
    spec_ = v;
    const auto at = spec_.find('@');
    where_ = spec_.substr(0, at);
    if (at != std::string::npos) step_ = std::atoll(spec_.c_str() + at + 1);
  }
  void check(const char* where, std::int64_t step) {
    if (fired_ || spec_.empty() || where_ != where || step < step_) return;
    fired_ = true;
    if (where_ == "unknown") throw 17;  // not a std::exception
    throw std::runtime_error("test fault HYBRID_MPM_TEST_FAULT=" + spec_ + " at step " + std::to_string(step));
  }

 private:
  std::string spec_, where_;
  std::int64_t step_ = 0;
  bool fired_ = false;
};

/// Checks every step header against the DEM clock so far ("" if acceptable): a known kind, finite
/// times, a positive step, and no more time between two headers than their steps can hold at the
/// largest DEM step seen (twice that, for round-off and a step changed between runs). Without it a
/// corrupt time would have the continuum take ~forever to catch up, or NaN it.
class HeaderClock {
 public:
  explicit HeaderClock(const coupler::Hello& hello) : step_(hello.step), time_(hello.time), max_dt_(hello.dt) {}
  std::string check(const coupler::StepHeader& h) {
    const std::string at = "the step header of step " + std::to_string(h.step);
    if (h.kind < coupler::kStepCouple || h.kind > coupler::kStepLoad)
      return at + " has an unknown kind " + std::to_string(h.kind) + " (0 to 3 are defined)";
    if (!std::isfinite(h.time) || !std::isfinite(h.dt) || !(h.dt > 0) || !std::isfinite(h.next_time))
      return at + " holds a non-finite or non-positive time or time step (time " + std::to_string(h.time) +
             " s, dt " + std::to_string(h.dt) + " s, next exchange " + std::to_string(h.next_time) + " s)";
    if (h.output != 0 && h.output != 1) return at + " has an output flag " + std::to_string(h.output) + " (0 or 1)";
    if (h.kind == coupler::kStepRezone &&
        (h.zone_source < coupler::kZonesOracle || h.zone_source > coupler::kZonesGiven))
      return at + " has an unknown zone source " + std::to_string(h.zone_source);
    if (h.kind == coupler::kStepLoad) {  // a loaded state sets its own clock
      accept(h);
      return "";
    }
    max_dt_ = std::max(max_dt_, h.dt);
    const double steps = static_cast<double>(h.step - step_);
    const double slack = 1e-9 * std::max(1.0, std::abs(h.time));
    if (h.time - time_ > 2.0 * std::max(steps, 0.0) * max_dt_ + slack)
      return at + " is at t = " + std::to_string(h.time) + " s, but the last one (step " + std::to_string(step_) +
             ", t = " + std::to_string(time_) + " s) is only " + std::to_string(steps) + " step(s) of at most " +
             std::to_string(max_dt_) + " s before it";
    if (h.next_time > h.time && h.next_time - h.time > 2.0 * kMaxStepsAhead * max_dt_)
      return at + " announces the next exchange at t = " + std::to_string(h.next_time) + " s, more than " +
             std::to_string(kMaxStepsAhead) + " steps ahead";
    accept(h);
    return "";
  }

 private:
  static constexpr double kMaxStepsAhead = 1e9;
  void accept(const coupler::StepHeader& h) {
    step_ = h.step;
    time_ = h.time;
    max_dt_ = std::max(max_dt_, h.dt);
  }
  std::int64_t step_;
  double time_;
  double max_dt_;
};

/// Error text for the DEM ranks, sent in place of the exchange's answers.
coupler::StepAck error_ack(std::int64_t step, const std::string& what) {
  coupler::StepAck ack;
  ack.step = step;
  ack.status = 1;
  coupler::set_text(ack.message, what);
  return ack;
}

/// One list of T from every DEM rank, in rank order.
template <class T>
std::vector<std::vector<T>> receive_from_all(coupler::Link& link, int tag, const std::string& what) {
  std::vector<std::vector<T>> lists(static_cast<std::size_t>(link.remote_size()));
  for (int r = 0; r < link.remote_size(); ++r)
    lists[r] = link.receive(r, {tag}, what + " from " + link.peer_name() + " rank " + std::to_string(r)).template as_array<T>();
  return lists;
}

void ack_all(coupler::Link& link, const coupler::StepAck& ack, const std::string& what) {
  for (int r = 0; r < link.remote_size(); ++r) link.send_struct(r, coupler::kTagStepAck, ack, what);
}

/// One rezone transaction (coupler/protocol.hpp). Returns 0, or 2 after reporting an error;
/// `moved` says whether it moved material (one that moves none ends after the zone map).
template <int D>
int rezone(coupler::Link& link, CoupledContinuum<D>* continuum, const coupler::StepHeader& h,
           const std::string& deferred_error, const CoupledOptions& opt, bool& moved) {
  const std::string at = " of the rezone at step " + std::to_string(h.step);
  std::vector<std::int8_t> given;
  coupler::OracleSettings oracle;
  std::vector<std::uint64_t> discrete_cells;
  if (h.zone_source == coupler::kZonesGiven)
    given = link.receive(0, {coupler::kTagZones}, "the zone map" + at).as_array<std::int8_t>();
  else {
    oracle = link.receive(0, {coupler::kTagOracle}, "the oracle settings" + at).as<coupler::OracleSettings>();
    discrete_cells = link.receive(0, {coupler::kTagDiscreteCells}, "the cells of the discrete regions" + at)
                         .as_array<std::uint64_t>();
  }
  const auto volumes =
      receive_from_all<coupler::CellGrains>(link, coupler::kTagVolumes, "the grain volumes" + at);
  const std::string failed = "the rezone at step " + std::to_string(h.step) + " failed: ";
  auto fail = [&](const std::string& what) {
    const coupler::StepAck ack = error_ack(h.step, what);
    ack_all(link, ack, "the rezone's error" + at);
    error_line(what);
    return 2;
  };
  std::vector<coupler::RezoneCell<D>> cells;
  try {
    if (!deferred_error.empty()) throw UserError(deferred_error);
    cells = continuum->plan_rezone(h.time, h.zone_source, given, oracle, discrete_cells, volumes);
  } catch (const coupler::PeerError&) {
    throw;
  } catch (...) {
    return fail(failed + describe_exception(std::current_exception()));
  }
  for (int r = 0; r < link.remote_size(); ++r) {
    link.send_array(r, coupler::kTagZones, continuum->zones(), "the new zone map" + at);
    link.send_array(r, coupler::kTagRezoneCells, cells, "the cells to rezone" + at);
  }
  if (cells.empty()) {  // no material moves: the acknowledgement ends the rezone
    coupler::StepAck ack;
    try {
      continuum->complete_rezone({});
      ack = continuum->totals(h.step);
    } catch (...) {
      return fail(failed + describe_exception(std::current_exception()));
    }
    ack_all(link, ack, "the rezone's acknowledgement" + at);
    moved = false;
    return 0;
  }
  moved = true;
  const auto grains = receive_from_all<coupler::GrainSums<D>>(link, coupler::kTagGrainSums, "the grain sums" + at);
  std::vector<coupler::GrainCorrection<D>> corrections;
  try {
    corrections = continuum->complete_rezone(grains);
  } catch (const coupler::PeerError&) {
    throw;
  } catch (...) {
    return fail(failed + describe_exception(std::current_exception()));
  }
  for (int r = 0; r < link.remote_size(); ++r)
    link.send_array(r, coupler::kTagCorrections, corrections, "the grain corrections" + at);
  const auto support = link.receive(0, {coupler::kTagSupport}, "the grains' support force" + at).as_array<double>();
  if (support.size() != 3) return fail("protocol error: the grains' support force has " +
                                       std::to_string(support.size()) + " components");
  if (!std::isfinite(support[0]) || !std::isfinite(support[1]) || !std::isfinite(support[2]))
    return fail("the grains' support force" + at + " is not finite: a coupled grain's state is NaN or inf");
  coupler::StepAck ack;
  try {
    continuum->balance_support(Eigen::Map<const Eigen::Vector3d>(support.data()).head<D>());
    ack = continuum->totals(h.step);
  } catch (...) {
    return fail(failed + describe_exception(std::current_exception()));
  }
  say(opt, "step " + std::to_string(h.step) + ": rezone moved the material of " + std::to_string(ack.moved_cells) +
               " cells (" + std::to_string(ack.points_made) + " points made, " + std::to_string(ack.points_removed) +
               " removed); cells continuum/hybrid/discrete " + std::to_string(ack.zone_cells[coupler::kContinuum]) +
               "/" + std::to_string(ack.zone_cells[coupler::kHybrid]) + "/" +
               std::to_string(ack.zone_cells[coupler::kDiscrete]) + "; rests to nearby points " +
               std::to_string(ack.rests_moved) + ", kept " + std::to_string(ack.rests_kept));
  ack_all(link, ack, "the rezone's acknowledgement" + at);
  return 0;
}

/// Where the MPM process's wall time goes in a coupled run, printed when it finishes: the DEM
/// host waits on the agreement (before the acknowledgement) and, when the rest outlasts its next
/// steps, on the header after it, so these are the terms to read against the fix's own wait.
/// The agreement is the continuum's work on that path (the agreed velocities, the grid totals
/// the acknowledgement carries); the replies are the messages that carry them.
class ServeLedger {
 public:
  enum Phase { kIdle, kSubstepsBefore, kAgreement, kReplies, kG2P, kOutput, kSubstepsAfter, kRezone, kOther, kCount };
  /// Adds the time since the last mark to `phase`.
  void lap(Phase phase) {
    const auto now = Clock::now();
    seconds_[phase] += std::chrono::duration<double>(now - mark_).count();
    mark_ = now;
  }
  std::string summary() const {
    static const char* const names[kCount] = {"waiting for the DEM host", "substeps before the agreement",
                                              "agreement", "replies and acknowledgement", "G2P", "output",
                                              "substeps after the acknowledgement", "rezones", "other"};
    double total = 0;
    for (double t : seconds_) total += t;
    std::string out = "wall time " + format_digits(total, 3) + " s:";
    for (int i = 0; i < kCount; ++i)
      out += std::string(i ? "," : "") + " " + names[i] + " " + format_digits(seconds_[i], 3);
    return out;
  }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point mark_ = Clock::now();
  double seconds_[kCount] = {};
};

/// The end-of-run line of what the rezones did to the points' energy (CoupledContinuum::RezoneEnergy).
template <class Energy>
std::string rezone_energy_text(const Energy& e) {
  auto term = [](const char* name, const typename Energy::Parts& p) {
    return std::string(name) + " " + format_digits(p.total(), 4) + " (kinetic " + format_digits(p.kinetic, 4) +
           ", potential " + format_digits(p.potential, 4) + ", elastic " + format_digits(p.elastic, 4) + ")";
  };
  return "the rezones' energy on the points (J, J/m in 2D): " + term("made", e.made) + ", " +
         term("removed", e.removed) + ", " + term("corrected", e.corrected) + ", " + term("rests", e.rests) +
         "; " + coupler::mechanism_terms(e.by_mechanism, term) + "; in all " + format_digits(e.total(), 4);
}

/// Serves the coupled run until Finish (returns 0), an AbortNote (returns 1) or a failure it
/// reported to the DEM ranks (returns 2). `step` follows the last step header.
template <int D>
int serve_loop(coupler::Link& link, const coupler::Hello& hello, const CoupledOptions& opt,
               const std::atomic<bool>* ended, std::int64_t& step) {
  std::string deferred_error;  // a failure after the last acknowledgement, reported at the next exchange
  std::unique_ptr<CoupledContinuum<D>> built;
  TestFault fault;
  try {
    built = std::make_unique<CoupledContinuum<D>>(hello);
  } catch (...) {  // e.g. an output directory that cannot be created
    deferred_error = "the MPM process could not set up the continuum: " + describe_exception(std::current_exception());
  }
  const double idle = hello.idle_timeout;
  HeaderClock clock(hello);
  ServeLedger ledger;
  long steps = 0;
  for (;;) {
    ledger.lap(ServeLedger::kOther);
    const coupler::Message m = link.receive(
        0, {coupler::kTagStep, coupler::kTagFinish, coupler::kTagAbort},
        "the next message from fix hybrid/mpm (a step header or the finish message; the fix keyword 'idle' sets "
        "this wait)",
        idle, ended);
    ledger.lap(ServeLedger::kIdle);
    if (m.tag == coupler::kTagStep) {
      const auto h = m.as<coupler::StepHeader>();
      step = h.step;
      const std::string at = " at step " + std::to_string(h.step);
      if (const std::string bad = clock.check(h); !bad.empty()) throw coupler::PeerError("protocol error: " + bad);
      if (h.kind == coupler::kStepCouple) fault.check("unknown", h.step);
      if (h.kind == coupler::kStepRezone) {
        bool moved = true;
        if (rezone<D>(link, built.get(), h, deferred_error, opt, moved) != 0) return 2;
        ledger.lap(ServeLedger::kRezone);
        // no material moved: the DEM host computes its steps to the next exchange, as after one
        // (errors are reported at that exchange)
        if (!moved && h.next_time > h.time) {
          try {
            built->advance_to(h.next_time);
          } catch (...) {
            deferred_error = "the continuum failed after the rezone at step " + std::to_string(h.step) + ": " +
                             describe_exception(std::current_exception());
          }
          ledger.lap(ServeLedger::kSubstepsAfter);
        }
        continue;
      }
      if (h.kind == coupler::kStepSave || h.kind == coupler::kStepLoad) {
        const auto request = link.receive(0, {coupler::kTagState}, "the state request").as<coupler::StateRequest>();
        const std::string path = coupler::get_text(request.path);
        coupler::StepAck ack;
        try {
          if (!deferred_error.empty()) throw UserError(deferred_error);
          if (built->step_open())  // the DEM host announces no next exchange before a restart file
            throw UserError("internal: a state request while a substep is open");
          if (h.kind == coupler::kStepSave) built->save(path, h.step, request.exchanges);
          else built->load(path);
          ack = built->totals(h.step);
          if (h.kind == coupler::kStepLoad)  // the DEM side continues with the saved zones
            for (int r = 0; r < link.remote_size(); ++r)
              link.send_array(r, coupler::kTagZones, built->zones(), "the zone map of the loaded state");
        } catch (const coupler::PeerError&) {
          throw;
        } catch (...) {
          ack = error_ack(h.step, describe_exception(std::current_exception()));
        }
        ack.step = h.step;
        say(opt, std::string(h.kind == coupler::kStepSave ? "saved the state to " : "loaded the state from ") + path);
        ack_all(link, ack, "the state request's acknowledgement");
        if (ack.status != 0) {
          error_line(coupler::get_text(ack.message));
          return 2;
        }
        continue;
      }
      const auto nodes = receive_from_all<coupler::NodeRecord>(link, coupler::kTagNodes, "the grain node sums" + at);
      ledger.lap(ServeLedger::kIdle);
      // The exchange's critical path for the DEM host ends with the acknowledgement; the rest of the
      // continuum's work (G2P, output, the substeps to the next exchange) overlaps the DEM host's
      // next steps. Its errors are reported at the next exchange.
      coupler::StepAck ack;
      if (!deferred_error.empty()) ack = error_ack(h.step, deferred_error);  // (also: no continuum)
      else {
        try {
          fault.check("exchange", h.step);
          built->advance_to(h.time);
          ledger.lap(ServeLedger::kSubstepsBefore);
          const auto replies = built->agree(nodes, h.field_shares != 0);
          ledger.lap(ServeLedger::kAgreement);
          for (int r = 0; r < link.remote_size(); ++r)
            link.send_array(r, coupler::kTagNodeReply, replies[r], "the node velocities" + at);
          ledger.lap(ServeLedger::kReplies);
          ack = built->grid_totals(h.step);
          ledger.lap(ServeLedger::kAgreement);
        } catch (const coupler::PeerError&) {
          throw;
        } catch (...) {
          ack = error_ack(h.step, "the continuum failed" + at + ": " + describe_exception(std::current_exception()));
        }
      }
      ack_all(link, ack, "the acknowledgement of step " + std::to_string(h.step));
      ledger.lap(ServeLedger::kReplies);
      if (ack.status != 0) {
        error_line(coupler::get_text(ack.message));
        return 2;
      }
      link.count_exchange();
      ++steps;
      std::vector<std::vector<coupler::GrainRecord>> grains;
      if (h.output) grains = receive_from_all<coupler::GrainRecord>(link, coupler::kTagGrains, "the grains" + at);
      try {
        fault.check("after", h.step);
        ledger.lap(ServeLedger::kOutput);
        built->complete_step();
        ledger.lap(ServeLedger::kG2P);
        if (h.output) built->write_frame(grains, h.step);
        ledger.lap(ServeLedger::kOutput);
        if (h.next_time > h.time) built->advance_to(h.next_time);
        ledger.lap(ServeLedger::kSubstepsAfter);
      } catch (...) {
        deferred_error = "the continuum failed after step " + std::to_string(h.step) + ": " +
                         describe_exception(std::current_exception());
      }
    } else if (m.tag == coupler::kTagFinish) {
      const auto f = m.as<coupler::Finish>();
      if (!deferred_error.empty()) {
        error_line(deferred_error);
        return 2;
      }
      const std::string host = link.peer_name();    // "LAMMPS step 30", "the DEM host's step 30"
      say(opt, "coupled run finished at " + host + (host == coupler::kUnknownDemHost ? "'s" : "") + " step " +
                   std::to_string(f.step) + " after " + std::to_string(steps) +
                   " exchange(s); " + std::to_string(built->solver().points().size()) + " material points");
      say(opt, ledger.summary());
      say(opt, rezone_energy_text(built->rezone_energy()));
      if (const auto& f = built->field_rule_tally(); f.mass > 0)
        say(opt, "pic regime over the exchanges, by the grains' mass at the shared nodes: share 1 (quasi-static) " +
                     format_digits(100 * f.quasi_static / f.mass, 3) + " %, 0 (flowing) " +
                     format_digits(100 * f.flowing / f.mass, 3) + " %, between " +
                     format_digits(100 * (f.mass - f.quasi_static - f.flowing) / f.mass, 3) + " %; mean share " +
                     format_digits(f.share / f.mass, 3) + ", applied at the agreement's closing " +
                     format_digits(f.applied / f.mass, 3));
      link.mark(coupler::Link::State::kFinished);
      return 0;
    } else {
      const auto note = m.as<coupler::AbortNote>();
      error_line(link.peer_name() + " stopped the coupled run after " + std::to_string(steps) +
                 " exchange(s): " + coupler::get_text(note.reason));
      link.mark(coupler::Link::State::kAborted);
      return 1;
    }
  }
}

/// Sends an error acknowledgement to every DEM rank, whatever it waits for (in an exchange
/// the DEM host takes a StepAck as the MPM process's error), and marks the link aborted.
void report_to_all(coupler::Link& link, const coupler::StepAck& ack) {
  for (int r = 0; r < link.remote_size(); ++r) {
    try {  // small enough to go out at once; bounded anyway
      coupler::send_msg(link.comm(), r, coupler::kTagStepAck, ack, 5.0, "the error report to " + link.peer_name());
    } catch (const coupler::PeerError&) {
    }
  }
  link.mark(coupler::Link::State::kAborted);
}

/// serve_loop with a last line of defence: a failure its own handlers did not catch is printed
/// and sent to every DEM rank as an error acknowledgement (whatever the DEM host waits for in an
/// exchange, it takes a StepAck as the MPM process's error), so the DEM host stops at once naming it.
template <int D>
int serve(coupler::Link& link, const coupler::Hello& hello, const CoupledOptions& opt, const std::atomic<bool>* ended) {
  std::int64_t step = -1;
  try {
    return serve_loop<D>(link, hello, opt, ended, step);
  } catch (const coupler::PeerTimeout&) {
    throw;  // the connection itself failed: run_coupled decides (abort or end)
  } catch (const coupler::PeerEnded&) {
    throw;
  } catch (const coupler::PeerError& e) {
    // A malformed, out-of-order or inconsistent message: the DEM host is still there and waits for an
    // answer, so it gets the error now instead of finding out after its reply timeout.
    error_line(e.what());
    report_to_all(link, error_ack(step, e.what()));
    return 2;
  } catch (...) {
    const std::string what = "the MPM process failed" + (step >= 0 ? " at step " + std::to_string(step) : "") +
                             ": " + describe_exception(std::current_exception());
    error_line(what);
    report_to_all(link, error_ack(step, what));
    return 2;
  }
}

}  // namespace

int run_coupled(const CoupledOptions& opt) {
  // The end-of-job barrier thread spins in Open MPI's progress engine, which the main thread
  // shares: unless that spin yields, each exchange waits milliseconds for the lock (measured:
  // 8-16 ms per exchange without, 0.3 ms with). Read by MPI_Init; a user's setting wins.
  setenv("OMPI_MCA_mpi_yield_when_idle", "1", 0);
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_MULTIPLE, &provided);
  int me = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &me);
  if (provided < MPI_THREAD_MULTIPLE) {
    error_line("the MPI library does not provide MPI_THREAD_MULTIPLE, which --coupled needs");
    MPI_Abort(MPI_COMM_WORLD, 2);
  }
  // Collective over MPI_COMM_WORLD; the DEM host's side does the same with kDemColor.
  MPI_Comm local = MPI_COMM_NULL;
  MPI_Comm_split(MPI_COMM_WORLD, coupler::kMpmColor, me, &local);
  int nlocal = 1;
  MPI_Comm_size(local, &nlocal);
  if (nlocal != 1) {
    int lme = 0;
    MPI_Comm_rank(local, &lme);
    if (lme == 0)
      error_line("mpm_solver --coupled runs on exactly one MPI rank for now (got " + std::to_string(nlocal) +
                 "): use '-np 1' for mpm_solver in the mpirun command");
    MPI_Abort(MPI_COMM_WORLD, 2);
  }
  say(opt, std::string("coupled mode, release ") + coupler::release_version() + ", protocol " +
               std::to_string(coupler::kProtocolVersion) + ", pid " + std::to_string(getpid()) +
               ", MPI_COMM_WORLD rank " + std::to_string(me) + "; waiting for fix hybrid/mpm");

  int rc = 0;
  bool finished = false;
  std::string host = coupler::kUnknownDemHost;    // named by the handshake
  {
    EndOfJobBarrier end_of_job;
    try {
      coupler::Hello hello;
      const std::string greeting = std::string("mpm_solver ") + coupler::release_version() + " (pid " +
                                   std::to_string(getpid()) + ", " + threads_text() + ") ready";
      auto link = coupler::connect_mpm(local, opt.hello_timeout, hello, greeting, &check_hello, end_of_job.flag());
      host = link->peer_name();
      say(opt, "handshake ok with " + link->peer_info() + " on " + std::to_string(hello.dem_ranks) +
                   " rank(s), release " + coupler::get_text(hello.release) + ": dimension " +
                   std::to_string(hello.dimension) + ", cell " + std::to_string(hello.cell) + " m, dt " +
                   std::to_string(hello.dt) + " s, model " + coupler::model_name(hello.model) + ", exchange every " +
                   std::to_string(hello.mpm_every) + " step(s)");
      rc = hello.dimension == 2 ? serve<2>(*link, hello, opt, end_of_job.flag())
                                : serve<3>(*link, hello, opt, end_of_job.flag());
      finished = rc == 0;
    } catch (const coupler::PeerTimeout& e) {
      // the DEM host may be hung: MPI_Finalize would wait for it forever.
      error_line(std::string(e.what()) + "; aborting the MPI job");
      MPI_Abort(MPI_COMM_WORLD, 1);
    } catch (const coupler::PeerEnded& e) {
      error_line(e.what());
      rc = 1;
    } catch (const coupler::PeerError& e) {
      error_line(e.what());
      rc = 2;
    } catch (...) {  // outside the exchanges (e.g. out of memory in the handshake)
      error_line("the MPM process failed: " + describe_exception(std::current_exception()));
      rc = 2;
    }
    // After Finish the DEM host may go on with uncoupled runs for as long as it likes; after an
    // error it reaches the end-of-job barrier within moments.
    if (!end_of_job.wait(finished ? 0.0 : 60.0)) {
      error_line(host + " did not reach the end of the job within 60 s after the coupling failed; aborting the MPI job");
      MPI_Abort(MPI_COMM_WORLD, rc != 0 ? rc : 1);
    }
  }
  MPI_Comm_free(&local);
  MPI_Finalize();
  return rc;
}

}  // namespace mpm
