/* ----------------------------------------------------------------------
   fix hybrid/mpm (hybrid-granular project)

   Phase 1: connection to the MPM process (mpm_solver --coupled), handshake,
   a step header every N steps acknowledged by the MPM process, and a clean
   finish or a bounded failure. The physics coupling (grain <-> grid
   transfers, velocity agreement, zone changes) is not implemented yet.
   Wire protocol: coupler/include/coupler/protocol.hpp. Docs:
   docs/fix_hybrid_mpm.md.
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm.h"

#include "atom.h"
#include "comm.h"
#include "domain.h"
#include "error.h"
#include "update.h"
#include "utils.h"
#include "version.h"

#include "coupler/protocol.hpp"
#include "coupler/version.hpp"

#include <cstring>
#include <string>

using namespace LAMMPS_NS;
using namespace FixConst;

namespace {
const char *const kKeywords = "cell, timeout, idle, model, every";
}

/* ---------------------------------------------------------------------- */

Fix *FixHybridMPM::creator(LAMMPS *lmp, int narg, char **arg)
{
  return new FixHybridMPM(lmp, narg, arg);
}

/* ---------------------------------------------------------------------- */

FixHybridMPM::FixHybridMPM(LAMMPS *lmp, int narg, char **arg) :
    Fix(lmp, narg, arg), cell(-1.0), reply_timeout(30.0), idle_timeout(600.0),
    model(coupler::kModelDruckerPrager), every(1), exchanges(0), restart_exchanges(0), last_step(0)
{
  // fix ID group hybrid/mpm keyword value ...

  int iarg = 3;
  while (iarg < narg) {
    const std::string key = arg[iarg];
    if (key != "cell" && key != "timeout" && key != "idle" && key != "model" && key != "every")
      illegal(fmt::format("unknown keyword '{}' (known keywords: {})", key, kKeywords));
    if (iarg + 2 > narg) illegal(fmt::format("keyword '{}' needs a value", key));
    const std::string val = arg[iarg + 1];
    if (key == "model") {
      if (val == "drucker_prager") model = coupler::kModelDruckerPrager;
      else if (val == "mu_i") model = coupler::kModelMuI;
      else illegal(fmt::format("keyword 'model' must be drucker_prager or mu_i, not '{}'", val));
    } else if (key == "every") {
      if (!utils::is_integer(val) || utils::inumeric(FLERR, val.c_str(), false, lmp) <= 0)
        illegal(fmt::format("keyword 'every' needs a positive integer, not '{}'", val));
      every = utils::inumeric(FLERR, val.c_str(), false, lmp);
    } else {
      if (!utils::is_double(val))
        illegal(fmt::format("keyword '{}' needs a number, not '{}'", key, val));
      const double v = utils::numeric(FLERR, val.c_str(), false, lmp);
      if (key == "cell") {
        if (v <= 0.0) illegal(fmt::format("keyword 'cell' must be > 0, not {}", val));
        cell = v;
      } else if (key == "timeout") {
        if (v <= 0.0) illegal(fmt::format("keyword 'timeout' must be > 0 seconds, not {}", val));
        reply_timeout = v;
      } else {    // idle
        if (v < 0.0) illegal(fmt::format("keyword 'idle' must be >= 0 seconds (0 = wait forever), not {}", val));
        idle_timeout = v;
      }
    }
    iarg += 2;
  }
  if (cell <= 0.0) illegal("keyword 'cell' (the MPM grid cell size) is required");

  nevery = every;
  scalar_flag = 1;           // f_ID = number of completed exchanges with the MPM process
  global_freq = 1;           // a count, valid on any step
  extscalar = 0;
  restart_global = 1;

  // tell the MPM process at MPI_Finalize if LAMMPS stops on an error (see coupler)
  coupler::install_dem_finalize_hook(world);
}

/* ---------------------------------------------------------------------- */

FixHybridMPM::~FixHybridMPM()
{
  if (!link) return;
  // normal end of the coupled run (unfix, clear, end of input): the MPM process exits 0
  try {
    link->finish(last_step);
    if (comm->me == 0)
      utils::logmesg(lmp, fmt::format("fix hybrid/mpm: finished the coupled run after {} exchange(s)\n",
                                      link->exchanges()));
  } catch (const coupler::PeerError &e) {
    if (comm->me == 0) error->warning(FLERR, fmt::format("Fix hybrid/mpm: {}", e.what()));
  }
  coupler::set_peer(nullptr);
  link.reset();
}

/* ---------------------------------------------------------------------- */

