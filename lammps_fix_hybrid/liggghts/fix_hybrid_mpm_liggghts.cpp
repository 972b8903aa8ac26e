/* ----------------------------------------------------------------------
   fix hybrid/mpm for LIGGGHTS 3.8 (hybrid-granular project)

   The LIGGGHTS adapter of the coupling of docs/design.md section 5: the
   same options, handshake, exchange and rezone sequences as the LAMMPS fix
   (coupler/dem_coupling.hpp, coupler/dem_session.hpp), with LIGGGHTS's
   atoms, regions and errors. What it does not do (2D, a calibrated
   material for a contact law other than hooke/stiffness) it refuses with a
   clear error: docs/fix_hybrid_mpm.md, "LIGGGHTS host".
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_liggghts.h"

#include "atom.h"
#include "atom_vec.h"
#include "comm.h"
#include "compute.h"
#include "domain.h"
#include "error.h"
#include "fix_gravity.h"
#include "fix_property_global.h"
#include "force.h"
#include "memory.h"
#include "modify.h"
#include "output.h"
#include "pair_gran.h"
#include "region.h"
#include "thermo.h"
#include "universe.h"
#include "update.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/dem_timestep.hpp"
#include "coupler/enrichment.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/protocol.hpp"
#include "coupler/rezone_log.hpp"
#include "coupler/text.hpp"
#include "coupler/transfer.hpp"
#include "coupler/version.hpp"
#include "coupler/zones.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <deque>

using namespace LAMMPS_NS;
using namespace FixConst;

namespace {

constexpr double kBig = 1.0e20;

using Vec3 = Eigen::Matrix<double, 3, 1>;

// LIGGGHTS's Error keeps the text it is given and prints it again at the end of the job (its
// SpecialMessages): the text must outlive the call, so the fix's messages are kept for good
const char *kept(const std::string &text)
{
  static std::deque<std::string> messages;
  messages.push_back(text);
  return messages.back().c_str();
}

// LIGGGHTS 3.8 keeps Output's restart schedule private; the announced time of the next exchange
// must not pass a restart file (its MPM state is that of the restart step): the members are
// reached as liggghts_main.cpp reaches the style map, through explicit template instantiation
using RestartFlagMember = bool Output::*;
using NextRestartMember = bigint Output::*;
template <RestartFlagMember Flag, NextRestartMember Next>
struct OutputRestartAccess {
  friend RestartFlagMember output_restart_flag() { return Flag; }
  friend NextRestartMember output_next_restart() { return Next; }
};
RestartFlagMember output_restart_flag();
NextRestartMember output_next_restart();
template struct OutputRestartAccess<&Output::restart_flag, &Output::next_restart>;

// LIGGGHTS 3.8's thermo calls atoms lost whenever their count fell since its last output
// (Thermo::last_natoms, private), so a rezone that turns grains into points would stop a deck
// with `thermo_modify lost error`: the fix tells it the count it changed itself, the same way
using LastNatomsMember = bigint Thermo::*;
template <LastNatomsMember Member>
struct ThermoLastNatomsAccess {
  friend LastNatomsMember thermo_last_natoms() { return Member; }
};
LastNatomsMember thermo_last_natoms();
template struct ThermoLastNatomsAccess<&Thermo::last_natoms>;

coupler::GridGeometry<3> box_grid(const Domain *domain, double cell)
{
  return coupler::padded_grid<3>(Eigen::Map<const Vec3>(domain->boxlo), Eigen::Map<const Vec3>(domain->boxhi), cell);
}

}    // namespace

/* ---------------------------------------------------------------------- */

Fix *FixHybridMPMLiggghts::creator(LAMMPS *lmp, int narg, char **arg)
{
  return new FixHybridMPMLiggghts(lmp, narg, arg);
}

