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

#include "fix_hybrid_mpm.h"

#include "atom.h"
#include "atom_vec.h"
#include "comm.h"
#include "compute.h"
#include "domain.h"
#include "error.h"
#include "force.h"
#include "group.h"
#include "math_const.h"
#include "memory.h"
#include "modify.h"
#include "output.h"
#include "pair.h"
#include "region.h"
#include "update.h"
#include "utils.h"
#include "version.h"

#include "GRANULAR/pair_gran_hooke_history.h"

#include "coupler/conversion.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_rezone.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/dem_timestep.hpp"
#include "coupler/enrichment.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/material_file.hpp"
#include "coupler/oracle.hpp"
#include "coupler/protocol.hpp"
#include "coupler/rezone_log.hpp"
#include "coupler/transfer.hpp"
#include "coupler/tuning.hpp"
#include "coupler/version.hpp"
#include "coupler/zones.hpp"

#include <memory>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <string>

using namespace LAMMPS_NS;
using namespace FixConst;
using MathConst::MY_PI;

static constexpr double BIG = 1.0e20;
// per-atom values that travel with a grain (pack_exchange): weight, support (3), stored stress (6)
static constexpr int kPerAtomValues = 1 + 3 + 6;
using coupler::kSmallestCellInGrains;    // tuned constants: coupler/tuning.hpp
using coupler::kSmallestShrink;

namespace {

// The contact constants of LAMMPS's Hookean granular pair styles are protected members; a type
// derived from the pair may name them (it is never instantiated, so nothing of the pair's code
// is linked: the plugin loads into a LAMMPS whatever its packages).
struct HookeanConstants : PairGranHookeHistory {
  static coupler::HookeanContact of(const Pair *pair)
  {
    const auto *p = static_cast<const PairGranHookeHistory *>(pair);
    coupler::HookeanContact c;
    c.kn = p->*(&HookeanConstants::kn);
    c.kt = p->*(&HookeanConstants::kt);
    c.gamman = p->*(&HookeanConstants::gamman);
    return c;
  }
  static double tangential_damping(const Pair *pair)
  {
    return static_cast<const PairGranHookeHistory *>(pair)->*(&HookeanConstants::gammat);
  }
  static double friction(const Pair *pair)
  {
    return static_cast<const PairGranHookeHistory *>(pair)->*(&HookeanConstants::xmu);
  }
};


template <int D>
using Vec = Eigen::Matrix<double, D, 1>;

template <int D>
coupler::GridGeometry<D> box_grid(const Domain *domain, double cell)
{
  return coupler::padded_grid<D>(Eigen::Map<const Vec<D>>(domain->boxlo), Eigen::Map<const Vec<D>>(domain->boxhi),
                                 cell);
}

}    // namespace

/* ---------------------------------------------------------------------- */

Fix *FixHybridMPM::creator(LAMMPS *lmp, int narg, char **arg)
{
  return new FixHybridMPM(lmp, narg, arg);
}

/* ---------------------------------------------------------------------- */

FixHybridMPM::FixHybridMPM(LAMMPS *lmp, int narg, char **arg) :
    Fix(lmp, narg, arg), exchanges(0), restart_exchanges(0), last_step(0), last_output_step(-1), weight(nullptr),
    support(nullptr), converted(false), rezone_pending(false), rezone_source(coupler::kZonesOracle),
    new_grain_mask(1), polydispersity(0.0), interval_rezones(new coupler::RezoneTally),
    run_rezones(new coupler::RezoneTally), timestep_checked(false), fewest_steps_warned(BIG), restored(false),
    state_loaded(false), clock_time(0.0), clock_step(-1), clock_dt(0.0), stress_id(nullptr),
    last_ack(new coupler::StepAck), coupled_grains(0), vector_step(-1), ledger(new coupler::EnergyLedger), ledger_started(false), continuum_start(0.0)
{
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
    coupler::install_dem_finalize_hook(world);
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
  try {
    link->finish(last_step);
    if (comm->me == 0)
      utils::logmesg(lmp, fmt::format("fix hybrid/mpm: finished the coupled run after {} exchange(s)\n",
                                      link->exchanges()));
  } catch (const coupler::PeerError &e) {
    if (comm->me == 0) error->warning(FLERR, fmt::format("Fix hybrid/mpm: {}", e.what()));
  }
  coupler::set_peer(nullptr);
  session.reset();
  link.reset();
}

/* ----------------------------------------------------------------------
   the MPM grid, the zone cells and the continuum's walls are axis-aligned
   boxes over [boxlo, boxhi]: a tilted box has no such grid
------------------------------------------------------------------------- */

void FixHybridMPM::check_box() const
{
  if (domain->triclinic)
    error->all(FLERR, "Fix hybrid/mpm: the simulation box is triclinic, but the MPM grid needs an orthogonal "
                      "box (its cells are axis-aligned); use an orthogonal box (change_box all ortho)");
}

/* ----------------------------------------------------------------------
   gravity: sent to the MPM process once, at the handshake, and part of the
   energy ledger's potential energy from then on, so it must not change
------------------------------------------------------------------------- */

void FixHybridMPM::dem_gravity(double *g) const
{
  for (int d = 0; d < 3; d++) g[d] = 0.0;
  for (int i = 0; i < modify->nfix; i++)
    if (utils::strmatch(modify->fix[i]->style, "^gravity")) {
      int dim = 0;
      const auto *gi = static_cast<const double *>(modify->fix[i]->extract("gvec", dim));
      if (gi)
        for (int d = 0; d < 3; d++) g[d] += gi[d];
    }
}

void FixHybridMPM::check_gravity() const
{
  double now[3];
  dem_gravity(now);
  const double *then = opt->continuum.gravity;
  const double scale = std::max(std::sqrt(then[0] * then[0] + then[1] * then[1] + then[2] * then[2]),
                                std::sqrt(now[0] * now[0] + now[1] * now[1] + now[2] * now[2]));
  bool same = true;
  for (int d = 0; d < 3; d++) same = same && std::fabs(now[d] - then[d]) <= 1e-12 * scale;    // round-off only
  if (!same)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: gravity changed since the coupled run started: ({}, {}, {}) m/s^2 "
                                  "then, ({}, {}, {}) now. The MPM process keeps the gravity of the handshake (and "
                                  "the energy ledger its potential energy): keep the fix gravity commands unchanged "
                                  "while fix hybrid/mpm is defined",
                                  then[0], then[1], then[2], now[0], now[1], now[2]));
}

/* ----------------------------------------------------------------------
   the compute stress/atom the fix made; a user may have deleted it
------------------------------------------------------------------------- */

