/* ----------------------------------------------------------------------
   fix hybrid/mpm (hybrid-granular project)

   Couples the grains of LAMMPS to a continuum in the MPM process
   (mpm_solver --coupled) as in docs/design.md section 5:
   - at the first step of the first run, grains in the continuum regions
     become material points that carry exactly their mass, momentum and
     angular momentum (and their Love-Weber stress); grains in hybrid cells
     keep a share `weight` of their mass, the points take the rest;
   - every N steps, coupled grains send their weighted mass and momentum to
     the grid nodes, the MPM process makes both sides agree on a common node
     velocity (momentum moves between the sides, the total is unchanged) and
     the grains take their velocity update.
   Wire protocol: coupler/include/coupler/protocol.hpp. Docs:
   docs/fix_hybrid_mpm.md.
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_impl.h"

#include "atom.h"
#include "comm.h"
#include "compute.h"
#include "error.h"
#include "group.h"
#include "memory.h"
#include "modify.h"
#include "output.h"
#include "timer.h"
#include "update.h"
#include "utils.h"
#include "version.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_run_log.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/dem_timestep.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/rezone_log.hpp"
#include "coupler/tuning.hpp"
#include "coupler/version.hpp"
#include "coupler/zones.hpp"

#include <cstring>
#include <memory>
#include <string>

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::hybrid_mpm;


/* ---------------------------------------------------------------------- */

Fix *FixHybridMPM::creator(LAMMPS *lmp, int narg, char **arg)
{
  return new FixHybridMPM(lmp, narg, arg);
}

/* ---------------------------------------------------------------------- */

FixHybridMPM::FixHybridMPM(LAMMPS *lmp, int narg, char **arg) :
    Fix(lmp, narg, arg), exchanges(0), restart_exchanges(0), last_step(0), weight(nullptr),
    support(nullptr), converted(false), rezone_pending(false), rezone_source(coupler::kZonesOracle),
    oracle_pending(false), new_grain_mask(1), polydispersity(0.0), timestep_checked(false), fewest_steps_warned(coupler::kBig),
    restored(false), state_loaded(false), clock(new coupler::CouplingClock), stress_id(nullptr),
    last_ack(new coupler::StepAck), coupled_grains(0), vector_step(-1), ledger(new coupler::EnergyLedger),
    ledger_started(false), continuum_start(0.0), run_log(new coupler::DemRunLog)
{
  static_assert(sizeof(vector_cache) / sizeof(vector_cache[0]) == coupler::kVecSize, "f_ID[] entries");
  // fix ID group hybrid/mpm keyword value ...: the options (coupler/fix_options.hpp)
  try {
    opt = std::make_unique<coupler::FixOptions>(coupler::parse_fix_options(
        std::vector<std::string>(arg + 3, arg + narg), domain->dimension, atom->ntypes,
        [&](const std::string &rid) { return domain->find_region(rid) >= 0; }));
  } catch (const coupler::OptionError &e) {
    illegal(e.what());
  }

  nevery = 1;               // the support force acts every step; exchanges every `every` steps
  scalar_flag = 1;           // f_ID = number of completed exchanges with the MPM process
  global_freq = 1;           // a count, valid on any step
  extscalar = 0;
  vector_flag = 1;           // f_ID[i]: hybrid counts, residual and totals (docs)
  size_vector = coupler::kVecSize;
  extvector = 0;
  restart_global = 1;
  restart_peratom = 1;
  restart_file = 1;          // the MPM process saves its state next to every restart file
  force_reneighbor = 1;      // rezones delete and create grains at a pre_exchange
  create_attribute = 1;      // grains made from points get a weight and no support (set_arrays)
  next_reneighbor = -1;
  maxexchange = kPerAtomValues;

  grow_arrays(atom->nmax);
  atom->add_callback(Atom::GROW);
  atom->add_callback(Atom::RESTART);
  for (int i = 0; i < atom->nlocal; i++) set_arrays(i);

  check_box();

  // per-atom stress*volume for the Love-Weber stress of new material points
  if (!opt->continuum_regions.empty() || opt->adapt_every > 0) {
    stress_id = utils::strdup(std::string(id) + "_hybrid_stress");
    modify->add_compute(fmt::format("{} all stress/atom NULL virial", stress_id));
  }

  // tell the MPM process at MPI_Finalize if LAMMPS stops on an error (see coupler)
  try {
    coupler::install_dem_finalize_hook(world, "LAMMPS");
  } catch (const std::exception &e) {
    error->all(FLERR, fmt::format("Fix hybrid/mpm: {}", e.what()));
  }
}