int FixHybridMPM::setmask()
{
  int mask = 0;
  mask |= END_OF_STEP;     // per-step exchange (placeholder for the coupling)
  mask |= POST_RUN;
  return mask;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::init()
{
  if (!atom->sphere_flag) error->all(FLERR, "Fix hybrid/mpm requires atom style sphere");
  if (strcmp(update->unit_style, "si") != 0)
    error->all(FLERR, "Fix hybrid/mpm requires units si (the MPM process works in SI units)");
  if (!link) connect();
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::connect()
{
  coupler::Hello hello;
  coupler::set_text(hello.host, fmt::format("LAMMPS {}", lmp->version));
  coupler::set_text(hello.units, update->unit_style);
  hello.dimension = domain->dimension;
  hello.model = model;
  hello.mpm_every = every;
  hello.cell = cell;
  hello.dt = update->dt;
  hello.reply_timeout = reply_timeout;
  hello.idle_timeout = idle_timeout;
  for (int d = 0; d < 3; d++) {
    hello.box_lo[d] = domain->boxlo[d];
    hello.box_hi[d] = domain->boxhi[d];
  }
  hello.step = update->ntimestep;

  try {
    link = coupler::connect_dem(world, hello);    // collective over world, same outcome on all ranks
  } catch (const coupler::PeerError &e) {
    error->all(FLERR, fmt::format("Fix hybrid/mpm: {}", e.what()));
  }
  coupler::set_peer(link.get());
  if (comm->me == 0)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: handshake ok with the MPM process ({} rank(s)): {}; "
                                    "protocol {}, release {}, cell {}, model {}, exchange every {} step(s)\n",
                                    link->remote_size(), link->peer_info(), coupler::kProtocolVersion,
                                    coupler::release_version(), cell, coupler::model_name(model), every));
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::setup(int /*vflag*/)
{
  // nothing to exchange before the first step yet (phase 1)
}

/* ----------------------------------------------------------------------
   per-step exchange: the leader sends a step header, the MPM process acks.
   Grain data will follow the header in later protocol versions.
------------------------------------------------------------------------- */

void FixHybridMPM::end_of_step()
{
  int status = 0;
  char what[coupler::kTextSize * 2] = {};
  if (comm->me == 0) {
    coupler::StepHeader h;
    h.step = update->ntimestep;
    h.time = update->atime + (update->ntimestep - update->atimestep) * update->dt;
    h.dt = update->dt;
    h.n_grains = 0;
    try {
      const coupler::StepAck ack = link->step(h);
      if (ack.status != 0) {
        status = 2;
        coupler::set_text(what, "the MPM process reported an error at step " + std::to_string(h.step) + ": " +
                                    coupler::get_text(ack.message));
      }
    } catch (const coupler::PeerError &e) {
      status = 1;
      coupler::set_text(what, e.what());
    }
  }
  last_step = update->ntimestep;
  MPI_Bcast(&status, 1, MPI_INT, 0, world);
  if (status != 0) {
    MPI_Bcast(what, sizeof(what), MPI_CHAR, 0, world);
    fail(FLERR, status, what);
  }
  exchanges++;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::fail(const char *file, int line, int status, const char *what)
{
  // a peer that did not answer is presumed hung: the finalize hook aborts the job
  if (status == 1) link->mark_unresponsive();
  else link->mark(coupler::Link::State::kConnected);
  error->all(file, line, fmt::format("Fix hybrid/mpm: {}", what));
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::post_run()
{
  last_step = update->ntimestep;
  if (comm->me == 0 && link)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: {} exchange(s) with the MPM process so far\n", exchanges));
}

/* ---------------------------------------------------------------------- */

double FixHybridMPM::compute_scalar()
{
  return static_cast<double>(exchanges + restart_exchanges);
}

/* ---------------------------------------------------------------------- */

double FixHybridMPM::memory_usage()
{
  return static_cast<double>(sizeof(*this));
}

/* ----------------------------------------------------------------------
   restart: cell size and exchange count only (the MPM state is not saved yet)
------------------------------------------------------------------------- */

void FixHybridMPM::write_restart(FILE *fp)
{
  double list[3];
  int n = 0;
  list[n++] = cell;
  list[n++] = static_cast<double>(exchanges + restart_exchanges);
  list[n++] = static_cast<double>(every);
  if (comm->me == 0) {
    int size = n * sizeof(double);
    fwrite(&size, sizeof(int), 1, fp);
    fwrite(list, sizeof(double), n, fp);
  }
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::restart(char *buf)
{
  double *list = (double *) buf;
  if (list[0] != cell && comm->me == 0)
    error->warning(FLERR, fmt::format("Fix hybrid/mpm: restart file has cell {}, the input says {}; using {}",
                                      list[0], cell, cell));
  restart_exchanges = static_cast<bigint>(list[1]);
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::illegal(const std::string &why)
{
  error->all(FLERR, "Illegal fix hybrid/mpm command: " + why);
}