Compute *FixHybridMPM::stress_compute() const
{
  const int icompute = stress_id ? modify->find_compute(stress_id) : -1;
  if (icompute < 0)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: its compute {} (stress/atom, for the stress of new material "
                                  "points) no longer exists: do not uncompute it while the fix is defined",
                                  stress_id ? stress_id : "ID_hybrid_stress"));
  return modify->compute[icompute];
}

/* ---------------------------------------------------------------------- */

int FixHybridMPM::setmask()
{
  int mask = 0;
  mask |= PRE_EXCHANGE;    // conversion of the continuum regions' grains (first step)
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

/* ----------------------------------------------------------------------
   grains the coupling made or rescaled may be lighter than any before, and
   their contacts faster: the user is told (again whenever the figure drops
   by another 10 %). Neither stopping nor shortening the step helps yet: both
   end runs the rezones' mass drift would otherwise finish (docs, "DEM time step")
------------------------------------------------------------------------- */

void FixHybridMPM::check_dem_timestep(const std::string &when)
{
  std::string why;
  const double steps = dem_steps_per_contact(why);
  if (steps >= opt->warn_steps_per_contact || steps >= 0.9 * fewest_steps_warned) return;
  fewest_steps_warned = steps;
  if (comm->me == 0)
    error->warning(FLERR, fmt::format("Fix hybrid/mpm: the time step {:.6g} s resolves the contacts poorly {}: {}",
                                      update->dt, when, why));
}

/* ----------------------------------------------------------------------
   the DEM side's stability (docs/design.md section 3): steps per contact of the
   stiffest pair, the two lightest grains (infinite for pair styles it cannot
   check); `why` explains it and names the safe step. Grains in hybrid cells
   carry only their share `weight` of their mass and vibrate faster, so while
   the coupling may split grains the lightest grain counts at that share.
   Logs the figure at the first check.
------------------------------------------------------------------------- */

double FixHybridMPM::dem_steps_per_contact(std::string &why)
{
  Pair *pair = force->pair_match("^gran/hooke", 0);
  if (!pair) {
    if (force->pair && !timestep_checked && comm->me == 0)
      error->warning(FLERR, fmt::format("Fix hybrid/mpm checks the DEM time step for pair styles gran/hooke and "
                                        "gran/hooke/history only; check it yourself for pair style {} "
                                        "(at least {:g} steps per contact)", force->pair_style,
                                        coupler::kSafeStepsPerContact));
    timestep_checked = true;
    return BIG;
  }
  const bool splits = !opt->continuum_regions.empty() || opt->adapt_every > 0;
  double local = BIG, lightest = BIG;
  for (int i = 0; i < atom->nlocal; i++) {
    local = std::min(local, atom->rmass[i]);
    if (splits && (atom->mask[i] & groupbit))
      local = std::min(local, atom->rmass[i] / weight[i] * opt->continuum.grain_weight);
  }
  MPI_Allreduce(&local, &lightest, 1, MPI_DOUBLE, MPI_MIN, world);
  if (lightest >= BIG) return BIG;

  coupler::HookeanContact contact = HookeanConstants::of(pair);
  contact.m_eff = 0.5 * lightest;
  contact.inertia = opt->inertia;
  const double tc = coupler::contact_time(contact), steps = tc / update->dt;
  const std::string what =
      fmt::format("the stiffest contact (pair style {}: kn = {:.6g} N/m, kt = {:.6g} N/m, gamma_n = {:.6g} 1/s; "
                  "lightest grains {:.6g} kg{}) lasts tc = {:.6g} s",
                  force->pair_style, contact.kn, contact.kt, contact.gamman, lightest,
                  splits ? ", at their share in hybrid cells" : "", tc);
  if (!timestep_checked && comm->me == 0)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: DEM time step {:.6g} s: {}, {:.3g} steps per contact\n",
                                    update->dt, what, steps));
  timestep_checked = true;
  why = fmt::format("{}, and {:.3g} steps per contact ({}) {}. Use timestep {:.6g} (tc/{:g}) or less", what, steps,
                    steps < coupler::kUnstableStepsPerContact ? "fewer than pi/2"
                                                              : fmt::format("fewer than {:g}", opt->warn_steps_per_contact),
                    steps < coupler::kUnstableStepsPerContact
                        ? "make velocity Verlet unstable"
                        : "resolve it poorly (a collision's energy balance drifts; keyword steps_per_contact sets "
                          "this threshold)",
                    tc / coupler::kSafeStepsPerContact, coupler::kSafeStepsPerContact);
  return steps;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::grain_defaults()
{
  // mu(I) needs the grain size and solid density; unless given, take them from the grains
  double sums[3] = {0, 0, 0}, all[3];
  const bool two_d = domain->dimension == 2;
  for (int i = 0; i < atom->nlocal; i++) {
    if (!(atom->mask[i] & groupbit)) continue;
    const double r = atom->radius[i];
    const double volume = two_d ? MY_PI * r * r : 4.0 / 3.0 * MY_PI * r * r * r;
    sums[0] += 2.0 * r;
    sums[1] += atom->rmass[i] / std::max(weight[i], 1e-300);
    sums[2] += volume;
  }
  MPI_Allreduce(sums, all, 3, MPI_DOUBLE, MPI_SUM, world);
  const bigint n = group->count(igroup);
  if (n > 0 && !opt->diameter_given) opt->continuum.grain_diameter = all[0] / n;
  if (all[2] > 0 && !opt->density_given) opt->continuum.grain_density = all[1] / all[2];

  // grains made from points: the size spread, type and groups of the grains there are
  double range[2] = {-BIG, -BIG}, range_all[2];    // -min diameter, max diameter
  int common_mask = ~0, all_mask = ~0, smallest_type = atom->ntypes + 1, type_all = 0;
  for (int i = 0; i < atom->nlocal; i++) {
    if (!(atom->mask[i] & groupbit)) continue;
    range[0] = std::max(range[0], -2.0 * atom->radius[i]);
    range[1] = std::max(range[1], 2.0 * atom->radius[i]);
    common_mask &= atom->mask[i];
    smallest_type = std::min(smallest_type, atom->type[i]);
  }
  MPI_Allreduce(range, range_all, 2, MPI_DOUBLE, MPI_MAX, world);
  MPI_Allreduce(&common_mask, &all_mask, 1, MPI_INT, MPI_BAND, world);
  MPI_Allreduce(&smallest_type, &type_all, 1, MPI_INT, MPI_MIN, world);
  if (n > 0) {
    const double dmin = -range_all[0], dmax = range_all[1];
    // the template's radii are uniform in mean (1 +- p); it needs p < 0.5
    polydispersity = std::min(0.45, (dmax - dmin) / (dmax + dmin));
    new_grain_mask = all_mask | 1 | groupbit;
    if (opt->grain_type == 0) opt->grain_type = type_all;
  } else {
    new_grain_mask = 1 | groupbit;
    if (opt->grain_type == 0) opt->grain_type = 1;
  }
}

