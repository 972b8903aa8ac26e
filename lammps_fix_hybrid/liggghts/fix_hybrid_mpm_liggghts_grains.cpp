/* ----------------------------------------------------------------------
   fix hybrid/mpm for LIGGGHTS 3.8 (hybrid-granular project): the host's
   grains and settings as the coupling sees them, its contact models, the
   calibrated material's contact law and the DEM time step
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_liggghts_impl.h"

#include "atom.h"
#include "comm.h"
#include "error.h"
#include "fix_gravity.h"
#include "fix_property_global.h"
#include "force.h"
#include "modify.h"
#include "pair_gran.h"
#include "update.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_timestep.hpp"
#include "coupler/fix_options.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::liggghts_hybrid;

/* ----------------------------------------------------------------------
   the DEM step against the contact model (docs/fix_hybrid_mpm.md, "DEM
   time step"): steps per contact of the lightest grains (at their share
   where the coupling splits grains); coupler::kBig for a model it cannot check.
   hooke/stiffness: its kn, kt, gamma_n as the LAMMPS host checks
   gran/hooke/history; hooke and hertz (Young's modulus): LIGGGHTS's Hertz
   and Rayleigh times as its fix check/timestep/gran estimates them
------------------------------------------------------------------------- */

void FixHybridMPMLiggghts::check_pair_style() const
{
  // LIGGGHTS's granular pair style is "gran" with its contact model on the pair_style line
  if (!force->pair_style || std::strncmp(force->pair_style, "gran", 4) != 0)
    fail(std::string("pair style ") + (force->pair_style ? force->pair_style : "none") +
         " is not a granular one: use pair_style gran model hooke (or hertz) tangential history");
}

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
    return coupler::kBig;
  }
  // the lightest grain (at its share where the coupling splits grains), its radius, the fastest
  const bool splits = opt->splits();
  struct {
    double mass;
    int rank;
  } mine = {coupler::kBig, comm->me}, lightest;
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
  if (lightest.mass >= coupler::kBig) return coupler::kBig;
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
