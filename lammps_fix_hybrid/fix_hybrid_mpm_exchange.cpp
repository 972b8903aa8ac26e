/* ----------------------------------------------------------------------
   fix hybrid/mpm (hybrid-granular project): the coupling exchange (the
   host's side of coupler/dem_session.hpp), the coupling's clock, restart
   files and the per-atom arrays that travel with the grains
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_impl.h"

#include <cmath>

#include "atom.h"
#include "comm.h"
#include "error.h"
#include "memory.h"
#include "output.h"
#include "update.h"
#include "utils.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_run_log.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/zones.hpp"

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::hybrid_mpm;


/* ----------------------------------------------------------------------
   time of the exchange after the one at step `now` if it is certain, else
   -1: the MPM process then advances to it while LAMMPS computes its steps.
   Not certain: the run ends first, a rezone follows (`rezone_next`), or a
   restart file is written before it (the MPM state must then be that of
   this exchange)
------------------------------------------------------------------------- */

double FixHybridMPM::next_exchange_time(bigint now, bool rezone_next) const
{
  coupler::ExchangeOutlook o;
  o.now = now, o.last_step = update->laststep, o.every = opt->every;
  o.rezone_next = rezone_next;
  o.restart_file = output->restart_flag && output->next_restart >= o.now && output->next_restart < o.now + opt->every;
  const bigint next = coupler::next_exchange_step(o);
  return next < 0 ? -1.0 : dem_time(next);
}

coupler::StepHeader FixHybridMPM::step_header(int kind) const
{
  coupler::StepHeader h;
  h.step = update->ntimestep;
  h.time = dem_time();
  h.dt = update->dt;
  h.kind = kind;
  return h;
}

double FixHybridMPM::dem_time() const
{
  return dem_time(update->ntimestep);
}

// the same expression for every step, so a time announced in advance is the same bits
// as the time of that step when it comes
double FixHybridMPM::dem_time(bigint step) const
{
  return clock->time_of(step, update->atime, update->atimestep, update->dt);
}

/* ----------------------------------------------------------------------
   one coupling exchange: coupled grains' weighted mass and momentum per node
   go to the MPM process, the agreed node velocities come back
------------------------------------------------------------------------- */

/* ----------------------------------------------------------------------
   every grain of the group must have a finite position, velocity and mass
   before it is mapped to grid cells and nodes (a NaN there indexed the grid
   out of range); collective, an error naming the first bad atom
------------------------------------------------------------------------- */

void FixHybridMPM::check_finite_grains(const std::string &when)
{
  double **x = atom->x, **v = atom->v;
  const double *rmass = atom->rmass;
  const int *mask = atom->mask;
  const tagint *tag = atom->tag;
  tagint bad = 0;
  for (int i = 0; i < atom->nlocal && bad == 0; i++) {
    if (!(mask[i] & groupbit)) continue;
    bool ok = std::isfinite(rmass[i]);
    for (int a = 0; a < 3; a++) ok = ok && std::isfinite(x[i][a]) && std::isfinite(v[i][a]);
    if (!ok) bad = tag[i];
  }
  tagint first = 0;
  MPI_Allreduce(&bad, &first, 1, MPI_LMP_TAGINT, MPI_MAX, world);
  if (first != 0)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: atom {} has a non-finite (NaN or inf) position, velocity or "
                                  "mass at step {} ({}): the DEM run went unstable (check the time step) or the "
                                  "input set a NaN",
                                  first, update->ntimestep, when));
}

template <int D>
void FixHybridMPM::exchange()
{
  const double start = MPI_Wtime();
  check_finite_grains("before the exchange");
  close_dem_bracket();
  // coupled grains: hybrid grains, and any grain of the group inside a hybrid or continuum cell
  const coupler::DemGrains g = grains();
  const std::vector<int> index = coupler::coupled_grains(g, [&](const double *xi) { return zone_of(xi); });

  coupler::StepHeader h = step_header(coupler::kStepCouple);
  // every N exchanges, and the run's last: the file holds each run's last coupled state
  const bool run_ends = coupler::last_exchange_of_run(update->ntimestep, opt->every, update->laststep);
  h.output = coupler::output_frame_due(opt->continuum.output_every, exchanges, run_ends) ? 1 : 0;
  h.next_time = next_exchange_time(update->ntimestep, opt->oracle_after(update->ntimestep, update->laststep, converted));
  coupler::StepAck ack;
  coupler::ExchangeTally tally;
  // the session's round trip is the wait for the MPM process (coupler::DemRunLog::charge_exchange)
  const double sent = MPI_Wtime();
  const coupler::StepOutcome outcome =
      coupler::exchange_grains<D>(*session, world, transfer<D>(), g, index, h, opt->continuum.pic, support, supported,
                                  [&] { return frame_grains(); }, ack, tally);
  const double replied = MPI_Wtime();
  coupled_grains = tally.coupled;
  ledger->add_agreement(tally.kicked);
  last_step = update->ntimestep;
  check(outcome);

  *last_ack = ack;
  exchanges++;
  link->count_exchange();
  run_log->charge_exchange(start, sent, replied, MPI_Wtime(), tally.applying, tally.framing);
}