/* ----------------------------------------------------------------------
   the continuum's constants from the calibrated material (keyword material):
   only for the contact law it was calibrated with
------------------------------------------------------------------------- */

void FixHybridMPM::apply_material()
{
  const coupler::CalibratedMaterial &m = *opt->material;
  Pair *pair = force->pair_match("^gran/hooke", 0);
  if (!pair)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: material {} was calibrated for pair style {}, the deck uses {}; "
                                  "measure the continuum's constants for this contact law (docs/design.md section 4.6)",
                                  m.path, m.pair, force->pair_style ? force->pair_style : "none"));
  const coupler::HookeanContact hooke = HookeanConstants::of(pair);
  coupler::DeckContact deck;
  deck.dimension = domain->dimension;
  deck.friction = HookeanConstants::friction(pair);
  deck.kn = hooke.kn;
  deck.kt = hooke.kt;
  deck.gamman = hooke.gamman;
  deck.gammat = HookeanConstants::tangential_damping(pair);
  const double r = 0.5 * opt->continuum.grain_diameter;
  deck.mean_mass = opt->continuum.grain_density * (domain->dimension == 2 ? MY_PI * r * r : 4.0 / 3.0 * MY_PI * r * r * r);
  const std::string mismatch = coupler::contact_mismatch(m, deck);
  if (!mismatch.empty())
    error->all(FLERR, fmt::format("Fix hybrid/mpm: material {} was calibrated for another contact law ({}); "
                                  "measure the continuum's constants for this one (docs/design.md section 4.6)",
                                  m.path, mismatch));
  coupler::apply_material(m, hooke.kn, opt->continuum.grain_diameter, opt->continuum);
  if (comm->me == 0)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: material {} ({}): Young's modulus {:.6g} Pa, Poisson's ratio "
                                    "{:.3g}, friction angle {:.4g} deg, mu_s {:.4g}, mu_2 {:.4g}, I0 {:.4g}, "
                                    "critical packing {:.4g}\n",
                                    m.name, m.path, opt->continuum.youngs_modulus, opt->continuum.poisson_ratio,
                                    opt->continuum.friction_angle_deg, opt->continuum.mu_s, opt->continuum.mu_2, opt->continuum.I0,
                                    opt->continuum.critical_packing));
}

int FixHybridMPM::modify_param(int narg, char **arg)
{
  // fix_modify ID depth L (band h, surface_packing phi, dilute phi, shear_rate g), and
  // fix_modify ID rezone_log full|summary|quiet: between runs
  if (narg < 2) return 0;
  if (strcmp(arg[0], "rezone_log") == 0) {
    set_rezone_log(arg[1]);
    return 2;
  }
  try {
    if (!coupler::set_oracle_option(opt->oracle, arg[0], arg[1])) return 0;
    coupler::check_oracle_options(*opt, domain->dimension);
  } catch (const coupler::OptionError &e) {
    illegal(e.what());
  }
  return 2;
}

void FixHybridMPM::set_rezone_log(const std::string &value)
{
  try {
    opt->rezone_log = coupler::rezone_log_option(value);
  } catch (const coupler::OptionError &e) {
    illegal(e.what());
  }
}

/* ----------------------------------------------------------------------
   the rezone log (keyword rezone_log): every rezone is counted in the
   summaries; its own two lines are printed in the full log, and in the
   default one for the conversion at the start (its zones are not the oracle's)
------------------------------------------------------------------------- */

void FixHybridMPM::log_rezone(const coupler::RezoneReport &report, int source, const double *before,
                              const double *after)
{
  interval_rezones->add(report);
  run_rezones->add(report);
  const bool conversion = source != coupler::kZonesOracle;
  if (comm->me != 0) return;
  if (opt->rezone_log == coupler::RezoneLog::kFull || (opt->rezone_log == coupler::RezoneLog::kSummary && conversion)) {
    utils::logmesg(lmp, coupler::rezone_line(report) + "\n");
    utils::logmesg(lmp, coupler::rezone_totals_line(report.step, before, after) + "\n");
  }
}

// at thermo output: the rezones since the last one (if any); at the end of a run: its rezones
void FixHybridMPM::log_rezone_summary(bool end_of_run)
{
  coupler::RezoneTally &tally = end_of_run ? *run_rezones : *interval_rezones;
  const bool shown = end_of_run || opt->rezone_log != coupler::RezoneLog::kQuiet;
  if (comm->me == 0 && shown && tally.rezones() > 0)
    utils::logmesg(lmp, tally.summary_line(end_of_run ? coupler::kSummaryRun : coupler::kSummaryInterval,
                                           update->ntimestep) + "\n");
  tally.restart(update->ntimestep + 1);
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::connect()
{
  grain_defaults();
  if (opt->material) apply_material();
  // With cells under 2 grain diameters the oracle's packing fraction per cell counts one or two
  // grains and a cell's rests land on a few points: a published 2D collapse with 1.74 d cells
  // went non-finite as its continuum shrank (issue 14), while the same scene ran with 5 d cells.
  // (2 % slack: a deck's cell of 2 nominal diameters passes whatever its grains' sampled mean)
  if (opt->adapt_every > 0 && opt->cell < 0.98 * kSmallestCellInGrains * opt->continuum.grain_diameter)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: cell {} is under {} grain diameters (mean diameter {:.4g}): adaptive "
                                  "zones need cells that hold several grains. Use cell {:.4g} or more",
                                  opt->cell, kSmallestCellInGrains, opt->continuum.grain_diameter,
                                  kSmallestCellInGrains * opt->continuum.grain_diameter));
  coupler::Hello hello;
  coupler::set_text(hello.host, fmt::format("LAMMPS {}", lmp->version));
  coupler::set_text(hello.units, update->unit_style);
  hello.dimension = domain->dimension;
  hello.model = opt->model;
  hello.mpm_every = opt->every;
  hello.cell = opt->cell;
  hello.dt = update->dt;
  hello.reply_timeout = opt->reply_timeout;
  hello.idle_timeout = opt->idle_timeout;
  for (int d = 0; d < 3; d++) {
    hello.box_lo[d] = domain->boxlo[d];
    hello.box_hi[d] = domain->boxhi[d];
  }
  hello.step = update->ntimestep;
  hello.time = dem_time();
  // gravity of the grains acts on the continuum too (and sets the energy ledger's potential
  // energy); read once here, checked at every later run's setup
  dem_gravity(opt->continuum.gravity);
  // the agreement's relaxation time: half the stiffest contact's duration, the time over which
  // grains in contact equalise their velocities (10 steps where the contact time is unknown)
  if (opt->relax_time < 0.0) {
    std::string why;
    const double steps = dem_steps_per_contact(why);
    opt->continuum.agreement_time = 0.5 * (steps < BIG ? steps : 20.0) * update->dt;
  } else opt->continuum.agreement_time = opt->relax_time;
  hello.continuum = opt->continuum;
  for (int d = 0; d < 3; d++)
    for (int side = 0; side < 2; side++) {
      const double v = container_edge(d, side);
      if (v < domain->boxlo[d] || v > domain->boxhi[d])
        error->all(FLERR, fmt::format("Fix hybrid/mpm: container {} {} = {} lies outside the box ({} to {})",
                                      "xyz"[d], side ? "hi" : "lo", v, domain->boxlo[d], domain->boxhi[d]));
      (side ? hello.continuum.container_hi : hello.continuum.container_lo)[d] = v;
    }

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

