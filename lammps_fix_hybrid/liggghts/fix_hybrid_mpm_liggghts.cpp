/* ----------------------------------------------------------------------
   fix hybrid/mpm for LIGGGHTS 3.8 (hybrid-granular project)

   The LIGGGHTS adapter of the coupling of docs/design.md section 5: the
   same options, handshake, exchange and rezone sequences as the LAMMPS fix
   (coupler/dem_coupling.hpp, coupler/dem_session.hpp), with LIGGGHTS's
   atoms, regions and errors. What it does not do (2D, a calibrated
   material for a contact law other than hooke/stiffness) it refuses with a
   clear error: docs/fix_hybrid_mpm.md, "LIGGGHTS host".
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_liggghts_impl.h"

#include "atom.h"
#include "comm.h"
#include "compute.h"
#include "error.h"
#include "group.h"
#include "memory.h"
#include "modify.h"
#include "output.h"
#include "timer.h"
#include "universe.h"
#include "update.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_run_log.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/dem_timestep.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/protocol.hpp"
#include "coupler/text.hpp"
#include "coupler/transfer.hpp"
#include "coupler/version.hpp"
#include "coupler/zones.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <deque>

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::liggghts_hybrid;

const char *LAMMPS_NS::liggghts_hybrid::kept(const std::string &text)
{
  static std::deque<std::string> messages;
  messages.push_back(text);
  return messages.back().c_str();
}

/* ---------------------------------------------------------------------- */

Fix *FixHybridMPMLiggghts::creator(LAMMPS *lmp, int narg, char **arg)
{
  return new FixHybridMPMLiggghts(lmp, narg, arg);
}

FixHybridMPMLiggghts::FixHybridMPMLiggghts(LAMMPS *lmp, int narg, char **arg) :
    Fix(lmp, narg, arg), last_ack(new coupler::StepAck), ledger(new coupler::EnergyLedger),
    run_log(new coupler::DemRunLog), weight(NULL), support(NULL), atom_stress(NULL), stress_id(NULL), exchanges(0),
    coupled_grains(0), last_step(0), vector_step(-1), converted(false), rezone_pending(false),
    ledger_started(false), oracle_pending(false), timestep_checked(false), restored(false), state_loaded(false), restart_exchanges(0),
    new_grain_mask(1), rezone_source(0), polydispersity(0.0), continuum_start(0.0),
    clock(new coupler::CouplingClock), fewest_steps_warned(coupler::kBig)
{
  static_assert(sizeof(vector_cache) / sizeof(vector_cache[0]) == coupler::kVecSize, "f_ID[] entries");
  for (double &v : vector_cache) v = 0.0;
  if (domain->dimension != 3)
    fail("LIGGGHTS runs are 3D only (its 2D support cannot bin the atoms of a coupled run): use dimension 3, "
         "or lmp_hybrid (LAMMPS) for a 2D deck");
  try {
    opt.reset(new coupler::FixOptions(coupler::parse_fix_options(
        std::vector<std::string>(arg + 3, arg + narg), domain->dimension, atom->ntypes,
        [&](const std::string &rid) { return domain->find_region(rid.c_str()) >= 0; })));
  } catch (const coupler::OptionError &e) {
    error->all(FLERR, kept("Illegal fix hybrid/mpm command: " + std::string(e.what())));
  }
  // what this host does not do yet: refused, not ignored

  nevery = 1;              // the support force acts every step; exchanges every `every` steps
  scalar_flag = 1;         // f_ID = number of completed exchanges
  global_freq = 1;
  extscalar = 0;
  vector_flag = 1;         // f_ID[i]: the same entries as the LAMMPS fix (coupler::ThermoEntry)
  size_vector = coupler::kVecSize;
  extvector = 0;
  force_reneighbor = 1;    // the conversion deletes grains at a pre_exchange
  next_reneighbor = -1;
  create_attribute = 1;    // new atoms get weight 1 and no support (set_arrays)
  restart_global = 1;
  restart_peratom = 1;
  restart_file = 1;        // the MPM process saves its state next to every restart file

  grow_arrays(atom->nmax);
  atom->add_callback(0);    // Atom::grow
  atom->add_callback(1);    // Atom::restart
  for (int i = 0; i < atom->nlocal; i++) set_arrays(i);

  if (domain->triclinic)
    fail("the simulation box is triclinic, but the MPM grid needs an orthogonal box (its cells are axis-aligned)");

  // per-atom stress*volume for the Love-Weber stress of new material points
  if (opt->splits()) {
    const std::string sid = std::string(id) + "_hybrid_stress";
    stress_id = new char[sid.size() + 1];
    std::strcpy(stress_id, sid.c_str());
    char all[] = "all", style[] = "stress/atom", virial[] = "virial";
    char *carg[] = {stress_id, all, style, virial};
    modify->add_compute(4, carg);
  }

  // tell the MPM process at MPI_Finalize if LIGGGHTS stops on an error (see coupler)
  try {
    coupler::install_dem_finalize_hook(world, "LIGGGHTS");
  } catch (const std::exception &e) {
    fail(e.what());
  }
}

