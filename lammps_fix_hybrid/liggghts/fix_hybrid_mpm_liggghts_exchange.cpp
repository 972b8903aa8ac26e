/* ----------------------------------------------------------------------
   fix hybrid/mpm for LIGGGHTS 3.8 (hybrid-granular project): the coupling
   exchange (the host's side of coupler/dem_session.hpp), the coupling's
   clock, restart files and the per-atom arrays that travel with the grains
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_liggghts_impl.h"
#include "liggghts_private.h"

#include "atom.h"
#include "comm.h"
#include "error.h"
#include "memory.h"
#include "output.h"
#include "update.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_run_log.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/transfer.hpp"
#include "coupler/zones.hpp"

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::liggghts_hybrid;

// LIGGGHTS 3.8 keeps Output's restart schedule private; the announced time of the next exchange
// must not pass a restart file (its MPM state is that of the restart step)
namespace LAMMPS_NS::liggghts_private {
struct OutputRestartFlag {
  using type = bool Output::*;
  friend type member(OutputRestartFlag);
};
struct OutputNextRestart {
  using type = bigint Output::*;
  friend type member(OutputNextRestart);
};
template struct Reach<OutputRestartFlag, &Output::restart_flag>;
template struct Reach<OutputNextRestart, &Output::next_restart>;
}    // namespace LAMMPS_NS::liggghts_private

/* ----------------------------------------------------------------------
   the coupling's clock (LIGGGHTS's own time at the first run) and steps
------------------------------------------------------------------------- */

double FixHybridMPMLiggghts::dem_time(bigint step) const
{
  return clock->time_of(step, update->atime, update->atimestep, update->dt);
}

coupler::StepHeader FixHybridMPMLiggghts::step_header(int kind) const
{
  coupler::StepHeader h;
  h.step = update->ntimestep;
  h.time = dem_time(update->ntimestep);
  h.dt = update->dt;
  h.kind = kind;
  return h;
}

// the time of the exchange after the one at step `now` if it is certain (the MPM process
// advances to it while LIGGGHTS computes its steps), else -1: the run ends first, a rezone
// (`rezone_next`) or a restart file comes first
double FixHybridMPMLiggghts::next_exchange_time(bigint now, bool rezone_next) const
{
  coupler::ExchangeOutlook o;
  o.now = now, o.last_step = update->laststep, o.every = opt->every;
  o.rezone_next = rezone_next;
  const bigint restart_step = output->*member(liggghts_private::OutputNextRestart{});
  o.restart_file = output->*member(liggghts_private::OutputRestartFlag{}) && restart_step >= o.now && restart_step < o.now + opt->every;
  const bigint next = coupler::next_exchange_step(o);
  return next < 0 ? -1.0 : dem_time(next);
}

void FixHybridMPMLiggghts::exchange()
{
  const double start = MPI_Wtime();
  ledger->close_dem_bracket(grain_energy());
  const coupler::DemGrains g = grains();
  const std::vector<int> index = coupler::coupled_grains(g, [&](const double *xi) { return zone_of(xi); });
  coupler::StepHeader h = step_header(coupler::kStepCouple);
  // every N exchanges, and the run's last: the file holds each run's last coupled state
  const bool run_ends = coupler::last_exchange_of_run(update->ntimestep, opt->every, update->laststep);
  h.output = coupler::output_frame_due(opt->continuum.output_every, exchanges, run_ends) ? 1 : 0;
  h.next_time = next_exchange_time(update->ntimestep, opt->oracle_after(update->ntimestep, update->laststep, converted));
  auto frame = [&] { return coupler::frame_records(grains(), atom->tag, [&](const double *x) { return zone_of(x); }); };
  coupler::StepAck ack;
  coupler::ExchangeTally tally;
  // the session's round trip is the wait for the MPM process (coupler::DemRunLog::charge_exchange)
  const double sent = MPI_Wtime();
  const coupler::StepOutcome mine = coupler::exchange_grains<3>(*session, world, *transfer, g, index, h,
                                                                opt->continuum.pic, support, supported, frame, ack, tally);
  const double replied = MPI_Wtime();
  const coupler::StepOutcome outcome = session->settle(mine);
  coupled_grains = tally.coupled;
  ledger->add_agreement(tally.kicked);
  last_step = update->ntimestep;
  if (!outcome.ok()) fail(outcome.what);
  *last_ack = ack;
  exchanges++;
  link->count_exchange();
  run_log->charge_exchange(start, sent, replied, MPI_Wtime(), tally.applying, tally.framing);
}