/* ----------------------------------------------------------------------
   zone of every grid cell from the continuum regions (same on all ranks)
------------------------------------------------------------------------- */

void FixHybridMPM::compute_zones()
{
  const std::vector<Region *> regions = prematched(opt->continuum_regions);
  auto inside = [&](const auto &x) { return in_any(regions, x[0], x[1], x.size() == 3 ? x[2] : 0.0); };
  if (domain->dimension == 2) {
    const auto grid = box_grid<2>(domain, opt->cell);
    zones = coupler::zones_from_regions<2>(grid, Eigen::Map<const Vec<2>>(domain->boxlo),
                                            Eigen::Map<const Vec<2>>(domain->boxhi), opt->hybrid_width, inside);
  } else {
    const auto grid = box_grid<3>(domain, opt->cell);
    zones = coupler::zones_from_regions<3>(grid, Eigen::Map<const Vec<3>>(domain->boxlo),
                                            Eigen::Map<const Vec<3>>(domain->boxhi), opt->hybrid_width, inside);
  }
  if (opt->continuum_regions.empty()) std::fill(zones.begin(), zones.end(), coupler::kDiscrete);
  if (domain->dimension == 2) transfer2 = std::make_unique<coupler::GrainTransfer<2>>(box_grid<2>(domain, opt->cell));
  else transfer3 = std::make_unique<coupler::GrainTransfer<3>>(box_grid<3>(domain, opt->cell));
  if (comm->me == 0 && !opt->continuum_regions.empty()) {
    // cells of the box only (the padding cells around it are continuum by convention)
    bigint n[3] = {0, 0, 0};
    double centre[3] = {0, 0, 0};
    for (std::size_t c = 0; c < zones.size(); ++c) {
      cell_centre(c, centre);
      bool in_box = true;    // overlapping it: a face may lie off the cell lattice
      for (int d = 0; d < domain->dimension; d++)
        in_box = in_box && centre[d] + 0.5 * opt->cell > domain->boxlo[d] && centre[d] - 0.5 * opt->cell < domain->boxhi[d];
      if (in_box) n[zones[c]]++;
    }
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: {} grid cells in the box: {} continuum, {} hybrid, {} discrete\n",
                                    n[0] + n[1] + n[2], n[coupler::kContinuum], n[coupler::kHybrid],
                                    n[coupler::kDiscrete]));
  }
}

/* ----------------------------------------------------------------------
   grid cells whose centre lies in a discrete region (evaluated now: regions
   may move); the oracle takes them as boundaries of the material
------------------------------------------------------------------------- */

std::vector<std::uint64_t> FixHybridMPM::discrete_cells()
{
  std::vector<std::uint64_t> cells;
  if (opt->discrete_regions.empty()) return cells;
  const std::vector<Region *> regions = prematched(opt->discrete_regions);
  double centre[3] = {0.0, 0.0, 0.0};
  for (std::size_t c = 0; c < zones.size(); ++c) {
    cell_centre(c, centre);
    if (in_any(regions, centre[0], centre[1], centre[2])) cells.push_back(c);
  }
  return cells;
}

/* ----------------------------------------------------------------------
   the fix's named regions by kind (for the checks that they exist), and
   regions ready to match at this step (they may move)
------------------------------------------------------------------------- */

std::array<std::pair<const char *, const std::vector<std::string> *>, 2> FixHybridMPM::named_regions() const
{
  return {{{"continuum", &opt->continuum_regions}, {"discrete", &opt->discrete_regions}}};
}

std::vector<Region *> FixHybridMPM::prematched(const std::vector<std::string> &ids) const
{
  std::vector<Region *> regions;
  for (const auto &rid : ids) {
    Region *r = domain->regions[domain->find_region(rid)];
    r->prematch();
    regions.push_back(r);
  }
  return regions;
}

bool FixHybridMPM::in_any(const std::vector<Region *> &regions, double x, double y, double z)
{
  for (Region *r : regions)
    if (r->match(x, y, z)) return true;
  return false;
}

void FixHybridMPM::cell_centre(std::size_t c, double *centre) const
{
  if (domain->dimension == 2) {
    const auto &grid = transfer2->grid();
    const Vec<2> x = coupler::cell_center<2>(grid, coupler::cell_coords<2>(grid, c));
    for (int d = 0; d < 2; d++) centre[d] = x[d];
  } else {
    const auto &grid = transfer3->grid();
    const Vec<3> x = coupler::cell_center<3>(grid, coupler::cell_coords<3>(grid, c));
    for (int d = 0; d < 3; d++) centre[d] = x[d];
  }
}

template <>
coupler::GrainTransfer<2> &FixHybridMPM::transfer<2>()
{
  return *transfer2;
}

template <>
coupler::GrainTransfer<3> &FixHybridMPM::transfer<3>()
{
  return *transfer3;
}

/* ----------------------------------------------------------------------
   time of the next exchange if it is certain now, else -1: the MPM process
   then advances to it while LAMMPS computes its steps. Not certain: the run
   ends first (unless the end-of-run output frame is an exchange), or a
   restart file is written before it (the MPM state must then be that of
   this exchange)
------------------------------------------------------------------------- */