FixHybridMPMLiggghts::FixHybridMPMLiggghts(LAMMPS *lmp, int narg, char **arg) :
    Fix(lmp, narg, arg), last_ack(new coupler::StepAck), ledger(new coupler::EnergyLedger), weight(NULL),
    support(NULL), atom_stress(NULL), stress_id(NULL), exchanges(0), coupled_grains(0), last_step(0),
    last_output_step(-1), vector_step(-1), clock_step(-1), converted(false), rezone_pending(false),
    ledger_started(false), timestep_checked(false), restored(false), state_loaded(false), restart_exchanges(0), new_grain_mask(1), rezone_source(0), polydispersity(0.0), continuum_start(0.0), clock_time(0.0),
    clock_dt(0.0), fewest_steps_warned(kBig)
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
    coupler::install_dem_finalize_hook(world);
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
  mask |= PRE_EXCHANGE;    // the conversion of the continuum regions' grains (first step)
  mask |= PRE_NEIGHBOR;    // atoms were exchanged and sorted: rebuild the list of supported grains
  mask |= END_OF_STEP;     // the coupling exchange
  mask |= POST_RUN;
  return mask;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPMLiggghts::say(const std::string &text) const
{
  if (comm->me != 0 || text.empty()) return;
  if (screen) fprintf(screen, "%s\n", text.c_str());
  if (logfile) fprintf(logfile, "%s\n", text.c_str());
}

void FixHybridMPMLiggghts::fail(const std::string &why) const
{
  error->all(FLERR, kept("Fix hybrid/mpm: " + why));
  std::exit(1);    // Error::all does not return
}

void FixHybridMPMLiggghts::check_pair_style() const
{
  // LIGGGHTS's granular pair style is "gran" with its contact model on the pair_style line
  if (!force->pair_style || std::strncmp(force->pair_style, "gran", 4) != 0)
    fail(std::string("pair style ") + (force->pair_style ? force->pair_style : "none") +
         " is not a granular one: use pair_style gran model hooke (or hertz) tangential history");
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
  // the deck's step, before the coupling has changed any grain, is refused only where velocity
  // Verlet cannot integrate the stiffest contact; later runs are checked as the rezones are
  if (!converted) {
    std::string why;
    if (dem_steps_per_contact(why) < coupler::kUnstableStepsPerContact)
      fail("the time step " + coupler::general(update->dt, 6) + " s is unstable (checked before the run): " + why);
  }
  check_dem_timestep("at the start of the run");
}

/* ----------------------------------------------------------------------
   the DEM step against the contact model (docs/fix_hybrid_mpm.md, "DEM
   time step"): steps per contact of the lightest grains (at their share
   where the coupling splits grains); kBig for a model it cannot check.
   hooke/stiffness: its kn, kt, gamma_n as the LAMMPS host checks
   gran/hooke/history; hooke and hertz (Young's modulus): LIGGGHTS's Hertz
   and Rayleigh times as its fix check/timestep/gran estimates them
------------------------------------------------------------------------- */

// the normal contact model of pair_style gran the fix knows ("" for another)
std::string FixHybridMPMLiggghts::contact_model() const
{
  PairGran *pair = static_cast<PairGran *>(force->pair_match("gran", 0));
  for (const char *m : {"hooke/stiffness", "hooke", "hertz"})
    if (pair && pair->contact_match("normal", m)) return m;
  return "";
}

// a material value of fix property/global (peratomtype or peratomtypepair) for atom type `type`
// (its pair with itself)
double FixHybridMPMLiggghts::material_value(const char *name, bool pair, int type) const
{
  const int n = atom->ntypes;
  const char *kind = pair ? "peratomtypepair" : "peratomtype";
  Fix *f = modify->find_fix_property(name, "property/global", kind, n, pair ? n : 0, style, false);
  if (!f) fail("pair_style gran model " + contact_model() + " needs fix property/global " + name + " " + kind);
  return static_cast<FixPropertyGlobal *>(f)->get_values()[pair ? (type - 1) * n + (type - 1) : type - 1];
}

