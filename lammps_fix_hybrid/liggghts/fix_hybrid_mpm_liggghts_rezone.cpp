/* ----------------------------------------------------------------------
   fix hybrid/mpm for LIGGGHTS 3.8 (hybrid-granular project): zones
   (continuum regions, discrete regions, mesh walls) and rezones: the host's side of
   coupler/dem_rezone.hpp (creating and deleting atoms as LIGGGHTS's
   particle insertion does)
------------------------------------------------------------------------- */

#include "fix_hybrid_mpm_liggghts_impl.h"
#include "liggghts_private.h"

#include "abstract_mesh.h"
#include "atom.h"
#include "atom_vec.h"
#include "comm.h"
#include "compute.h"
#include "error.h"
#include "fix_mesh.h"
#include "modify.h"
#include "output.h"
#include "region.h"
#include "thermo.h"
#include "update.h"

#include "coupler/dem_coupling.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
#include "coupler/dem_rezone.hpp"
#include "coupler/dem_run_log.hpp"
#include "coupler/dem_session.hpp"
#include "coupler/enrichment.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/text.hpp"
#include "coupler/transfer.hpp"
#include "coupler/zones.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

using namespace LAMMPS_NS;
using namespace FixConst;
using namespace LAMMPS_NS::liggghts_hybrid;

// LIGGGHTS 3.8's thermo calls atoms lost whenever their count fell since its last output
// (Thermo::last_natoms, private), so a rezone that turns grains into points would stop a deck
// with `thermo_modify lost error`: the fix tells it the count it changed itself
namespace LAMMPS_NS::liggghts_private {
struct ThermoLastNatoms {
  using type = bigint Thermo::*;
  friend type member(ThermoLastNatoms);
};
template struct Reach<ThermoLastNatoms, &Thermo::last_natoms>;
}    // namespace LAMMPS_NS::liggghts_private

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
  const coupler::GridGeometry<3> grid = box_grid(domain, *opt);
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
  // A discrete region that touches no cell of the box keeps nothing discrete (cells_touched).
  const int untouched = coupler::first_untouching_region<3>(grid, domain->boxlo, domain->boxhi, discrete_shapes());
  if (untouched >= 0)
    fail("discrete region '" + opt->discrete_regions[untouched] + "' touches no grid cell of the box (cell " +
         coupler::shortest(opt->cell) + "), so it keeps nothing discrete: make the region span at least a third of "
         "a cell, or the cell smaller");
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

// the Love-Weber stress of this step, per atom, for the next rezone's new points
void FixHybridMPMLiggghts::store_atom_stress()
{
  Compute *c = stress_compute();
  c->compute_peratom();
  for (int i = 0; i < atom->nlocal; i++)
    for (int k = 0; k < 6; k++) atom_stress[i][k] = c->array_atom[i][k];
}

// a rezone at the next step's pre_exchange (the conversion)
void FixHybridMPMLiggghts::schedule_rezone(int source)
{
  store_atom_stress();
  rezone_pending = true;
  rezone_source = source;
  next_reneighbor = update->ntimestep + 1;
}

// the zone oracle at the next step's post_integrate (adaptive zones)
void FixHybridMPMLiggghts::schedule_oracle()
{
  store_atom_stress();
  oracle_pending = true;
}

// grid cells a discrete region touches now (regions may move): the oracle's boundaries
std::vector<std::uint64_t> FixHybridMPMLiggghts::discrete_cells() const
{
  return coupler::cells_touched<3>(transfer->grid(), discrete_shapes());
}

std::vector<coupler::RegionShape> FixHybridMPMLiggghts::discrete_shapes() const
{
  std::vector<coupler::RegionShape> shapes;
  for (const auto &rid : opt->discrete_regions) {
    Region *r = domain->regions[domain->find_region(rid.c_str())];
    r->prematch();
    shapes.push_back(coupler::region_shape(r));
  }
  return shapes;
}