double FixHybridMPM::next_exchange_time(bool force_output) const
{
  const bigint now = update->ntimestep, next = now + opt->every;
  if (force_output) return -1.0;
  if (opt->adapt_every > 0 && converted && now % opt->adapt_every == 0 && now < update->laststep) return -1.0;    // a rezone
  if (output->restart_flag && output->next_restart >= now && output->next_restart < next) return -1.0;
  if (next <= update->laststep) return dem_time(next);
  if (opt->continuum.output_every > 0 && update->laststep > now) return dem_time(update->laststep);    // end-of-run frame
  return -1.0;
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
  if (clock_step < 0) return update->atime + (step - update->atimestep) * update->dt;
  return clock_time + (step - clock_step) * clock_dt;
}

int FixHybridMPM::zone_of(const double *x) const
{
  if (zones.empty()) return coupler::kDiscrete;
  if (domain->dimension == 2) {
    const auto &grid = transfer2->grid();
    return zones[coupler::cell_index<2>(grid, coupler::cell_of<2>(grid, Eigen::Map<const Vec<2>>(x)))];
  }
  const auto &grid = transfer3->grid();
  return zones[coupler::cell_index<3>(grid, coupler::cell_of<3>(grid, Eigen::Map<const Vec<3>>(x)))];
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::setup(int /*vflag*/)
{
  // the coupling's clock: LAMMPS's own time at the first run, kept by the fix from then on
  // (this LAMMPS does not restore the simulated time from restart files); re-anchored when
  // the time step changes between runs
  if (clock_step < 0) {
    clock_time = update->atime + (update->ntimestep - update->atimestep) * update->dt;
    clock_step = update->ntimestep;
  } else if (clock_dt != update->dt) {
    clock_time = dem_time();
    clock_step = update->ntimestep;
  }
  clock_dt = update->dt;
  if (!link) connect();
  else check_gravity();
  if (zones.empty()) compute_zones();
  if (restored && !state_loaded) load_mpm_state();
  if (!ledger_started) {
    ledger->start = ledger->energy = grain_energy();
    continuum_start = last_ack->energy;
    ledger_started = true;
  }
  // a rezone left pending at the end of the last run is dropped (its stress is of a step
  // before the commands between the runs); the oracle runs again at its next step
  rezone_pending = false;
  interval_rezones->restart(update->ntimestep + 1);
  run_rezones->restart(update->ntimestep + 1);
  if (!converted && (!opt->continuum_regions.empty() || opt->adapt_every > 0))
    schedule_rezone(opt->continuum_regions.empty() ? coupler::kZonesInitial : coupler::kZonesGiven);
  if (opt->adapt_every > 0) {
    // the Love-Weber stress of the first oracle step needs its per-atom virial
    const bigint first = (update->ntimestep / opt->adapt_every + 1) * opt->adapt_every;
    stress_compute()->addstep(first);
  }
}

/* ----------------------------------------------------------------------
   a rezone at the next step's pre_exchange, with the Love-Weber stress of
   this step, kept per atom: another fix's pre_exchange may delete, add or
   move atoms before ours (fix evaporate, deposit, balance), so a local
   index is not the same atom's then; LAMMPS carries atom_stress with them
------------------------------------------------------------------------- */

void FixHybridMPM::schedule_rezone(int source)
{
  store_atom_stress();
  rezone_pending = true;
  rezone_source = source;
  next_reneighbor = update->ntimestep + 1;
}

void FixHybridMPM::store_atom_stress()
{
  Compute *c = stress_compute();
  c->compute_peratom();
  for (int i = 0; i < atom->nlocal; i++)
    for (int k = 0; k < 6; k++) atom_stress[i][k] = c->array_atom[i][k];
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::pre_exchange()
{
  if (!rezone_pending || update->ntimestep != next_reneighbor) return;
  if (domain->dimension == 2) rezone<2>(rezone_source);
  else rezone<3>(rezone_source);
  rezone_pending = false;
  converted = true;
}

template <int D>
const coupler::PackingTemplate<D> &FixHybridMPM::packing_template()
{
  // 10 x 10 disks or 6 x 6 x 6 balls per period: tiles much larger than a grain, made the
  // same on every rank (deterministic in the seed)
  if constexpr (D == 2) {
    if (!template2)
      template2 = std::make_unique<coupler::PackingTemplate<2>>(
          coupler::make_packing_template<2>(10, polydispersity, static_cast<std::uint32_t>(opt->template_seed)));
    return *template2;
  } else {
    if (!template3)
      template3 = std::make_unique<coupler::PackingTemplate<3>>(
          coupler::make_packing_template<3>(6, polydispersity, static_cast<std::uint32_t>(opt->template_seed)));
    return *template3;
  }
}

/* ----------------------------------------------------------------------
   enrichment (coupler::plan_new_grains, the same list on every rank): each
   rank makes the planned grains in its sub-domain, at their weight times
   their solid mass, and adds them to their cell's sums (the MPM process
   then corrects old and new grains together). Returns how many it made.
------------------------------------------------------------------------- */

template <int D>
bigint FixHybridMPM::make_grains(const std::vector<coupler::RezoneCell<D>> &cells,
                                 std::map<std::size_t, coupler::GrainSums<D>> &sums)
{
  double lo[3], hi[3];
  for (int a = 0; a < 3; a++) lo[a] = container_edge(a, 0), hi[a] = container_edge(a, 1);
  const auto planned = coupler::plan_new_grains<D>(transfer<D>().grid(), cells, sums, grains(), packing_template<D>(),
                                                   grain_rules(), opt->continuum.grain_diameter, lo, hi, world);
  const double zmid = 0.5 * (domain->boxlo[2] + domain->boxhi[2]);
  bigint made = 0;
  for (const auto &p : planned) {
    const auto &g = p.grain;
    double coord[3] = {0.0, 0.0, zmid};
    for (int a = 0; a < D; ++a) coord[a] = g.x[a];
    bool mine = true;
    for (int a = 0; a < D; ++a) mine = mine && coord[a] >= domain->sublo[a] && coord[a] < domain->subhi[a];
    if (!mine) continue;
    atom->avec->create_atom(opt->grain_type, coord);
    const int n = atom->nlocal - 1;
    atom->mask[n] = new_grain_mask;
    atom->radius[n] = g.radius;
    atom->rmass[n] = p.share * g.mass;
    for (int a = 0; a < 3; a++) atom->v[n][a] = a < D ? g.v[a] : 0.0, atom->omega[n][a] = 0.0;
    modify->create_attribute(n);    // every fix's per-atom data (pair history, ours)
    weight[n] = p.share;
    coupler::add_new_grain<D>(sums, cells, p, grain_rules());
    made++;
  }
  return made;
}

double FixHybridMPM::solid_mass(double radius) const
{
  return grain_rules().solid_mass(radius);
}

coupler::GrainRules FixHybridMPM::grain_rules() const
{
  coupler::GrainRules rules;
  rules.dimension = domain->dimension;
  rules.density = opt->continuum.grain_density;
  rules.inertia = opt->inertia;
  return rules;
}

coupler::DemGrains FixHybridMPM::grains() const
{
  coupler::DemGrains g;
  g.n = atom->nlocal;
  g.x = atom->x, g.v = atom->v, g.omega = atom->omega;
  g.radius = atom->radius, g.rmass = atom->rmass;
  g.mask = atom->mask, g.groupbit = groupbit;
  g.weight = weight;
  g.stress = atom_stress;
  return g;
}

double FixHybridMPM::container_edge(int axis, int side) const
{
  return opt->container_edge(axis, side, domain->boxlo, domain->boxhi);
}

/* ----------------------------------------------------------------------
   a rezone (coupler/protocol.hpp): the zones change (oracle, or the map of
   the continuum regions at the start), and the material of every cell whose
   zone changed moves between grains and points with exact mass, momentum
   and angular momentum: grains are deleted (homogenisation), made from the
   points (enrichment) or take a new share of the cell's material; the MPM
   process does the same for the points. Love-Weber stress of the grains
   goes into the new points.
------------------------------------------------------------------------- */

template <int D>
void FixHybridMPM::rezone(int source)
{
  const auto &grid = transfer<D>().grid();
  // as fix pour: atoms are created and deleted now, the ghosts are rebuilt after
  if (atom->map_style != Atom::MAP_NONE) atom->map_clear();
  atom->nghost = 0;
  atom->avec->clear_bonus();

  coupler::StepAck ack;

  double grains_before[7], grains_after[7];
  grain_totals(grains_before);
  close_dem_bracket();

  // 1. zones: the grains' volume per cell goes to the MPM process, which runs the oracle
  const std::vector<coupler::CellGrains> volumes = coupler::cell_grains<D>(grid, grains());
  std::vector<signed char> new_zones;
  std::vector<coupler::RezoneCell<D>> cells;
  coupler::StepHeader header = step_header(coupler::kStepRezone);
  header.zone_source = source;
  check(session->rezone_zones<D>(header, zones, opt->oracle, [&] { return discrete_cells(); }, volumes, zones.size(),
                                 new_zones, cells, ack));
  zones = std::move(new_zones);

  // 2. the sums of the grains in the moving cells, before anything changes
  const coupler::CellSlots slots = coupler::cell_slots<D>(cells);
  std::map<std::size_t, coupler::GrainSums<D>> sums =
      coupler::moving_grain_sums<D>(grid, cells, slots, grains(), grain_rules());

  // 3. enrichment (collective over the DEM ranks): new grains, their sums with the old ones'
  const bigint made_local = make_grains<D>(cells, sums);

  // 4. the MPM process answers what the grains of each cell become
  std::vector<coupler::GrainCorrection<D>> corrections;
  std::vector<coupler::GrainSums<D>> sum_list;
  for (const auto &kv : sums) sum_list.push_back(kv.second);
  check(session->rezone_corrections<D>(sum_list, corrections, ack));

  // 5. apply them: delete, or scale and add the rigid velocity increment
  coupler::DemGrains now = grains();    // (new grains may have moved the arrays)
  std::int64_t hybrid_local = 0;
  const std::vector<char> remove =
      coupler::apply_corrections<D>(grid, cells, slots, corrections, now, grain_rules(), hybrid_local);
  bigint deleted_local = 0;
  AtomVec *avec = atom->avec;
  for (int i = static_cast<int>(remove.size()) - 1; i >= 0; i--)    // as fix evaporate: the last atom fills the gap
    if (remove[i]) {
      avec->copy(atom->nlocal - 1, i, 1);
      atom->nlocal--;
      deleted_local++;
    }

  // 6. the grains' support force now (deleted, made, rescaled grains changed it): the MPM
  // process balances the points' reaction with it; then the acknowledgement with its totals
  double force_local[3] = {0.0, 0.0, 0.0}, force[3];
  for (int i = 0; i < atom->nlocal; i++)
    for (int a = 0; a < 3; a++) force_local[a] += atom->rmass[i] * support[i][a];
  MPI_Allreduce(force_local, force, 3, MPI_DOUBLE, MPI_SUM, world);
  check(session->rezone_finish(force, ack));
  *last_ack = ack;

  grain_totals(grains_after);
  const double energy_after = grain_energy();
  ledger->close_rezone(energy_after);
  // how far the carried masses drifted from the grains' share of their solid mass
  double drift[2], drift_all[2];    // -lightest, heaviest
  coupler::mass_drift(grains(), grain_rules(), drift);
  MPI_Allreduce(drift, drift_all, 2, MPI_DOUBLE, MPI_MAX, world);
  bigint local[3] = {deleted_local, made_local, static_cast<bigint>(hybrid_local)}, all[3];
  MPI_Allreduce(local, all, 3, MPI_LMP_BIGINT, MPI_SUM, world);
  // as fix deposit and fix pour do: made grains must not overflow the atom count or the IDs
  if (all[1] > all[0] && all[1] - all[0] > MAXBIGINT - atom->natoms)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: too many total atoms: making {} grains from points at step {} "
                                  "would exceed the largest atom count LAMMPS allows ({})",
                                  all[1], update->ntimestep, MAXBIGINT));
  if (all[1] > 0) {
    tagint maxtag = 0, maxtag_all = 0;
    for (int i = 0; i < atom->nlocal; i++) maxtag = std::max(maxtag, atom->tag[i]);    // new grains: tag 0
    MPI_Allreduce(&maxtag, &maxtag_all, 1, MPI_LMP_TAGINT, MPI_MAX, world);
    if (all[1] >= static_cast<bigint>(MAXTAGINT) - maxtag_all)
      error->all(FLERR, fmt::format("Fix hybrid/mpm: new atom IDs exceed the largest ID allowed ({}): making {} "
                                    "grains from points at step {} after ID {}; compact the IDs (reset_atom_ids) or "
                                    "build LAMMPS with -DLAMMPS_BIGBIG",
                                    MAXTAGINT, all[1], update->ntimestep, maxtag_all));
  }
  atom->natoms += all[1] - all[0];
  if (all[1] > 0) atom->tag_extend();
  if (atom->map_style != Atom::MAP_NONE) {
    atom->map_init();
    atom->map_set();
  }
  coupler::RezoneReport report;
  report.step = update->ntimestep;
  report.grains_deleted = all[0];
  report.points_made = ack.points_made;
  report.hybrid_grains = all[2];
  report.weight = opt->continuum.grain_weight;
  report.grains_made = all[1];
  report.moved_cells = ack.moved_cells;
  report.continuum_cells = ack.zone_cells[coupler::kContinuum];
  report.hybrid_cells = ack.zone_cells[coupler::kHybrid];
  report.discrete_cells = ack.zone_cells[coupler::kDiscrete];
  report.rests_moved = ack.rests_moved;
  report.rests_kept = ack.rests_kept;
  report.lightest = -drift_all[0];
  report.heaviest = drift_all[1];
  // what the rezone did to the totals of grains plus points (exact up to round-off)
  const double points_after[7] = {ack.mass, ack.momentum[0], ack.momentum[1], ack.momentum[2],
                                  ack.angular[0], ack.angular[1], ack.angular[2]};
  double before[7], after[7];
  for (int k = 0; k < 7; k++) before[k] = grains_before[k] + ack.before[k], after[k] = grains_after[k] + points_after[k];
  log_rezone(report, source, before, after);
  check_dem_timestep(fmt::format("after the rezone at step {}", update->ntimestep));
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
  for (int i : supported)
    for (int a = 0; a < 3; a++) {
      const double dv = dt * support[i][a];
      kicked += rmass[i] * (v[i][a] + 0.5 * dv) * dv;
      v[i][a] += dv;
    }
  ledger->support_open += kicked;
  const bigint step = update->ntimestep;
  const bool oracle_next = opt->adapt_every > 0 && converted && (step + 1) % opt->adapt_every == 0;
  if (oracle_next) stress_compute()->addstep(step + 1);    // its virial
  // LAMMPS prints its thermo output right after this step's end_of_step (Output::write)
  if (output->next_thermo == step) log_rezone_summary(false);
  if (step % opt->every != 0) return;
  if (domain->dimension == 2) exchange<2>(false);
  else exchange<3>(false);
  // the zone oracle right after this exchange (the MPM process did not advance past it),
  // unless the run ends here: the next run's setup reorders the atoms
  if (opt->adapt_every > 0 && converted && step % opt->adapt_every == 0 && step < update->laststep)
    schedule_rezone(coupler::kZonesOracle);
}

