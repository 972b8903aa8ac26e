/* ----------------------------------------------------------------------
   fix hybrid/mpm (hybrid-granular project): zones (continuum regions,
   discrete regions) and rezones: the host's side of coupler/dem_rezone.hpp
   (creating and deleting atoms)
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_impl.h"

#include "atom.h"
#include "atom_vec.h"
#include "comm.h"
#include "compute.h"
#include "error.h"
#include "modify.h"
#include "region.h"
#include "update.h"
#include "utils.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_run_log.hpp"
#include "coupler/dem_rezone.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/enrichment.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/rezone_log.hpp"
#include "coupler/zones.hpp"

#include <algorithm>
#include <map>

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::hybrid_mpm;


/* ----------------------------------------------------------------------
   zone of every grid cell from the continuum regions (same on all ranks)
------------------------------------------------------------------------- */

void FixHybridMPM::compute_zones()
{
  const std::vector<Region *> regions = prematched(opt->continuum_regions);
  auto inside = [&](const auto &x) { return in_any(regions, x[0], x[1], x.size() == 3 ? x[2] : 0.0); };
  if (domain->dimension == 2) {
    const auto grid = box_grid<2>(domain, *opt);
    zones = coupler::zones_from_regions<2>(grid, Eigen::Map<const Vec<2>>(domain->boxlo),
                                            Eigen::Map<const Vec<2>>(domain->boxhi), opt->hybrid_width, inside);
  } else {
    const auto grid = box_grid<3>(domain, *opt);
    zones = coupler::zones_from_regions<3>(grid, Eigen::Map<const Vec<3>>(domain->boxlo),
                                            Eigen::Map<const Vec<3>>(domain->boxhi), opt->hybrid_width, inside);
  }
  if (opt->continuum_regions.empty()) std::fill(zones.begin(), zones.end(), coupler::kDiscrete);
  if (domain->dimension == 2) transfer2 = std::make_unique<coupler::GrainTransfer<2>>(box_grid<2>(domain, *opt));
  else transfer3 = std::make_unique<coupler::GrainTransfer<3>>(box_grid<3>(domain, *opt));
  // A continuum region that holds no cell centre of the box converts nothing: a region smaller
  // than a cell, or outside the box, is a mistake, not an empty continuum.
  const auto match = [&](int k, const double *x) { return regions[k]->match(x[0], x[1], x[2]) != 0; };
  const int empty = domain->dimension == 2
      ? coupler::first_empty_region<2>(transfer2->grid(), domain->boxlo, domain->boxhi, regions.size(), match)
      : coupler::first_empty_region<3>(transfer3->grid(), domain->boxlo, domain->boxhi, regions.size(), match);
  if (empty >= 0)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: continuum region '{}' contains no grid cell centre of the box "
                                  "(cell {}): make the region span at least one cell, or the cell smaller",
                                  opt->continuum_regions[empty], opt->cell));
  // A discrete region that touches no cell of the box keeps nothing discrete (cells_touched).
  const std::vector<coupler::RegionShape> discrete = discrete_shapes();
  const int untouched = domain->dimension == 2
      ? coupler::first_untouching_region<2>(transfer2->grid(), domain->boxlo, domain->boxhi, discrete)
      : coupler::first_untouching_region<3>(transfer3->grid(), domain->boxlo, domain->boxhi, discrete);
  if (untouched >= 0)
    error->all(FLERR, fmt::format("Fix hybrid/mpm: discrete region '{}' touches no grid cell of the box (cell {}), so "
                                  "it keeps nothing discrete: make the region span at least a third of a cell, or the "
                                  "cell smaller", opt->discrete_regions[untouched], opt->cell));
  if (comm->me == 0 && !opt->continuum_regions.empty()) {
    bigint n[3];
    if (domain->dimension == 2) coupler::zone_counts<2>(transfer2->grid(), zones, domain->boxlo, domain->boxhi, n);
    else coupler::zone_counts<3>(transfer3->grid(), zones, domain->boxlo, domain->boxhi, n);
    utils::logmesg(lmp, coupler::zone_counts_line(n) + "\n");
  }
}

/* ----------------------------------------------------------------------
   grid cells a discrete region touches (evaluated now: regions may move);
   the oracle takes them as boundaries of the material
------------------------------------------------------------------------- */

std::vector<std::uint64_t> FixHybridMPM::discrete_cells()
{
  const std::vector<coupler::RegionShape> shapes = discrete_shapes();
  if (domain->dimension == 2) return coupler::cells_touched<2>(transfer2->grid(), shapes);
  return coupler::cells_touched<3>(transfer3->grid(), shapes);
}