// LIGGGHTS's mesh walls (fix mesh/surface, the meshes of fix wall/gran ... mesh): the grid cells their
// triangles pass through now (meshes may move), from the triangles every rank owns (collective);
// logged at the first call
std::vector<std::uint64_t> FixHybridMPMLiggghts::mesh_wall_cells()
{
  std::vector<double> mine;
  std::string ids;
  for (int f = 0; f < modify->nfix; f++) {
    if (std::strncmp(modify->fix[f]->style, "mesh/surface", 12) != 0) continue;
    ids += std::string(ids.empty() ? "" : " ") + modify->fix[f]->id;
    AbstractMesh *mesh = static_cast<FixMesh *>(modify->fix[f])->mesh();
    if (!mesh || mesh->numNodes() != 3) continue;
    double node[3];
    for (int e = 0; e < mesh->sizeLocal(); e++)
      for (int k = 0; k < 3; k++) {
        mesh->node_slow(e, k, node);
        mine.insert(mine.end(), node, node + 3);
      }
  }
  if (ids.empty()) return {};
  const int n = static_cast<int>(mine.size());
  std::vector<int> counts(comm->nprocs), offsets(comm->nprocs, 0);
  MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, world);
  for (int r = 1; r < comm->nprocs; r++) offsets[r] = offsets[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<std::size_t>(offsets.back() + counts.back()));
  MPI_Allgatherv(mine.data(), n, MPI_DOUBLE, all.data(), counts.data(), offsets.data(), MPI_DOUBLE, world);
  std::vector<std::uint64_t> cells = coupler::cells_of_triangles(transfer->grid(), all);
  if (!mesh_walls_logged)
    say("fix hybrid/mpm: mesh walls (fix mesh/surface " + ids + "): " + std::to_string(all.size() / 9) +
        " triangles on " + std::to_string(cells.size()) +
        " grid cells, kept discrete (boundaries of the zone oracle, as the cells of discrete regions)");
  mesh_walls_logged = true;
  return cells;
}

void FixHybridMPMLiggghts::pre_exchange()
{
  if (!rezone_pending || update->ntimestep != next_reneighbor) return;
  rezone(rezone_source);
  rezone_pending = false;
  converted = true;
}

// the zone oracle before LIGGGHTS decides whether to rebuild its neighbour lists (as the LAMMPS
// fix, docs/design.md 5.5): a rezone at this step's pre_exchange only where material moves
void FixHybridMPMLiggghts::post_integrate()
{
  if (!oracle_pending) return;
  oracle_pending = false;
  const double start = MPI_Wtime();
  check_finite_atoms("the zone oracle");
  const coupler::RezonePlan<3> plan = rezone_plan(coupler::kZonesOracle, next_exchange_time(update->ntimestep - 1, false));
  coupler::RezoneAtoms<3> atoms = rezone_atoms();
  auto answer = std::make_unique<coupler::ZoneAnswer<3>>();
  const coupler::StepOutcome outcome = coupler::ask_zones<3>(*session, plan, zones, atoms, *answer);
  if (!outcome.ok()) fail(outcome.what);
  const double wait = answer->oracle_wait;
  const bool moves = answer->moves_material();
  if (moves) {
    zone_answer = std::move(answer);
    rezone_pending = true;
    rezone_source = coupler::kZonesOracle;
    next_reneighbor = update->ntimestep;
  } else {    // the rezone ended with the answer: the atoms and their lists stay as they are
    zones = std::move(answer->zones);
    *last_ack = answer->ack;
    double grains_now[7];
    grain_totals(grains_now);
    report_rezone(coupler::kZonesOracle, coupler::RezoneCounts{}, answer->ack,
                  coupler::rezone_aftermath(grains(), grain_rules(), 0, world), grains_now, grains_now);
  }
  run_log->charge_rezone(start, wait, !moves);    // a rezone that goes on is counted at its end
}

void FixHybridMPMLiggghts::check_finite_atoms(const char *before) const
{
  for (int i = 0; i < atom->nlocal; i++)
    for (int a = 0; a < 3; a++)
      if (!std::isfinite(atom->x[i][a]) || !std::isfinite(atom->v[i][a]) || !std::isfinite(atom->rmass[i]))
        error->one(FLERR, (std::string("Fix hybrid/mpm: an atom has a non-finite (NaN or inf) position, velocity or "
                                       "mass before ") + before + ": check the time step and the input").c_str());
}

coupler::RezonePlan<3> FixHybridMPMLiggghts::rezone_plan(int source, double next_time)
{
  coupler::RezonePlan<3> plan;
  plan.grid = &transfer->grid();
  plan.header = step_header(coupler::kStepRezone);
  plan.header.zone_source = source;
  plan.header.next_time = next_time;
  plan.oracle = &opt->oracle;
  if (!packing)
    packing.reset(new coupler::PackingTemplate<3>(
        coupler::make_packing_template<3>(6, polydispersity, static_cast<std::uint32_t>(opt->template_seed))));
  plan.packing = packing.get();
  plan.rules = grain_rules();
  plan.grain_diameter = opt->continuum.grain_diameter;
  for (int a = 0; a < 3; a++)
    plan.lo[a] = opt->container_edge(a, 0, domain->boxlo, domain->boxhi),
    plan.hi[a] = opt->container_edge(a, 1, domain->boxlo, domain->boxhi), plan.gravity[a] = opt->continuum.gravity[a];
  return plan;
}