/* ----------------------------------------------------------------------
   one coupling exchange: coupled grains' weighted mass and momentum per node
   go to the MPM process, the agreed node velocities come back
------------------------------------------------------------------------- */

template <int D>
void FixHybridMPM::exchange(bool force_output)
{
  double **x = atom->x, **v = atom->v;
  double *rmass = atom->rmass;

  // coupled grains: hybrid grains, and any grain of the group inside a hybrid or continuum cell
  const std::vector<int> index = coupler::coupled_grains(grains(), [&](const double *xi) { return zone_of(xi); });
  std::vector<double> xs, vs, ms;
  for (int i : index) {
    xs.insert(xs.end(), x[i], x[i] + 3);
    vs.insert(vs.end(), v[i], v[i] + 3);
    ms.push_back(rmass[i]);
  }
  coupler::GrainView view;
  view.count = index.size();
  view.x = xs.data();
  view.v = vs.data();
  view.mass = ms.data();
  close_dem_bracket();
  const auto &nodes = transfer<D>().to_nodes(view);
  std::vector<coupler::NodeRecord> records(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    records[k].node = nodes[k].node;
    records[k].mass = nodes[k].mass;
    for (int a = 0; a < D; ++a) records[k].momentum[a] = nodes[k].momentum[a];
  }
  bigint n_coupled_local = static_cast<bigint>(index.size()), n_coupled = 0;
  MPI_Allreduce(&n_coupled_local, &n_coupled, 1, MPI_LMP_BIGINT, MPI_SUM, world);
  coupled_grains = n_coupled;

  const bool output_frame =
      opt->continuum.output_every > 0 && (force_output || (exchanges % opt->continuum.output_every) == 0);
  if (output_frame) last_output_step = update->ntimestep;
  coupler::StepHeader h = step_header(coupler::kStepCouple);
  h.output = output_frame ? 1 : 0;
  h.n_grains = n_coupled;
  h.next_time = next_exchange_time(force_output);
  coupler::StepAck ack;
  const coupler::StepOutcome outcome = session->exchange(
      h, records, [&](const std::vector<coupler::NodeUpdate> &updates) { apply_updates<D>(view, updates, index); },
      [&] { return frame_grains(); }, ack);
  last_step = update->ntimestep;
  check(outcome);

  *last_ack = ack;
  exchanges++;
  link->count_exchange();
}