std::vector<coupler::RegionShape> FixHybridMPM::discrete_shapes() const
{
  std::vector<coupler::RegionShape> shapes;
  for (Region *r : prematched(opt->discrete_regions)) shapes.push_back(coupler::region_shape(r));
  return shapes;
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

/* ----------------------------------------------------------------------
   a rezone at the next step's pre_exchange (the conversion), or the zone
   oracle at the next step's post_integrate (adaptive zones), with the
   Love-Weber stress of this step, kept per atom: another fix's
   pre_exchange may delete, add or move atoms before ours (fix evaporate,
   deposit, balance), so a local index is not the same atom's then; LAMMPS
   carries atom_stress with them
------------------------------------------------------------------------- */

void FixHybridMPM::schedule_rezone(int source)
{
  store_atom_stress();
  rezone_pending = true;
  rezone_source = source;
  next_reneighbor = update->ntimestep + 1;
}

void FixHybridMPM::schedule_oracle()
{
  store_atom_stress();
  oracle_pending = true;
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

/* ----------------------------------------------------------------------
   the zone oracle before LAMMPS decides whether to rebuild its neighbour
   lists (docs/design.md 5.5): where the new zones move material, the
   rezone follows at this step's pre_exchange (a forced rebuild); where
   they move none, the rezone ended with the answer and the atoms and their
   lists stay as they are (most oracle steps of a flow near rest)
------------------------------------------------------------------------- */

void FixHybridMPM::post_integrate()
{
  if (!oracle_pending) return;
  oracle_pending = false;
  if (domain->dimension == 2) ask_oracle<2>();
  else ask_oracle<3>();
}

template <int D>
void FixHybridMPM::ask_oracle()
{
  const double start = MPI_Wtime();
  check_finite_grains("before the zone oracle");
  coupler::RezonePlan<D> plan = rezone_plan<D>(coupler::kZonesOracle);
  // the last exchange was the step before: the MPM process advances to the next one at once
  // if no material moves
  plan.header.next_time = next_exchange_time(update->ntimestep - 1, false);
  coupler::RezoneAtoms<D> atoms = rezone_atoms<D>();
  auto answer = std::make_unique<coupler::ZoneAnswer<D>>();
  const coupler::StepOutcome outcome = coupler::ask_zones<D>(*session, plan, zones, atoms, *answer);
  if (!outcome.ok()) error->all(FLERR, "Fix hybrid/mpm: " + outcome.what);
  const double wait = answer->oracle_wait;
  const bool moves = answer->moves_material();
  if (moves) {
    zone_answer<D>() = std::move(answer);
    rezone_pending = true;
    rezone_source = coupler::kZonesOracle;
    next_reneighbor = update->ntimestep;
  } else {
    zones = std::move(answer->zones);
    *last_ack = answer->ack;
    double grains_now[7];
    grain_totals(grains_now);
    report_rezone(coupler::kZonesOracle, coupler::RezoneCounts{}, answer->ack,
                  coupler::rezone_aftermath(grains(), grain_rules(), 0, world), grains_now, grains_now);
  }
  run_log->charge_rezone(start, wait, !moves);    // a rezone that goes on is counted at its end
}

template <int D>
coupler::RezonePlan<D> FixHybridMPM::rezone_plan(int source)
{
  coupler::RezonePlan<D> plan;
  plan.grid = &transfer<D>().grid();
  plan.header = step_header(coupler::kStepRezone);
  plan.header.zone_source = source;
  plan.oracle = &opt->oracle;
  plan.packing = &packing_template<D>();
  plan.rules = grain_rules();
  plan.grain_diameter = opt->continuum.grain_diameter;
  for (int a = 0; a < 3; a++)
    plan.lo[a] = container_edge(a, 0), plan.hi[a] = container_edge(a, 1), plan.gravity[a] = opt->continuum.gravity[a];
  return plan;
}

template <int D>
coupler::RezoneAtoms<D> FixHybridMPM::rezone_atoms()
{
  coupler::RezoneAtoms<D> atoms;
  atoms.grains = [this] { return grains(); };
  atoms.make = [this](const coupler::PlannedGrain<D> &p) { return make_grain<D>(p); };
  atoms.remove = [this](const std::vector<char> &flags) {
    atom->nlocal = coupler::delete_flagged(flags, atom->nlocal, [this](int from, int to) { atom->avec->copy(from, to, 1); });
  };
  atoms.discrete_cells = [this] { return discrete_cells(); };
  return atoms;
}

template <>
std::unique_ptr<coupler::ZoneAnswer<2>> &FixHybridMPM::zone_answer<2>()
{
  return zone_answer2;
}

template <>
std::unique_ptr<coupler::ZoneAnswer<3>> &FixHybridMPM::zone_answer<3>()
{
  return zone_answer3;
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
   a grain the enrichment planned (coupler::plan_new_grains, the same list
   on every rank): made by the rank whose sub-domain holds it, at its
   weight times its solid mass
------------------------------------------------------------------------- */

template <int D>
bool FixHybridMPM::make_grain(const coupler::PlannedGrain<D> &p)
{
  const auto &g = p.grain;
  double coord[3] = {0.0, 0.0, 0.5 * (domain->boxlo[2] + domain->boxhi[2])};
  for (int a = 0; a < D; ++a) coord[a] = g.x[a];
  for (int a = 0; a < D; ++a)
    if (coord[a] < domain->sublo[a] || coord[a] >= domain->subhi[a]) return false;
  atom->avec->create_atom(opt->grain_type, coord);
  const int n = atom->nlocal - 1;
  atom->mask[n] = new_grain_mask;
  atom->radius[n] = g.radius;
  atom->rmass[n] = p.share * g.mass;
  for (int a = 0; a < 3; a++) atom->v[n][a] = a < D ? g.v[a] : 0.0, atom->omega[n][a] = 0.0;
  modify->create_attribute(n);    // every fix's per-atom data (pair history, ours)
  weight[n] = p.share;
  return true;
}

/* ----------------------------------------------------------------------
   a rezone (coupler::rezone_grains): the zones change (oracle, or the map
   of the continuum regions at the start), and the material of every cell
   whose zone changed moves between grains and points with exact mass,
   momentum and angular momentum: grains are deleted (homogenisation), made
   from the points (enrichment) or take a new share of the cell's material;
   the MPM process does the same for the points. Love-Weber stress of the
   grains goes into the new points.
------------------------------------------------------------------------- */

template <int D>
void FixHybridMPM::rezone(int source)
{
  const double start = MPI_Wtime();
  // as fix pour: atoms are created and deleted now, the ghosts are rebuilt after
  if (atom->map_style != Atom::MAP_NONE) atom->map_clear();
  atom->nghost = 0;
  atom->avec->clear_bonus();

  double grains_before[7], grains_after[7];
  grain_totals(grains_before);
  close_dem_bracket();

  const coupler::RezonePlan<D> plan = rezone_plan<D>(source);
  coupler::RezoneAtoms<D> atoms = rezone_atoms<D>();
  // the oracle's answer came at post_integrate; the conversion asks now
  std::unique_ptr<coupler::ZoneAnswer<D>> answer = std::move(zone_answer<D>());
  double oracle_wait = 0.0;
  if (!answer) {
    check_finite_grains("before the rezone");
    answer = std::make_unique<coupler::ZoneAnswer<D>>();
    const coupler::StepOutcome asked = coupler::ask_zones<D>(*session, plan, zones, atoms, *answer);
    if (!asked.ok()) error->all(FLERR, "Fix hybrid/mpm: " + asked.what);
    oracle_wait = answer->oracle_wait;
  }
  zones = std::move(answer->zones);
  coupler::StepAck ack = answer->ack;
  coupler::RezoneCounts counts;
  if (answer->moves_material()) {
    const coupler::StepOutcome outcome =
        coupler::move_material<D>(*session, world, plan, answer->cells, atoms, support, ack, counts);
    if (!outcome.ok()) error->all(FLERR, "Fix hybrid/mpm: " + outcome.what);
  }
  *last_ack = ack;

  grain_totals(grains_after);
  ledger->close_rezone(grain_energy());
  // how far the carried masses drifted from the grains' share of their solid mass; the IDs in use
  const coupler::RezoneAftermath aftermath = coupler::rezone_aftermath(
      grains(), grain_rules(), atom->nlocal > 0 ? *std::max_element(atom->tag, atom->tag + atom->nlocal) : 0, world);
  const std::string too_many = coupler::new_atoms_problem(
      counts.made, counts.deleted, atom->natoms, MAXBIGINT, aftermath.max_tag, MAXTAGINT, update->ntimestep, "LAMMPS",
      "compact the IDs (reset_atom_ids) or build LAMMPS with -DLAMMPS_BIGBIG");
  if (!too_many.empty()) error->all(FLERR, "Fix hybrid/mpm: " + too_many);
  atom->natoms += counts.made - counts.deleted;
  if (counts.made > 0) atom->tag_extend();
  if (atom->map_style != Atom::MAP_NONE) {
    atom->map_init();
    atom->map_set();
  }
  report_rezone(source, counts, ack, aftermath, grains_before, grains_after);
  check_dem_timestep(fmt::format("after the rezone at step {}", update->ntimestep));
  double vector[coupler::kVecSize];
  ledger_vector(grains_after, vector);    // the energy guard, at every rezone that moved material
  run_log->charge_rezone(start, oracle_wait);
}

/* ----------------------------------------------------------------------
   a rezone's tallies and its lines in the rezone log (every rezone with
   rezone_log full, the conversion by default); every rank
------------------------------------------------------------------------- */

void FixHybridMPM::report_rezone(int source, const coupler::RezoneCounts &counts, const coupler::StepAck &ack,
                                 const coupler::RezoneAftermath &aftermath, const double grains_before[7],
                                 const double grains_after[7])
{
  const coupler::RezoneReport report =
      coupler::rezone_report(update->ntimestep, counts, ack, opt->continuum.grain_weight, aftermath);
  // what the rezone did to the totals of grains plus points (exact up to round-off)
  double before[7], after[7];
  coupler::rezone_totals(grains_before, grains_after, ack, before, after);
  const std::string lines = run_log->rezone(report, source != coupler::kZonesOracle, opt->rezone_log, before, after);
  if (comm->me == 0 && !lines.empty()) utils::logmesg(lmp, lines);
}