/* ----------------------------------------------------------------------
   local atoms with a support acceleration, after atoms were reordered
------------------------------------------------------------------------- */

void FixHybridMPM::collect_supported()
{
  supported = coupler::supported_grains(support, atom->nlocal);
}

void FixHybridMPM::setup_post_neighbor()
{
  collect_supported();
}

void FixHybridMPM::post_neighbor()
{
  collect_supported();
}

/* ----------------------------------------------------------------------
   this rank's grains for an output frame of the MPM process's file
------------------------------------------------------------------------- */

std::vector<coupler::GrainRecord> FixHybridMPM::frame_grains() const
{
  return coupler::frame_records(grains(), atom->tag, [&](const double *x) { return zone_of(x); });
}

/* ----------------------------------------------------------------------
   collective outcome of a step with the MPM process: any rank's failure
   stops all ranks with the message of the lowest failing rank
------------------------------------------------------------------------- */

void FixHybridMPM::check(const coupler::StepOutcome &mine)
{
  const coupler::StepOutcome all = session->settle(mine);
  if (!all.ok()) error->all(FLERR, "Fix hybrid/mpm: " + all.what);
}

/* ----------------------------------------------------------------------
   restart: settings, exchange count and whether the conversion happened
   (the MPM state itself is not saved yet)
------------------------------------------------------------------------- */

void FixHybridMPM::write_restart(FILE *fp)
{
  coupler::RestartRecord r;
  r.cell = opt->cell, r.exchanges = exchanges + restart_exchanges, r.every = opt->every;
  r.converted = converted, r.time = dem_time(), r.step = update->ntimestep;
  if (comm->me == 0) r.write_file(fp);
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::restart(char *buf)
{
  const coupler::RestartRecord r = coupler::RestartRecord::read(reinterpret_cast<double *>(buf));
  const std::string warning = r.take_cell(opt->cell);
  if (!warning.empty() && comm->me == 0) error->warning(FLERR, warning);
  restart_exchanges = r.exchanges;
  clock->restore(r, update->dt);
  // grains already became points: the MPM process continues from the state saved with the file
  converted = restored = r.converted;
  const std::string problem = r.state_problem(opt->mpm_state_path);
  if (!problem.empty()) error->all(FLERR, problem);
}

/* ----------------------------------------------------------------------
   the MPM process writes its state next to every LAMMPS restart file
------------------------------------------------------------------------- */

void FixHybridMPM::write_restart_file(const char *file)
{
  if (!link || !converted) return;
  state_request(coupler::kStepSave, std::string(file) + ".mpm.h5");
}

void FixHybridMPM::load_mpm_state()
{
  state_request(coupler::kStepLoad, opt->mpm_state_path);
  state_loaded = true;
}

void FixHybridMPM::state_request(int kind, const std::string &path)
{
  coupler::StepAck ack;
  check(session->state_request(step_header(kind), path, exchanges + restart_exchanges, zones, ack));
  *last_ack = ack;
  if (comm->me == 0) utils::logmesg(lmp, coupler::state_line(kind, path, ack.points) + "\n");
}

/* ----------------------------------------------------------------------
   per-atom weight, support and stored stress: allocate, copy, exchange
   with atoms; restart files hold weight and support only (a rezone left
   pending at the end of a run is dropped, see setup)
------------------------------------------------------------------------- */

void FixHybridMPM::grow_arrays(int nmax)
{
  memory->grow(weight, nmax, "hybrid/mpm:weight");
  memory->grow(support, nmax, 3, "hybrid/mpm:support");
  memory->grow(atom_stress, nmax, 6, "hybrid/mpm:atom_stress");
}

void FixHybridMPM::copy_arrays(int i, int j, int /*delflag*/)
{
  arrays().copy(i, j);
}

void FixHybridMPM::set_arrays(int i)
{
  arrays().reset(i);
}

int FixHybridMPM::pack_exchange(int i, double *buf)
{
  return arrays().pack(i, buf);
}

int FixHybridMPM::unpack_exchange(int nlocal, double *buf)
{
  return arrays().unpack(nlocal, buf);
}

coupler::GrainArrays FixHybridMPM::arrays() const
{
  coupler::GrainArrays a;
  a.weight = weight, a.support = support, a.stress = atom_stress;
  return a;
}

int FixHybridMPM::pack_restart(int i, double *buf)
{
  return arrays().pack_restart(i, buf);
}

void FixHybridMPM::unpack_restart(int nlocal, int nth)
{
  double **extra = atom->extra;
  int m = 0;
  for (int i = 0; i < nth; i++) m += static_cast<int>(extra[nlocal][m]);
  arrays().unpack_restart(nlocal, &extra[nlocal][m]);
}

int FixHybridMPM::size_restart(int /*nlocal*/)
{
  return coupler::GrainArrays::kRestartValues;
}

int FixHybridMPM::maxsize_restart()
{
  return coupler::GrainArrays::kRestartValues;
}

// end_of_step (fix_hybrid_mpm.cpp) exchanges in 2D and 3D
template void FixHybridMPM::exchange<2>();
template void FixHybridMPM::exchange<3>();