/* ----------------------------------------------------------------------
   grain velocity updates from the agreed node velocities (coupler rule)
------------------------------------------------------------------------- */

template <int D>
void FixHybridMPM::apply_updates(const coupler::GrainView &view, const std::vector<coupler::NodeUpdate> &updates,
                                 const std::vector<int> &index)
{
  std::vector<coupler::AgreedNode<D>> agreed(updates.size());
  for (std::size_t k = 0; k < updates.size(); ++k)
    for (int a = 0; a < D; ++a) {
      agreed[k].velocity[a] = updates[k].velocity[a];
      agreed[k].impulse_per_mass[a] = updates[k].impulse_per_mass[a];
      agreed[k].support[a] = updates[k].support[a];
    }
  std::vector<double> dv(index.size() * D), accel(index.size() * D);
  transfer<D>().velocity_updates(view, agreed, opt->continuum.pic, dv.data(), accel.data());
  double **v = atom->v;
  const double *rmass = atom->rmass;
  for (int i : supported) support[i][0] = support[i][1] = support[i][2] = 0.0;
  supported.clear();
  double kicked = 0.0;    // the kinetic energy the agreement adds to the grains (energy ledger)
  for (std::size_t g = 0; g < index.size(); ++g) {
    bool any = false;
    for (int a = 0; a < D; ++a) {
      const double dva = dv[g * D + a], va = v[index[g]][a];
      kicked += rmass[index[g]] * (va + 0.5 * dva) * dva;
      v[index[g]][a] += dva;
      support[index[g]][a] = accel[g * D + a];
      any = any || accel[g * D + a] != 0.0;
    }
    if (any) supported.push_back(index[g]);
  }
  ledger->add_agreement(kicked);
}

/* ----------------------------------------------------------------------
   local atoms with a support acceleration, after atoms were reordered
------------------------------------------------------------------------- */