double FixHybridMPMLiggghts::dem_steps_per_contact(std::string &why)
{
  const std::string model = contact_model();
  if (model.empty()) {
    if (!timestep_checked && comm->me == 0)
      error->warning(FLERR, "Fix hybrid/mpm checks the DEM time step for pair_style gran models hooke/stiffness, "
                            "hooke and hertz only: check it yourself (fix check/timestep/gran reports the Rayleigh "
                            "and Hertz times)");
    timestep_checked = true;
    return kBig;
  }
  // the lightest grain (at its share where the coupling splits grains), its radius, the fastest
  const bool splits = opt->splits();
  struct {
    double mass;
    int rank;
  } mine = {kBig, comm->me}, lightest;
  double radius = 0.0, speed_local = 0.0, speed = 0.0;
  int type = 1;
  for (int i = 0; i < atom->nlocal; i++) {
    double m = atom->rmass[i];
    if (splits && (atom->mask[i] & groupbit)) m = std::min(m, m / weight[i] * opt->continuum.grain_weight);
    if (m < mine.mass) mine.mass = m, radius = atom->radius[i], type = atom->type[i];
    const double *v = atom->v[i];
    speed_local = std::max(speed_local, std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]));
  }
  MPI_Allreduce(&mine, &lightest, 1, MPI_DOUBLE_INT, MPI_MINLOC, world);
  if (lightest.mass >= kBig) return kBig;
  MPI_Allreduce(&speed_local, &speed, 1, MPI_DOUBLE, MPI_MAX, world);
  double grain[2] = {radius, static_cast<double>(type)};
  MPI_Bcast(grain, 2, MPI_DOUBLE, lightest.rank, world);
  type = static_cast<int>(grain[1]);
  coupler::DemStepCheck check;
  if (model == "hooke/stiffness") {
    // kn, kt, gamma_n of the lightest grain's own type pair; gamma_n is multiplied by m_eff
    // (without absolute_damping), as LAMMPS's gran/hooke/history does
    coupler::HookeanContact contact;
    contact.kn = material_value("kn", true, type);
    contact.kt = material_value("kt", true, type);
    contact.gamman = material_value("gamman", true, type);
    contact.m_eff = 0.5 * lightest.mass;
    contact.inertia = opt->inertia;
    check = coupler::check_dem_step("gran model hooke/stiffness", contact, lightest.mass, splits, update->dt);
  } else {
    check = coupler::check_elastic_step(model, grain[0], lightest.mass, material_value("youngsModulus", false, type),
                                        material_value("poissonsRatio", false, type), 2.0 * speed, splits, update->dt);
  }
  if (!timestep_checked) say(check.log_line(update->dt));
  timestep_checked = true;
  why = check.why(opt->warn_steps_per_contact);
  return check.steps;
}

// grains the coupling made or rescaled may be lighter than any before, and their contacts faster:
// the user is told (again whenever the figure drops by another 10 %)
void FixHybridMPMLiggghts::check_dem_timestep(const std::string &when)
{
  std::string why;
  if (coupler::warn_poor_step(dem_steps_per_contact(why), opt->warn_steps_per_contact, fewest_steps_warned) &&
      comm->me == 0)
    error->warning(FLERR, kept(coupler::poor_step_warning(update->dt, when, why)));
}

/* ----------------------------------------------------------------------
   the host's grains and settings as the coupling sees them
------------------------------------------------------------------------- */

coupler::DemGrains FixHybridMPMLiggghts::grains() const
{
  return coupler::grain_view(atom->nlocal, atom->x, atom->v, atom->omega, atom->radius, atom->rmass, atom->mask,
                             groupbit, arrays());
}

coupler::GrainRules FixHybridMPMLiggghts::grain_rules() const
{
  coupler::GrainRules rules;
  rules.dimension = 3;
  rules.density = opt->continuum.grain_density;
  rules.inertia = opt->inertia;
  return rules;
}

void FixHybridMPMLiggghts::grain_totals(double *all) const
{
  double local[7];
  coupler::grain_totals(grains(), opt->inertia, local);
  MPI_Allreduce(local, all, 7, MPI_DOUBLE, MPI_SUM, world);
}

double FixHybridMPMLiggghts::grain_energy() const
{
  return coupler::grain_energy(grains(), opt->inertia, opt->continuum.gravity);
}

void FixHybridMPMLiggghts::dem_gravity(double *g) const
{
  for (int d = 0; d < 3; d++) g[d] = 0.0;
  for (int i = 0; i < modify->nfix; i++)
    if (std::strcmp(modify->fix[i]->style, "gravity") == 0) {
      double gi[3];
      static_cast<FixGravity *>(modify->fix[i])->get_gravity(gi);
      for (int d = 0; d < 3; d++) g[d] += gi[d];
    }
}

/* ----------------------------------------------------------------------
   the coupling's clock (LIGGGHTS's own time at the first run) and steps
------------------------------------------------------------------------- */

