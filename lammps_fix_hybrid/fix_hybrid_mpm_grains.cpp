/* ----------------------------------------------------------------------
   fix hybrid/mpm (hybrid-granular project): the host's grains and settings
   as the coupling sees them, and the checks of the run against them (box,
   gravity, the DEM time step, the calibrated material's contact law)
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_impl.h"

#include "atom.h"
#include "comm.h"
#include "compute.h"
#include "error.h"
#include "force.h"
#include "group.h"
#include "modify.h"
#include "pair.h"
#include "update.h"
#include "utils.h"

#include "GRANULAR/pair_gran_hooke_history.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_timestep.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/material_file.hpp"

#include <algorithm>
#include <cmath>

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::hybrid_mpm;

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

}    // namespace


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
  const std::string problem = coupler::gravity_change_problem(opt->continuum.gravity, now);
  if (!problem.empty()) error->all(FLERR, problem);
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
  if (coupler::warn_poor_step(steps, opt->warn_steps_per_contact, fewest_steps_warned) && comm->me == 0)
    error->warning(FLERR, coupler::poor_step_warning(update->dt, when, why));
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
      error->warning(FLERR, coupler::unchecked_pair_style(force->pair_style));
    timestep_checked = true;
    return coupler::kBig;
  }
  const bool splits = opt->splits();
  double local = coupler::kBig, lightest = coupler::kBig;
  for (int i = 0; i < atom->nlocal; i++) {
    local = std::min(local, atom->rmass[i]);
    if (splits && (atom->mask[i] & groupbit))
      local = std::min(local, atom->rmass[i] / weight[i] * opt->continuum.grain_weight);
  }
  MPI_Allreduce(&local, &lightest, 1, MPI_DOUBLE, MPI_MIN, world);
  if (lightest >= coupler::kBig) return coupler::kBig;

  coupler::HookeanContact contact = HookeanConstants::of(pair);
  contact.m_eff = 0.5 * lightest;
  contact.inertia = opt->inertia;
  const coupler::DemStepCheck check =
      coupler::check_dem_step(force->pair_style, contact, lightest, splits, update->dt);
  if (!timestep_checked && comm->me == 0) utils::logmesg(lmp, check.log_line(update->dt) + "\n");
  timestep_checked = true;
  why = check.why(opt->warn_steps_per_contact);
  return check.steps;
}

/* ---------------------------------------------------------------------- */

void FixHybridMPM::grain_defaults()
{
  // mu(I) needs the grain size and solid density; grains made from points take the size
  // spread, type and groups of the grains there are
  const coupler::GroupGrains gg = coupler::group_grains(grains(), atom->type, atom->ntypes, domain->dimension, world);
  new_grain_mask = coupler::apply_group_defaults(*opt, gg, groupbit, polydispersity);
  const std::string density = coupler::density_problem(*opt, gg, domain->dimension);
  if (!density.empty()) error->all(FLERR, "Fix hybrid/mpm: " + density);
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
  deck.kn = hooke.kn, deck.kt = hooke.kt, deck.gamman = hooke.gamman;
  deck.gammat = HookeanConstants::tangential_damping(pair);
  const std::string problem = coupler::apply_deck_material(*opt, deck);
  if (!problem.empty()) error->all(FLERR, problem);
  if (comm->me == 0) utils::logmesg(lmp, coupler::material_line(*opt) + "\n");
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
  return coupler::grain_view(atom->nlocal, atom->x, atom->v, atom->omega, atom->radius, atom->rmass, atom->mask,
                             groupbit, arrays());
}

double FixHybridMPM::container_edge(int axis, int side) const
{
  return opt->container_edge(axis, side, domain->boxlo, domain->boxhi);
}

void FixHybridMPM::grain_totals(double *all) const
{
  // mass, linear momentum, angular momentum about the origin of the group's grains
  double local[7];
  coupler::grain_totals(grains(), opt->inertia, local);
  MPI_Allreduce(local, all, 7, MPI_DOUBLE, MPI_SUM, world);
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