void FixHybridMPM::collect_supported()
{
  supported.clear();
  for (int i = 0; i < atom->nlocal; i++)
    if (support[i][0] != 0.0 || support[i][1] != 0.0 || support[i][2] != 0.0) supported.push_back(i);
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
  const int nlocal = atom->nlocal;
  std::vector<coupler::GrainRecord> grains(nlocal);
  for (int i = 0; i < nlocal; i++) {
    auto &g = grains[i];
    g.id = atom->tag[i];
    for (int a = 0; a < 3; a++) g.x[a] = atom->x[i][a], g.v[a] = atom->v[i][a];
    g.radius = atom->radius[i];
    g.mass = atom->rmass[i];
    g.weight = weight[i];
    g.zone = zone_of(atom->x[i]);
  }
  return grains;
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

/* ---------------------------------------------------------------------- */

void FixHybridMPM::post_run()
{
  // the state at the end of every run is in the output file (an exchange at this step)
  if (link && opt->continuum.output_every > 0 && last_output_step != update->ntimestep) {
    if (domain->dimension == 2) exchange<2>(true);
    else exchange<3>(true);
  }
  last_step = update->ntimestep;
  log_rezone_summary(true);
  if (comm->me == 0 && link)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: {} exchange(s) with the MPM process so far\n", exchanges));
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

void FixHybridMPM::grain_totals(double *all) const
{
  // mass, linear momentum, angular momentum about the origin of the group's grains
  double local[7];
  coupler::grain_totals(grains(), opt->inertia, local);
  MPI_Allreduce(local, all, 7, MPI_DOUBLE, MPI_SUM, world);
}

void FixHybridMPM::fill_thermo_vector()
{
  double totals[7], local[coupler::EnergyLedger::kSums], sums[coupler::EnergyLedger::kSums];
  grain_totals(totals);
  ledger->sums(local);
  MPI_Allreduce(local, sums, coupler::EnergyLedger::kSums, MPI_DOUBLE, MPI_SUM, world);
  coupler::thermo_vector(*last_ack, exchanges + restart_exchanges, coupled_grains, totals, sums, continuum_start,
                         vector_cache);
  vector_step = update->ntimestep;
}

/* ----------------------------------------------------------------------
   energy ledger: the grains' kinetic (translation and rotation) and
   potential energy, and the bracket of LAMMPS's own steps, closed at every
   exchange and rezone (the support force's kicks in it are measured apart)
------------------------------------------------------------------------- */

double FixHybridMPM::grain_energy() const
{
  return coupler::grain_energy(grains(), opt->inertia, opt->continuum.gravity);
}

void FixHybridMPM::close_dem_bracket()
{
  ledger->close_dem_bracket(grain_energy());
}

/* ---------------------------------------------------------------------- */

double FixHybridMPM::memory_usage()
{
  return static_cast<double>(sizeof(*this)) + atom->nmax * kPerAtomValues * sizeof(double) + zones.size();
}

/* ----------------------------------------------------------------------
   restart: settings, exchange count and whether the conversion happened
   (the MPM state itself is not saved yet)
------------------------------------------------------------------------- */

void FixHybridMPM::write_restart(FILE *fp)
{
  double list[6];
  int n = 0;
  list[n++] = opt->cell;
  list[n++] = static_cast<double>(exchanges + restart_exchanges);
  list[n++] = static_cast<double>(opt->every);
  list[n++] = converted ? 1.0 : 0.0;
  list[n++] = dem_time();
  list[n++] = static_cast<double>(update->ntimestep);
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
  if (list[0] != opt->cell && comm->me == 0)
    error->warning(FLERR, fmt::format("Fix hybrid/mpm: restart file has cell {}, the input says {}; using {}",
                                      list[0], opt->cell, opt->cell));
  restart_exchanges = static_cast<bigint>(list[1]);
  clock_time = list[4];
  clock_step = static_cast<bigint>(list[5]);
  clock_dt = update->dt;
  if (list[3] != 0.0) {
    // grains already became points: the MPM process continues from the state saved with the file
    converted = true;
    restored = true;
    if (opt->mpm_state_path.empty())
      error->all(FLERR, "Fix hybrid/mpm: the restart file was written after grains became material points; "
                        "add the keyword 'mpm_state FILE' with the MPM state written next to it "
                        "(<restart file>.mpm.h5)");
  }
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
  if (comm->me == 0)
    utils::logmesg(lmp, fmt::format("fix hybrid/mpm: MPM state {} {} ({} material points)\n",
                                    kind == coupler::kStepSave ? "saved to" : "loaded from", path, ack.points));
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
  weight[j] = weight[i];
  for (int a = 0; a < 3; a++) support[j][a] = support[i][a];
  for (int k = 0; k < 6; k++) atom_stress[j][k] = atom_stress[i][k];
}

void FixHybridMPM::set_arrays(int i)
{
  weight[i] = 1.0;
  support[i][0] = support[i][1] = support[i][2] = 0.0;
  for (int k = 0; k < 6; k++) atom_stress[i][k] = 0.0;    // made after the stress was stored: none
}

int FixHybridMPM::pack_exchange(int i, double *buf)
{
  buf[0] = weight[i];
  for (int a = 0; a < 3; a++) buf[1 + a] = support[i][a];
  for (int k = 0; k < 6; k++) buf[4 + k] = atom_stress[i][k];
  return kPerAtomValues;
}

int FixHybridMPM::unpack_exchange(int nlocal, double *buf)
{
  weight[nlocal] = buf[0];
  for (int a = 0; a < 3; a++) support[nlocal][a] = buf[1 + a];
  for (int k = 0; k < 6; k++) atom_stress[nlocal][k] = buf[4 + k];
  return kPerAtomValues;
}

int FixHybridMPM::pack_restart(int i, double *buf)
{
  buf[0] = 5;    // values for this fix, count included (LAMMPS convention)
  buf[1] = weight[i];
  for (int a = 0; a < 3; a++) buf[2 + a] = support[i][a];
  return 5;
}

void FixHybridMPM::unpack_restart(int nlocal, int nth)
{
  double **extra = atom->extra;
  int m = 0;
  for (int i = 0; i < nth; i++) m += static_cast<int>(extra[nlocal][m]);
  weight[nlocal] = extra[nlocal][m + 1];
  for (int a = 0; a < 3; a++) support[nlocal][a] = extra[nlocal][m + 2 + a];
}

int FixHybridMPM::size_restart(int /*nlocal*/)
{
  return 5;
}

int FixHybridMPM::maxsize_restart()
{
  return 5;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::illegal(const std::string &why)
{
  error->all(FLERR, "Illegal fix hybrid/mpm command: " + why);
}