double FixHybridMPMLiggghts::dem_time(bigint step) const
{
  if (clock_step < 0) return update->atime + (step - update->atimestep) * update->dt;
  return clock_time + (step - clock_step) * clock_dt;
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

// the time of the next exchange if it is certain now (the MPM process advances to it while
// LIGGGHTS computes its steps), else -1: the run ends first, or a rezone comes first
double FixHybridMPMLiggghts::next_exchange_time(bool force_output) const
{
  const bigint now = update->ntimestep, next = now + opt->every;
  if (force_output) return -1.0;
  if (opt->adaptive() && converted && now % opt->adapt_every == 0 && now < update->laststep) return -1.0;
  const bigint restart_step = output->*output_next_restart();
  if (output->*output_restart_flag() && restart_step >= now && restart_step < next) return -1.0;    // a restart file
  if (next <= update->laststep) return dem_time(next);
  if (opt->continuum.output_every > 0 && update->laststep > now) return dem_time(update->laststep);
  return -1.0;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPMLiggghts::connect()
{
  const coupler::GroupGrains gg = coupler::group_grains(grains(), atom->type, atom->ntypes, 3, world);
  new_grain_mask = coupler::apply_group_defaults(*opt, gg, groupbit, polydispersity);
  if (opt->material) apply_material();
  // the grid: the fix line's cell, or one chosen from the grains (and the oracle's defaults from it)
  std::string problem;
  try {
    say("fix hybrid/mpm: " + coupler::grid_of_run(*opt, 3, gg.count, problem));
  } catch (const coupler::OptionError &e) {
    error->all(FLERR, kept("Illegal fix hybrid/mpm command: " + std::string(e.what())));
  }
  if (!problem.empty()) fail(problem);
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

/* ----------------------------------------------------------------------
   the continuum's constants from the calibrated material (keyword material):
   its calibrations are of a linear spring-dashpot, LIGGGHTS's hooke/stiffness
------------------------------------------------------------------------- */

void FixHybridMPMLiggghts::apply_material()
{
  if (contact_model() != "hooke/stiffness")
    fail("material " + opt->material->path + " was calibrated for pair style " + opt->material->pair +
         " (a linear spring-dashpot), the deck's contact model is " +
         (contact_model().empty() ? std::string("another") : "gran model " + contact_model()) +
         ": use pair_style gran model hooke/stiffness with its constants, or measure the continuum's constants for "
         "this contact law (docs/design.md section 4.6)");
  const int type = opt->grain_type;    // the grains' (the new grains' type: the group's smallest)
  coupler::DeckContact deck;
  deck.dimension = 3;
  deck.friction = material_value("coefficientFriction", true, type);
  deck.kn = material_value("kn", true, type), deck.kt = material_value("kt", true, type);
  deck.gamman = material_value("gamman", true, type), deck.gammat = material_value("gammat", true, type);
  const std::string problem = coupler::apply_deck_material(*opt, deck);
  if (!problem.empty()) error->all(FLERR, kept(problem));
  say(coupler::material_line(*opt));
}

void FixHybridMPMLiggghts::setup(int /*vflag*/)
{
  if (clock_step < 0) {
    clock_time = update->atime + (update->ntimestep - update->atimestep) * update->dt;
    clock_step = update->ntimestep;
  } else if (clock_dt != update->dt) {
    clock_time = dem_time(update->ntimestep);
    clock_step = update->ntimestep;
  }
  clock_dt = update->dt;
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
  }
  // a rezone left pending at the end of the last run is dropped (its stress is of a step before
  // the commands between the runs); the oracle runs again at its next step
  rezone_pending = false;
  if (!converted && opt->splits())
    schedule_rezone(opt->continuum_regions.empty() ? coupler::kZonesInitial : coupler::kZonesGiven);
  if (opt->adaptive())    // the Love-Weber stress of the first oracle step needs its per-atom virial
    stress_compute()->addstep((update->ntimestep / opt->adapt_every + 1) * opt->adapt_every);
}

/* ----------------------------------------------------------------------
   zone of every grid cell from the continuum regions (same on all ranks)
------------------------------------------------------------------------- */

void FixHybridMPMLiggghts::compute_zones()
{
  std::vector<Region *> regions;
  for (const auto &rid : opt->continuum_regions) {
    Region *r = domain->regions[domain->find_region(rid.c_str())];
    r->prematch();
    regions.push_back(r);
  }
  auto inside = [&](const Vec3 &x) {
    for (Region *r : regions)
      if (r->match(x[0], x[1], x[2])) return true;
    return false;
  };
  const coupler::GridGeometry<3> grid = box_grid(domain, opt->cell);
  zones = coupler::zones_from_regions<3>(grid, Eigen::Map<const Vec3>(domain->boxlo),
                                         Eigen::Map<const Vec3>(domain->boxhi), opt->hybrid_width, inside);
  if (opt->continuum_regions.empty()) std::fill(zones.begin(), zones.end(), coupler::kDiscrete);
  transfer.reset(new coupler::GrainTransfer<3>(grid));
  const int empty = coupler::first_empty_region<3>(
      grid, domain->boxlo, domain->boxhi, static_cast<int>(regions.size()),
      [&](int k, const double *x) { return regions[k]->match(x[0], x[1], x[2]) != 0; });
  if (empty >= 0)
    fail("continuum region '" + opt->continuum_regions[empty] + "' contains no grid cell centre of the box (cell " +
         coupler::shortest(opt->cell) + "): make the region span at least one cell, or the cell smaller");
  if (!opt->continuum_regions.empty()) {
    std::int64_t n[3];
    coupler::zone_counts<3>(grid, zones, domain->boxlo, domain->boxhi, n);
    say(coupler::zone_counts_line(n));
  }
}

int FixHybridMPMLiggghts::zone_of(const double *x) const
{
  if (zones.empty()) return coupler::kDiscrete;
  const auto &grid = transfer->grid();
  return zones[coupler::cell_index<3>(grid, coupler::cell_of<3>(grid, Eigen::Map<const Vec3>(x)))];
}

/* ----------------------------------------------------------------------
   a rezone (the conversion to the continuum regions' zones, or the
   oracle's) at the next step's pre_exchange, with the Love-Weber stress of
   this step kept per atom (it travels with the atoms until then)
------------------------------------------------------------------------- */

Compute *FixHybridMPMLiggghts::stress_compute() const
{
  const int icompute = stress_id ? modify->find_compute(stress_id) : -1;
  if (icompute < 0)
    fail("its compute stress/atom (for the stress of new material points) no longer exists: do not uncompute it "
         "while the fix is defined");
  return modify->compute[icompute];
}

void FixHybridMPMLiggghts::schedule_rezone(int source)
{
  Compute *c = stress_compute();
  c->compute_peratom();
  for (int i = 0; i < atom->nlocal; i++)
    for (int k = 0; k < 6; k++) atom_stress[i][k] = c->array_atom[i][k];
  rezone_pending = true;
  rezone_source = source;
  next_reneighbor = update->ntimestep + 1;
}

// grid cells whose centre lies in a discrete region now (regions may move): the oracle's boundaries
std::vector<std::uint64_t> FixHybridMPMLiggghts::discrete_cells() const
{
  std::vector<std::uint64_t> cells;
  std::vector<Region *> regions;
  for (const auto &rid : opt->discrete_regions) {
    regions.push_back(domain->regions[domain->find_region(rid.c_str())]);
    regions.back()->prematch();
  }
  const auto &grid = transfer->grid();
  for (std::size_t c = 0; c < zones.size() && !regions.empty(); ++c) {
    const Vec3 x = coupler::cell_center<3>(grid, coupler::cell_coords<3>(grid, c));
    for (Region *r : regions)
      if (r->match(x[0], x[1], x[2])) {
        cells.push_back(c);
        break;
      }
  }
  return cells;
}

void FixHybridMPMLiggghts::pre_exchange()
{
  if (!rezone_pending || update->ntimestep != next_reneighbor) return;
  rezone(rezone_source);
  rezone_pending = false;
  converted = true;
}

// as LIGGGHTS's particle insertion: the atom, its per-atom data in every fix (contact history, ours)
bool FixHybridMPMLiggghts::make_grain(const coupler::PlannedGrain<3> &p)
{
  const auto &g = p.grain;
  double coord[3] = {g.x[0], g.x[1], g.x[2]};
  for (int a = 0; a < 3; ++a)
    if (coord[a] < domain->sublo[a] || coord[a] >= domain->subhi[a]) return false;
  atom->avec->create_atom(opt->grain_type, coord);
  const int n = atom->nlocal - 1;
  atom->mask[n] = new_grain_mask;
  atom->radius[n] = g.radius;
  atom->density[n] = opt->continuum.grain_density;
  atom->rmass[n] = p.share * g.mass;
  for (int a = 0; a < 3; a++) atom->v[n][a] = g.v[a], atom->omega[n][a] = 0.0;
  for (int f = 0; f < modify->nfix; f++)
    if (modify->fix[f]->create_attribute) modify->fix[f]->set_arrays(n);
  weight[n] = p.share;
  return true;
}

void FixHybridMPMLiggghts::rezone(int source)
{
  for (int i = 0; i < atom->nlocal; i++)
    for (int a = 0; a < 3; a++)
      if (!std::isfinite(atom->x[i][a]) || !std::isfinite(atom->v[i][a]) || !std::isfinite(atom->rmass[i]))
        error->one(FLERR, "Fix hybrid/mpm: an atom has a non-finite (NaN or inf) position, velocity or mass before "
                          "the conversion: check the time step and the input");
  // as LIGGGHTS's insertion: atoms are created and deleted now, the ghosts are rebuilt after
  if (atom->map_style) atom->map_clear();
  atom->nghost = 0;
  double grains_before[7], grains_after[7], before[7], after[7];
  grain_totals(grains_before);
  ledger->close_dem_bracket(grain_energy());

  coupler::RezonePlan<3> plan;
  plan.grid = &transfer->grid();
  plan.header = step_header(coupler::kStepRezone);
  plan.header.zone_source = source;
  plan.oracle = &opt->oracle;
  if (!packing)
    packing.reset(new coupler::PackingTemplate<3>(
        coupler::make_packing_template<3>(6, polydispersity, static_cast<std::uint32_t>(opt->template_seed))));
  plan.packing = packing.get();
  plan.rules = grain_rules();
  plan.grain_diameter = opt->continuum.grain_diameter;
  for (int a = 0; a < 3; a++)
    plan.lo[a] = opt->container_edge(a, 0, domain->boxlo, domain->boxhi),
    plan.hi[a] = opt->container_edge(a, 1, domain->boxlo, domain->boxhi);
  coupler::RezoneAtoms<3> atoms;
  atoms.grains = [&] { return grains(); };
  atoms.make = [&](const coupler::PlannedGrain<3> &p) { return make_grain(p); };
  atoms.remove = [&](const std::vector<char> &flags) {
    atom->nlocal = coupler::delete_flagged(flags, atom->nlocal, [&](int from, int to) { atom->avec->copy(from, to, 1); });
  };
  atoms.discrete_cells = [&] { return discrete_cells(); };
  coupler::StepAck ack;
  coupler::RezoneCounts counts;
  const coupler::StepOutcome outcome = coupler::rezone_grains<3>(*session, world, plan, zones, atoms, support, ack, counts);
  if (!outcome.ok()) fail(outcome.what);
  *last_ack = ack;

  grain_totals(grains_after);
  ledger->close_rezone(grain_energy());
  const coupler::RezoneAftermath aftermath = coupler::rezone_aftermath(
      grains(), grain_rules(), atom->nlocal > 0 ? *std::max_element(atom->tag, atom->tag + atom->nlocal) : 0, world);
  const std::string too_many =
      coupler::new_atoms_problem(counts.made, counts.deleted, atom->natoms, MAXBIGINT, aftermath.max_tag, MAXTAGINT,
                                 update->ntimestep, "LIGGGHTS", "LIGGGHTS's atom IDs are 32-bit");
  if (!too_many.empty()) fail(too_many);
  atom->natoms += counts.made - counts.deleted;
  if (output != nullptr && output->thermo != nullptr)    // not lost: made and deleted by the fix
    output->thermo->*thermo_last_natoms() += counts.made - counts.deleted;
  if (counts.made > 0 && atom->tag_enable) atom->tag_extend();
  if (atom->map_style) {
    atom->map_init();
    atom->map_set();
  }
  const coupler::RezoneReport report =
      coupler::rezone_report(update->ntimestep, counts, ack, opt->continuum.grain_weight, aftermath.drift);
  coupler::rezone_totals(grains_before, grains_after, ack, before, after);
  // every rezone's lines with rezone_log full; the conversion's also by default (summary)
  const bool conversion = source != coupler::kZonesOracle;
  if (opt->rezone_log == coupler::RezoneLog::kFull || (opt->rezone_log == coupler::RezoneLog::kSummary && conversion)) {
    say(coupler::rezone_line(report));
    say(coupler::rezone_totals_line(report.step, before, after));
  }
  check_dem_timestep("after the rezone at step " + std::to_string(update->ntimestep));
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
  for (int i : supported)
    for (int a = 0; a < 3; a++) {
      const double dv = dt * support[i][a];
      kicked += atom->rmass[i] * (v[i][a] + 0.5 * dv) * dv;
      v[i][a] += dv;
    }
  ledger->support_open += kicked;
  const bigint step = update->ntimestep;
  if (opt->adaptive() && converted && (step + 1) % opt->adapt_every == 0) stress_compute()->addstep(step + 1);
  if (step % opt->every != 0) return;
  exchange(false);
  // the zone oracle right after this exchange (the MPM process did not advance past it), unless
  // the run ends here: the next run's setup reorders the atoms
  if (opt->adaptive() && converted && step % opt->adapt_every == 0 && step < update->laststep)
    schedule_rezone(coupler::kZonesOracle);
}

void FixHybridMPMLiggghts::post_run()
{
  if (link && opt->continuum.output_every > 0 && last_output_step != update->ntimestep) exchange(true);
  last_step = update->ntimestep;
  if (link) say("fix hybrid/mpm: " + std::to_string(exchanges) + " exchange(s) with the MPM process so far");
}

void FixHybridMPMLiggghts::exchange(bool force_output)
{
  ledger->close_dem_bracket(grain_energy());
  const coupler::DemGrains g = grains();
  const std::vector<int> index = coupler::coupled_grains(g, [&](const double *xi) { return zone_of(xi); });
  coupler::StepHeader h = step_header(coupler::kStepCouple);
  h.output = coupler::output_frame_due(opt->continuum.output_every, exchanges, force_output) ? 1 : 0;
  h.next_time = next_exchange_time(force_output);
  if (h.output) last_output_step = update->ntimestep;
  auto frame = [&] { return coupler::frame_records(grains(), atom->tag, [&](const double *x) { return zone_of(x); }); };
  coupler::StepAck ack;
  coupler::ExchangeTally tally;
  const coupler::StepOutcome outcome = session->settle(coupler::exchange_grains<3>(
      *session, world, *transfer, g, index, h, opt->continuum.pic, support, supported, frame, ack, tally));
  coupled_grains = tally.coupled;
  ledger->add_agreement(tally.kicked);
  last_step = update->ntimestep;
  if (!outcome.ok()) fail(outcome.what);
  *last_ack = ack;
  exchanges++;
  link->count_exchange();
}

/* ----------------------------------------------------------------------
   thermo output: f_ID the exchanges, f_ID[i] the LAMMPS fix's entries
   (coupler::ThermoEntry; the wall-time entries are 0 on LIGGGHTS)
------------------------------------------------------------------------- */

double FixHybridMPMLiggghts::compute_scalar()
{
  return static_cast<double>(exchanges + restart_exchanges);
}

double FixHybridMPMLiggghts::compute_vector(int n)
{
  if (vector_step != update->ntimestep) {
    double totals[7], local[coupler::EnergyLedger::kSums], sums[coupler::EnergyLedger::kSums];
    grain_totals(totals);
    ledger->sums(local);
    MPI_Allreduce(local, sums, coupler::EnergyLedger::kSums, MPI_DOUBLE, MPI_SUM, world);
    coupler::thermo_vector(*last_ack, exchanges + restart_exchanges, coupled_grains, totals, sums, continuum_start, vector_cache);
    vector_step = update->ntimestep;
  }
  return vector_cache[n];
}

double FixHybridMPMLiggghts::memory_usage()
{
  return static_cast<double>(sizeof(*this)) + atom->nmax * coupler::GrainArrays::kValues * sizeof(double) + zones.size();
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
  double list[coupler::RestartRecord::kValues];
  r.write(list);
  if (comm->me != 0) return;
  const int size = sizeof(list);
  fwrite(&size, sizeof(int), 1, fp);
  fwrite(list, sizeof(double), coupler::RestartRecord::kValues, fp);
}

void FixHybridMPMLiggghts::restart(char *buf)
{
  const coupler::RestartRecord r = coupler::RestartRecord::read(reinterpret_cast<double *>(buf));
  const std::string warning = r.take_cell(opt->cell);
  if (comm->me == 0 && !warning.empty()) error->warning(FLERR, kept(warning));
  restart_exchanges = r.exchanges;
  clock_time = r.time, clock_step = r.step, clock_dt = update->dt;
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