coupler::RezoneAtoms<3> FixHybridMPMLiggghts::rezone_atoms()
{
  coupler::RezoneAtoms<3> atoms;
  atoms.grains = [this] { return grains(); };
  atoms.make = [this](const coupler::PlannedGrain<3> &p) { return make_grain(p); };
  atoms.remove = [this](const std::vector<char> &flags) {
    atom->nlocal = coupler::delete_flagged(flags, atom->nlocal, [this](int from, int to) { atom->avec->copy(from, to, 1); });
  };
  // the oracle's boundaries: the discrete regions and the mesh walls (their cells gathered here,
  // collectively: the session asks for them on rank 0 only)
  atoms.discrete_cells = [this, mesh_cells = mesh_wall_cells()] {
    std::vector<std::uint64_t> cells = discrete_cells();
    cells.insert(cells.end(), mesh_cells.begin(), mesh_cells.end());
    std::sort(cells.begin(), cells.end());
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    return cells;
  };
  return atoms;
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
  const double start = MPI_Wtime();
  // as LIGGGHTS's insertion: atoms are created and deleted now, the ghosts are rebuilt after
  if (atom->map_style) atom->map_clear();
  atom->nghost = 0;
  double grains_before[7], grains_after[7];
  grain_totals(grains_before);
  ledger->close_dem_bracket(grain_energy());

  const coupler::RezonePlan<3> plan = rezone_plan(source, -1.0);
  coupler::RezoneAtoms<3> atoms = rezone_atoms();
  // the oracle's answer came at post_integrate; the conversion asks now
  std::unique_ptr<coupler::ZoneAnswer<3>> answer = std::move(zone_answer);
  double oracle_wait = 0.0;
  if (!answer) {
    check_finite_atoms("the conversion");
    if (source == coupler::kZonesGiven) {
      // the continuum regions' own map: it must leave the grains next to a mesh wall discrete
      std::int64_t covered = 0;
      for (std::uint64_t c : mesh_wall_cells()) covered += zones[c] != coupler::kDiscrete;
      if (covered > 0)
        fail("the continuum regions make " + std::to_string(covered) + " grid cells that a mesh wall (fix " +
             "mesh/surface) passes through continuum or hybrid, but grains next to a mesh wall must stay discrete: "
             "make the continuum regions clear of the mesh walls by at least hybrid_width + 1 cells, or use adaptive "
             "zones (keyword adaptive), whose oracle keeps the mesh walls' cells discrete");
    }
    answer = std::make_unique<coupler::ZoneAnswer<3>>();
    const coupler::StepOutcome asked = coupler::ask_zones<3>(*session, plan, zones, atoms, *answer);
    if (!asked.ok()) fail(asked.what);
    oracle_wait = answer->oracle_wait;
  }
  zones = std::move(answer->zones);
  coupler::StepAck ack = answer->ack;
  coupler::RezoneCounts counts;
  if (answer->moves_material()) {
    const coupler::StepOutcome outcome =
        coupler::move_material<3>(*session, world, plan, answer->cells, atoms, support, ack, counts);
    if (!outcome.ok()) fail(outcome.what);
  }
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
    output->thermo->*member(liggghts_private::ThermoLastNatoms{}) += counts.made - counts.deleted;
  if (counts.made > 0 && atom->tag_enable) atom->tag_extend();
  if (atom->map_style) {
    atom->map_init();
    atom->map_set();
  }
  report_rezone(source, counts, ack, aftermath, grains_before, grains_after);
  check_dem_timestep("after the rezone at step " + std::to_string(update->ntimestep));
  double vector[coupler::kVecSize];
  ledger_vector(grains_after, vector);    // the energy guard, at every rezone that moved material
  run_log->charge_rezone(start, oracle_wait);
}

// a rezone's tallies and its lines in the rezone log (every rezone with rezone_log full, the
// conversion by default)
void FixHybridMPMLiggghts::report_rezone(int source, const coupler::RezoneCounts &counts, const coupler::StepAck &ack,
                                         const coupler::RezoneAftermath &aftermath, const double grains_before[7],
                                         const double grains_after[7])
{
  const coupler::RezoneReport report =
      coupler::rezone_report(update->ntimestep, counts, ack, opt->continuum.grain_weight, aftermath);
  double before[7], after[7];
  coupler::rezone_totals(grains_before, grains_after, ack, before, after);
  say(run_log->rezone(report, source != coupler::kZonesOracle, opt->rezone_log, before, after));
}