/* ---------------------------------------------------------------------- */

FixHybridMPM::~FixHybridMPM()
{
  atom->delete_callback(id, Atom::GROW);
  atom->delete_callback(id, Atom::RESTART);
  memory->destroy(weight);
  memory->destroy(support);
  memory->destroy(atom_stress);
  if (stress_id && modify->find_compute(stress_id) >= 0) modify->delete_compute(stress_id);
  delete[] stress_id;
  if (!link) return;
  // normal end of the coupled run (unfix, clear, end of input): the MPM process exits 0
  std::string warning;
  const std::string line = coupler::finish_coupled_run(*link, last_step, warning);
  if (comm->me == 0 && !line.empty()) utils::logmesg(lmp, line + "\n");
  if (comm->me == 0 && !warning.empty()) error->warning(FLERR, "Fix hybrid/mpm: " + warning);
  session.reset();
  link.reset();
}

/* ---------------------------------------------------------------------- */

int FixHybridMPM::setmask()
{
  int mask = 0;
  mask |= POST_INTEGRATE;  // the zone oracle, before LAMMPS decides on its neighbour lists
  mask |= PRE_EXCHANGE;    // the rezones: the conversion (first step), the oracle's
  mask |= POST_NEIGHBOR;   // atoms were reordered: rebuild the list of supported grains
  mask |= END_OF_STEP;     // the coupling exchange
  mask |= POST_RUN;
  return mask;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::init()
{
  check_box();    // again: change_box may have tilted it since the fix was defined
  if (!atom->sphere_flag) error->all(FLERR, "Fix hybrid/mpm requires atom style sphere");
  if (strcmp(update->unit_style, "si") != 0)
    error->all(FLERR, "Fix hybrid/mpm requires units si (the MPM process works in SI units)");
  if (atom->molecular != Atom::ATOMIC)
    error->all(FLERR, "Fix hybrid/mpm does not support molecular systems (grains only)");
  if (!opt->continuum_regions.empty() || opt->adapt_every > 0) {
    for (int d = 0; d < domain->dimension; d++)
      if (domain->boundary[d][0] != 1 || domain->boundary[d][1] != 1)
        error->all(FLERR, fmt::format("Fix hybrid/mpm with continuum regions or adaptive zones needs fixed boundaries ('f') in "
                                      "x, y{}: the continuum's grid covers the box and has walls at its faces "
                                      "(use boundary f f {})",
                                      domain->dimension == 3 ? ", z" : "", domain->dimension == 3 ? "f" : "p"));
    for (const auto &[kind, ids] : named_regions())
      for (const auto &rid : *ids)
        if (domain->find_region(rid) < 0)
          error->all(FLERR, fmt::format("Fix hybrid/mpm: {} region '{}' no longer exists", kind, rid));
  }
  if (update->whichflag == 1 && strcmp(update->integrate_style, "verlet") != 0)
    error->all(FLERR, "Fix hybrid/mpm needs run_style verlet");
  // the deck's step, before the coupling has changed any grain, is refused only where velocity
  // Verlet cannot integrate the stiffest contact; later runs are checked as the rezones are
  // (their grains may have become lighter)
  if (!converted) {
    std::string why;
    if (dem_steps_per_contact(why) < coupler::kUnstableStepsPerContact)
      error->all(FLERR, fmt::format("Fix hybrid/mpm: the time step {:.6g} s is unstable (checked before the run): {}",
                                    update->dt, why));
  }
  check_dem_timestep("at the start of the run");
}

int FixHybridMPM::modify_param(int narg, char **arg)
{
  // fix_modify ID depth L (band h, surface_packing phi, dilute phi, shear_rate g),
  // fix_modify ID pic x and fix_modify ID rezone_log full|summary|quiet: between runs
  if (narg < 2) return 0;
  try {
    return coupler::modify_option(*opt, arg[0], arg[1], domain->dimension) ? 2 : 0;
  } catch (const coupler::OptionError &e) {
    illegal(e.what());
  }
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::connect()
{
  grain_defaults();
  if (opt->material) apply_material();
  // the grid: the fix line's cell, or one chosen from the grains (and the oracle's defaults from it)
  std::string problem;
  try {
    const std::string grid = coupler::grid_of_run(*opt, domain->dimension, group->count(igroup), domain->boxlo,
                                                  domain->boxhi, problem);
    if (comm->me == 0) utils::logmesg(lmp, fmt::format("fix hybrid/mpm: {}\n", grid));
  } catch (const coupler::OptionError &e) {
    illegal(e.what());
  }
  if (!problem.empty()) error->all(FLERR, "Fix hybrid/mpm: " + problem);
  if (opt->every_auto) {    // every rank resolves it, rank 0 says what it chose
    const std::string interval = coupler::resolve_exchange_interval(*opt, update->dt);
    if (comm->me == 0) utils::logmesg(lmp, fmt::format("fix hybrid/mpm: {}\n", interval));
  }
  // gravity of the grains acts on the continuum too (and sets the energy ledger's potential
  // energy); read once here, checked at every later run's setup
  dem_gravity(opt->continuum.gravity);
  // the agreement's relaxation time: keyword relax, else from the stiffest contact's duration
  std::string why;
  opt->continuum.agreement_time = coupler::agreement_time(opt->relax_time, dem_steps_per_contact(why), update->dt);
  const coupler::Hello hello =
      coupler::make_hello(*opt, fmt::format("LAMMPS {}", lmp->version), update->unit_style, domain->dimension,
                          update->dt, domain->boxlo, domain->boxhi, update->ntimestep, dem_time(), problem);
  if (!problem.empty()) error->all(FLERR, "Fix hybrid/mpm: " + problem);

  try {
    link = coupler::connect_dem(world, hello);    // collective over world, same outcome on all ranks
  } catch (const coupler::PeerError &e) {
    error->all(FLERR, fmt::format("Fix hybrid/mpm: {}", e.what()));
  }
  coupler::set_peer(link.get());
  session = std::make_unique<coupler::DemSession>(*link, world, comm->me);
  if (comm->me == 0)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: handshake ok with the MPM process ({} rank(s)): {}; "
                                    "protocol {}, release {}, cell {}, model {}, exchange every {} step(s)\n",
                                    link->remote_size(), link->peer_info(), coupler::kProtocolVersion,
                                    coupler::release_version(), opt->cell, coupler::model_name(opt->model), opt->every));
  if (comm->me == 0 && opt->continuum.touched_faces != 0) {
    std::string faces;
    for (int f = 0; f < 6; f++)
      if (opt->continuum.touched_faces & coupler::face_bit(f / 2, f % 2))
        faces += std::string(faces.empty() ? "" : " ") + coupler::kFaceNames[f];
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: the continuum may touch the container faces {} (its wall law "
                                    "there); the other faces are discrete boundaries\n", faces));
  }
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::setup(int /*vflag*/)
{
  // the coupling's clock: LAMMPS's own time at the first run, kept by the fix from then on
  // (this LAMMPS does not restore the simulated time from restart files); re-anchored when
  // the time step changes between runs
  clock->start_run(update->ntimestep, update->atime, update->atimestep, update->dt);
  // this run's timing breakdown starts here (LAMMPS's own setup is done; the handshake of the
  // first run is not counted)
  run_log->start_run(update->ntimestep + 1);
  if (!link) connect();
  else check_gravity();
  if (zones.empty()) compute_zones();
  if (restored && !state_loaded) load_mpm_state();
  if (!ledger_started) {
    ledger->start = ledger->energy = grain_energy();
    continuum_start = last_ack->energy;
    ledger_started = true;
    guard = std::make_unique<coupler::EnergyGuard>(coupler::EnergyGuard::over_box(
        opt->energy_guard, opt->continuum.gravity, domain->boxlo, domain->boxhi, domain->dimension));
  }
  // a rezone or oracle left pending at the end of the last run is dropped (its stress is of a
  // step before the commands between the runs); the oracle runs again at its next step
  rezone_pending = oracle_pending = false;
  zone_answer2.reset(), zone_answer3.reset();
  if (!converted && (!opt->continuum_regions.empty() || opt->adapt_every > 0))
    schedule_rezone(opt->continuum_regions.empty() ? coupler::kZonesInitial : coupler::kZonesGiven);
  if (opt->adapt_every > 0) {
    // the Love-Weber stress of the first oracle step needs its per-atom virial
    const bigint first = (update->ntimestep / opt->adapt_every + 1) * opt->adapt_every;
    stress_compute()->addstep(first);
  }
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::end_of_step()
{
  // the continuum's support force on the coupled grains (an acceleration fixed at the last
  // exchange; its impulse is taken from the points over the same interval)
  const double dt = update->dt;
  double **v = atom->v;
  const double *rmass = atom->rmass;
  double kicked = 0.0;    // the kinetic energy the kicks add (energy ledger)
  const double kicks_start = MPI_Wtime();
  for (int i : supported)
    for (int a = 0; a < 3; a++) {
      const double dv = dt * support[i][a];
      kicked += rmass[i] * (v[i][a] + 0.5 * dv) * dv;
      v[i][a] += dv;
    }
  ledger->support_open += kicked;
  run_log->charge(coupler::kTimeApply, MPI_Wtime() - kicks_start);
  const bigint step = update->ntimestep;
  const bool oracle_next = opt->adapt_every > 0 && converted && (step + 1) % opt->adapt_every == 0;
  if (oracle_next) stress_compute()->addstep(step + 1);    // its virial
  // LAMMPS prints its thermo output right after this step's end_of_step (Output::write)
  if (output->next_thermo == step) {
    const double log_start = MPI_Wtime();
    log_rezone_summary(false);
    run_log->charge(coupler::kTimeOutput, MPI_Wtime() - log_start);
  }
  if (step % opt->every != 0) return;
  if (domain->dimension == 2) exchange<2>();
  else exchange<3>();
  // the zone oracle at the next step, before the MPM process advances past this exchange,
  // unless the run ends here: the next run's setup reorders the atoms
  if (opt->oracle_after(step, update->laststep, converted)) schedule_oracle();
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::post_run()
{
  last_step = update->ntimestep;
  const std::string frameless = coupler::frameless_run_warning(opt->continuum.output_every,
                                                               run_log->run_timing().exchanges, update->nsteps, opt->every);
  if (comm->me == 0 && link && !frameless.empty()) error->warning(FLERR, frameless);
  log_rezone_summary(true);
  if (comm->me == 0 && link)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: {} exchange(s) with the MPM process so far\n", exchanges));
  if (link) print_timing_breakdown();
}

/* ----------------------------------------------------------------------
   the rezones since the last thermo output (if any), or the run's
------------------------------------------------------------------------- */

void FixHybridMPM::log_rezone_summary(bool end_of_run)
{
  const std::string line = run_log->summary(end_of_run, opt->rezone_log, update->ntimestep);
  if (comm->me == 0 && !line.empty()) utils::logmesg(lmp, line);
}

/* ----------------------------------------------------------------------
   the run's coupling timing breakdown (coupler::DemRunLog), with LAMMPS's
   own Pair, Neigh, Comm and Modify (the fix's time is part of Modify)
------------------------------------------------------------------------- */

void FixHybridMPM::print_timing_breakdown()
{
  coupler::HostTimers timers;
  timers.pair = timer->get_wall(Timer::PAIR), timers.neigh = timer->get_wall(Timer::NEIGH);
  timers.comm = timer->get_wall(Timer::COMM), timers.modify = timer->get_wall(Timer::MODIFY);
  const std::string block = run_log->timing_breakdown(world, "LAMMPS", timers);
  if (comm->me == 0) utils::logmesg(lmp, block);
}

/* ---------------------------------------------------------------------- */

double FixHybridMPM::compute_scalar()
{
  return static_cast<double>(exchanges + restart_exchanges);
}

/* ----------------------------------------------------------------------
   thermo vector: counts and residual of the last exchange, and the totals
   of grains (their carried mass) plus material points; the continuum's part
   is that of the last exchange, so the totals are exact on exchange steps
------------------------------------------------------------------------- */

double FixHybridMPM::compute_vector(int n)
{
  if (vector_step != update->ntimestep) fill_thermo_vector();
  return vector_cache[n];
}

void FixHybridMPM::fill_thermo_vector()
{
  double totals[7];
  grain_totals(totals);
  ledger_vector(totals, vector_cache);
  // where the coupling's wall time went, the ranks' mean (coupler::ThermoEntry)
  run_log->thermo_times(world, vector_cache);
  vector_step = update->ntimestep;
}

/* ----------------------------------------------------------------------
   the vector's counts and ledger from the grains' totals and the last
   acknowledgement (collective); a run whose coupling made energy stops
   here, at a thermo output or a rezone (keyword energy_guard)
------------------------------------------------------------------------- */

void FixHybridMPM::ledger_vector(const double totals[7], double *out)
{
  const std::string made = coupler::guarded_thermo_vector(*ledger, world, *last_ack, exchanges + restart_exchanges,
                                                          coupled_grains, totals, continuum_start, guard.get(),
                                                          dem_time(), out);
  if (!made.empty()) error->all(FLERR, "Fix hybrid/mpm: " + made);
}

/* ---------------------------------------------------------------------- */

double FixHybridMPM::memory_usage()
{
  return static_cast<double>(sizeof(*this)) + atom->nmax * kPerAtomValues * sizeof(double) + zones.size();
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::illegal(const std::string &why)
{
  error->all(FLERR, "Illegal fix hybrid/mpm command: " + why);
}