FixHybridMPMLiggghts::~FixHybridMPMLiggghts()
{
  if (link) {
    // normal end of the coupled run (unfix, clear, end of input): the MPM process exits 0
    std::string warning;
    say(coupler::finish_coupled_run(*link, last_step, warning));
    if (comm->me == 0 && !warning.empty()) error->warning(FLERR, kept("Fix hybrid/mpm: " + warning));
    session.reset();
    link.reset();
  }
  if (stress_id && modify->find_compute(stress_id) >= 0) modify->delete_compute(stress_id);
  delete[] stress_id;
  atom->delete_callback(id, 0);
  atom->delete_callback(id, 1);
  memory->destroy(weight), memory->destroy(support), memory->destroy(atom_stress);
}

int FixHybridMPMLiggghts::setmask()
{
  int mask = 0;
  mask |= POST_INTEGRATE;  // the zone oracle, before LIGGGHTS decides on its neighbour lists
  mask |= PRE_EXCHANGE;    // the rezones: the conversion (first step), the oracle's
  mask |= PRE_NEIGHBOR;    // atoms were exchanged and sorted: rebuild the list of supported grains
  mask |= END_OF_STEP;     // the coupling exchange
  mask |= POST_RUN;
  return mask;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPMLiggghts::say(const std::string &text) const
{
  if (comm->me != 0 || text.empty()) return;
  const char *end = text.back() == '\n' ? "" : "\n";    // lines of several lines end in one
  if (screen) fprintf(screen, "%s%s", text.c_str(), end);
  if (logfile) fprintf(logfile, "%s%s", text.c_str(), end);
}

void FixHybridMPMLiggghts::fail(const std::string &why) const
{
  error->all(FLERR, kept("Fix hybrid/mpm: " + why));
  std::exit(1);    // Error::all does not return
}

void FixHybridMPMLiggghts::init()
{
  if (!atom->radius_flag || !atom->rmass_flag || !atom->omega_flag)
    fail("the atom style has no per-atom radius, mass and angular velocity: use atom_style granular (or sphere)");
  if (std::strcmp(update->unit_style, "si") != 0) fail("needs units si (the MPM process works in SI units)");
  if (atom->molecular) fail("does not support molecular systems (grains only)");
  if (opt->splits())
    for (int d = 0; d < 3; d++)
      if (domain->boundary[d][0] != 1 || domain->boundary[d][1] != 1)
        fail("with continuum regions or adaptive zones needs fixed boundaries ('f') in x, y, z: the continuum's grid covers the box "
             "and has walls at its faces (use boundary f f f)");
  for (const auto *ids : {&opt->continuum_regions, &opt->discrete_regions})
    for (const auto &rid : *ids)
      if (domain->find_region(rid.c_str()) < 0) fail("region '" + rid + "' of the fix line no longer exists");
  if (update->whichflag == 1 && std::strcmp(update->integrate_style, "verlet") != 0)
    fail("needs run_style verlet");
  check_pair_style();
  check_insertions();
  // the deck's step, before the coupling has changed any grain, is refused only where velocity
  // Verlet cannot integrate the stiffest contact; later runs are checked as the rezones are
  if (!converted) {
    std::string why;
    if (dem_steps_per_contact(why) < coupler::kUnstableStepsPerContact)
      fail("the time step " + coupler::general(update->dt, 6) + " s is unstable (checked before the run): " + why);
  }
  check_dem_timestep("at the start of the run");
}

// LIGGGHTS's particle insertion (fix insert/pack, insert/stream, insert/rate/region) gives a new
// particle the groups all and its own fix's, then calls set_arrays of this fix (weight 1, no
// support): the particles join the coupling if that group is the coupled one. Otherwise they stay
// outside it (uncoupled, not in the totals), which the user is told once per insertion fix.
void FixHybridMPMLiggghts::check_insertions()
{
  for (int f = 0; f < modify->nfix; f++) {
    const Fix *ins = modify->fix[f];
    if (std::strncmp(ins->style, "insert/", 7) != 0 || ((1 | ins->groupbit) & groupbit)) continue;
    if (std::find(insertions_warned.begin(), insertions_warned.end(), ins->id) != insertions_warned.end()) continue;
    insertions_warned.push_back(ins->id);
    if (comm->me == 0)
      error->warning(FLERR, kept(std::string("Fix hybrid/mpm: fix ") + ins->style + " " + ins->id +
                                 " inserts particles into group " + group->names[ins->igroup] +
                                 ", not into the coupled group " + group->names[igroup] +
                                 ": they will not be coupled nor counted in the fix's totals; give the insertion "
                                 "fix the group " + group->names[igroup] + " to couple them"));
  }
}

/* ---------------------------------------------------------------------- */

void FixHybridMPMLiggghts::connect()
{
  const coupler::GroupGrains gg = coupler::group_grains(grains(), atom->type, atom->ntypes, 3, world);
  new_grain_mask = coupler::apply_group_defaults(*opt, gg, groupbit, polydispersity);
  const std::string density = coupler::density_problem(*opt, gg, 3);
  if (!density.empty()) fail(density);
  if (opt->material) apply_material();
  // the grid: the fix line's cell, or one chosen from the grains (and the oracle's defaults from it)
  std::string problem;
  try {
    say("fix hybrid/mpm: " + coupler::grid_of_run(*opt, 3, gg.count, domain->boxlo, domain->boxhi, problem));
  } catch (const coupler::OptionError &e) {
    error->all(FLERR, kept("Illegal fix hybrid/mpm command: " + std::string(e.what())));
  }
  if (!problem.empty()) fail(problem);
  if (opt->every_auto) say("fix hybrid/mpm: " + coupler::resolve_exchange_interval(*opt, update->dt));
  dem_gravity(opt->continuum.gravity);
  // the agreement's relaxation time: keyword relax, else from the stiffest contact's duration
  std::string why;
  opt->continuum.agreement_time = coupler::agreement_time(opt->relax_time, dem_steps_per_contact(why), update->dt);
  // "Version LIGGGHTS-PUBLIC 3.8.0, compiled ..." -> "LIGGGHTS 3.8.0" (the handshake's short text)
  std::string version(universe->version);
  version = version.substr(0, version.find(','));
  const coupler::Hello hello =
      coupler::make_hello(*opt, "LIGGGHTS " + version.substr(version.rfind(' ') + 1), update->unit_style, 3, update->dt,
                          domain->boxlo, domain->boxhi, update->ntimestep, dem_time(update->ntimestep), problem);
  if (!problem.empty()) fail(problem);
  try {
    link = coupler::connect_dem(world, hello);    // collective over world, same outcome on all ranks
  } catch (const coupler::PeerError &e) {
    fail(e.what());
  }
  coupler::set_peer(link.get());
  session.reset(new coupler::DemSession(*link, world, comm->me));
  say("fix hybrid/mpm: handshake ok with the MPM process (" + std::to_string(link->remote_size()) +
      " rank(s)): " + link->peer_info() + "; protocol " + std::to_string(coupler::kProtocolVersion) + ", release " +
      coupler::release_version() + ", host LIGGGHTS, cell " + coupler::shortest(opt->cell) + ", model " +
      coupler::model_name(opt->model) + ", exchange every " + std::to_string(opt->every) + " step(s)");
}

void FixHybridMPMLiggghts::setup(int /*vflag*/)
{
  clock->start_run(update->ntimestep, update->atime, update->atimestep, update->dt);
  // this run's timing breakdown starts here (LIGGGHTS's own setup is done; the handshake of the
  // first run is not counted) and its rezone summaries
  run_log->start_run(update->ntimestep + 1);
  if (!link) connect();
  else {    // gravity was sent at the handshake: it must not change between runs
    double now[3];
    dem_gravity(now);
    const std::string problem = coupler::gravity_change_problem(opt->continuum.gravity, now);
    if (!problem.empty()) error->all(FLERR, kept(problem));
  }
  if (zones.empty()) compute_zones();
  if (restored && !state_loaded) {
    state_request(coupler::kStepLoad, opt->mpm_state_path);
    state_loaded = true;
  }
  if (!ledger_started) {
    ledger->start = ledger->energy = grain_energy();
    continuum_start = last_ack->energy;
    ledger_started = true;
    guard = std::make_unique<coupler::EnergyGuard>(
        coupler::EnergyGuard::over_box(opt->energy_guard, opt->continuum.gravity, domain->boxlo, domain->boxhi, 3));
  }
  // a rezone or oracle left pending at the end of the last run is dropped (its stress is of a step
  // before the commands between the runs); the oracle runs again at its next step
  rezone_pending = oracle_pending = false;
  zone_answer.reset();
  if (!converted && opt->splits())
    schedule_rezone(opt->continuum_regions.empty() ? coupler::kZonesInitial : coupler::kZonesGiven);
  if (opt->adaptive())    // the Love-Weber stress of the first oracle step needs its per-atom virial
    stress_compute()->addstep((update->ntimestep / opt->adapt_every + 1) * opt->adapt_every);
}

/* ----------------------------------------------------------------------
   the support force every step, the exchange every `every` steps
------------------------------------------------------------------------- */

// atoms were exchanged and sorted (LIGGGHTS sorts before pre_neighbor): the supported grains' indices
void FixHybridMPMLiggghts::pre_neighbor()
{
  supported = coupler::supported_grains(support, atom->nlocal);
}

void FixHybridMPMLiggghts::end_of_step()
{
  const double dt = update->dt;
  double **v = atom->v;
  double kicked = 0.0;
  const double kicks_start = MPI_Wtime();
  for (int i : supported)
    for (int a = 0; a < 3; a++) {
      const double dv = dt * support[i][a];
      kicked += atom->rmass[i] * (v[i][a] + 0.5 * dv) * dv;
      v[i][a] += dv;
    }
  ledger->support_open += kicked;
  run_log->charge(coupler::kTimeApply, MPI_Wtime() - kicks_start);
  const bigint step = update->ntimestep;
  if (opt->adaptive() && converted && (step + 1) % opt->adapt_every == 0) stress_compute()->addstep(step + 1);
  // LIGGGHTS prints its thermo output right after this step's end_of_step (Output::write)
  if (output->next_thermo == step) {
    const double log_start = MPI_Wtime();
    log_rezone_summary(false);
    run_log->charge(coupler::kTimeOutput, MPI_Wtime() - log_start);
  }
  if (step % opt->every != 0) return;
  exchange();
  // the zone oracle at the next step, before the MPM process advances past this exchange, unless
  // the run ends here: the next run's setup reorders the atoms
  if (opt->oracle_after(step, update->laststep, converted)) schedule_oracle();
}

void FixHybridMPMLiggghts::post_run()
{
  last_step = update->ntimestep;
  const std::string frameless = coupler::frameless_run_warning(opt->continuum.output_every,
                                                               run_log->run_timing().exchanges, update->nsteps, opt->every);
  if (comm->me == 0 && link && !frameless.empty()) error->warning(FLERR, kept(frameless));
  log_rezone_summary(true);
  if (link) say("fix hybrid/mpm: " + std::to_string(exchanges) + " exchange(s) with the MPM process so far");
  if (link) print_timing_breakdown();
}

// fix_modify ID depth L (band h, surface_packing phi, dilute phi, shear_rate g), fix_modify
// ID pic x and fix_modify ID rezone_log full|summary|quiet: between runs (as on LAMMPS)
int FixHybridMPMLiggghts::modify_param(int narg, char **arg)
{
  if (narg < 2) return 0;
  try {
    return coupler::modify_option(*opt, arg[0], arg[1], 3) ? 2 : 0;
  } catch (const coupler::OptionError &e) {
    error->all(FLERR, kept("Illegal fix hybrid/mpm command: " + std::string(e.what())));
  }
  return 0;
}

/* ----------------------------------------------------------------------
   the rezones since the last thermo output (if any), or the run's; the
   run's coupling timing breakdown (coupler::DemRunLog), with LIGGGHTS's own
   Pair, Neigh, Comm and Other (the fix's time is part of Other)
------------------------------------------------------------------------- */

void FixHybridMPMLiggghts::log_rezone_summary(bool end_of_run)
{
  say(run_log->summary(end_of_run, opt->rezone_log, update->ntimestep));
}

void FixHybridMPMLiggghts::print_timing_breakdown()
{
  // LIGGGHTS 3.8 does not time its fixes: the coupling is part of its "Other" (the loop, stopped
  // before post_run, less the timed sections, as its Finish computes it)
  const double *t = timer->array;
  coupler::HostTimers timers;
  timers.pair = t[TIME_PAIR], timers.neigh = t[TIME_NEIGHBOR], timers.comm = t[TIME_COMM];
  timers.modify = t[TIME_LOOP] - t[TIME_PAIR] - t[TIME_BOND] - t[TIME_KSPACE] - t[TIME_NEIGHBOR] - t[TIME_COMM] -
                  t[TIME_OUTPUT];
  timers.modify_name = "Other";
  say(run_log->timing_breakdown(world, "LIGGGHTS", timers));
}

/* ----------------------------------------------------------------------
   thermo output: f_ID the exchanges, f_ID[i] the LAMMPS fix's entries
   (coupler::ThermoEntry, with the coupling's wall times of coupler::DemRunLog)
------------------------------------------------------------------------- */

double FixHybridMPMLiggghts::compute_scalar()
{
  return static_cast<double>(exchanges + restart_exchanges);
}

double FixHybridMPMLiggghts::compute_vector(int n)
{
  if (vector_step != update->ntimestep) {
    double totals[7];
    grain_totals(totals);
    ledger_vector(totals, vector_cache);
    run_log->thermo_times(world, vector_cache);    // where the coupling's wall time went
    vector_step = update->ntimestep;
  }
  return vector_cache[n];
}

// the vector's counts and ledger (collective); a run whose coupling made energy stops here, at a
// thermo output or a rezone (keyword energy_guard)
void FixHybridMPMLiggghts::ledger_vector(const double totals[7], double *out)
{
  const std::string made = coupler::guarded_thermo_vector(*ledger, world, *last_ack, exchanges + restart_exchanges,
                                                          coupled_grains, totals, continuum_start, guard.get(),
                                                          dem_time(update->ntimestep), out);
  if (!made.empty()) fail(made);
}

double FixHybridMPMLiggghts::memory_usage()
{
  return static_cast<double>(sizeof(*this)) + atom->nmax * coupler::GrainArrays::kValues * sizeof(double) + zones.size();
}