/* ----------------------------------------------------------------------
   restart files: the fix's record (coupler::RestartRecord), weight and
   support per atom, and the MPM state the MPM process writes next to
   every restart file after the conversion (keyword mpm_state reads it)
------------------------------------------------------------------------- */

void FixHybridMPMLiggghts::write_restart(FILE *fp)
{
  coupler::RestartRecord r;
  r.cell = opt->cell, r.every = opt->every, r.converted = converted;
  r.exchanges = exchanges + restart_exchanges, r.time = dem_time(update->ntimestep), r.step = update->ntimestep;
  if (comm->me == 0) r.write_file(fp);
}

void FixHybridMPMLiggghts::restart(char *buf)
{
  const coupler::RestartRecord r = coupler::RestartRecord::read(reinterpret_cast<double *>(buf));
  const std::string warning = r.take_cell(opt->cell);
  if (comm->me == 0 && !warning.empty()) error->warning(FLERR, kept(warning));
  restart_exchanges = r.exchanges;
  clock->restore(r, update->dt);
  converted = restored = r.converted;
  if (!r.state_problem(opt->mpm_state_path).empty()) error->all(FLERR, kept(r.state_problem(opt->mpm_state_path)));
}

void FixHybridMPMLiggghts::write_restart_file(char *file)
{
  if (link && converted) state_request(coupler::kStepSave, std::string(file) + ".mpm.h5");
}

void FixHybridMPMLiggghts::state_request(int kind, const std::string &path)
{
  coupler::StepAck ack;
  const coupler::StepOutcome outcome =
      session->settle(session->state_request(step_header(kind), path, exchanges + restart_exchanges, zones, ack));
  if (!outcome.ok()) fail(outcome.what);
  *last_ack = ack;
  say(coupler::state_line(kind, path, ack.points));
}

int FixHybridMPMLiggghts::pack_restart(int i, double *buf) { return arrays().pack_restart(i, buf); }
int FixHybridMPMLiggghts::size_restart(int) { return coupler::GrainArrays::kRestartValues; }
int FixHybridMPMLiggghts::maxsize_restart() { return coupler::GrainArrays::kRestartValues; }

void FixHybridMPMLiggghts::unpack_restart(int nlocal, int nth)
{
  int m = 0;    // this fix's values follow those of the nth - 1 fixes before it, each count first
  for (int k = 0; k < nth; k++) m += static_cast<int>(atom->extra[nlocal][m]);
  arrays().unpack_restart(nlocal, &atom->extra[nlocal][m]);
}

/* ----------------------------------------------------------------------
   per-atom weight, support and stored stress
------------------------------------------------------------------------- */

void FixHybridMPMLiggghts::grow_arrays(int nmax)
{
  weight = memory->grow(weight, nmax, "hybrid/mpm:weight");
  support = memory->grow(support, nmax, 3, "hybrid/mpm:support");
  atom_stress = memory->grow(atom_stress, nmax, 6, "hybrid/mpm:atom_stress");
}

coupler::GrainArrays FixHybridMPMLiggghts::arrays() const
{
  coupler::GrainArrays a;
  a.weight = weight, a.support = support, a.stress = atom_stress;
  return a;
}

void FixHybridMPMLiggghts::copy_arrays(int i, int j, int /*delflag*/) { arrays().copy(i, j); }
void FixHybridMPMLiggghts::set_arrays(int i) { arrays().reset(i); }
int FixHybridMPMLiggghts::pack_exchange(int i, double *buf) { return arrays().pack(i, buf); }
int FixHybridMPMLiggghts::unpack_exchange(int nlocal, double *buf) { return arrays().unpack(nlocal, buf); }
