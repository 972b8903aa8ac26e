/* ----------------------------------------------------------------------
   fix hybrid/mpm (hybrid-granular project): zones (continuum regions,
   discrete regions) and rezones: the host's side of coupler/dem_rezone.hpp
   (creating and deleting atoms), and the rezone log
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

#include "coupler/coupling_timer.hpp"
#include "coupler/dem_grains.hpp"
#include "coupler/dem_ledger.hpp"
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
  // A continuum region that holds no cell centre of the box converts nothing: a region smaller
  // than a cell, or outside the box, is a mistake, not an empty continuum.
  for (std::size_t k = 0; k < regions.size(); ++k) {
    double centre[3] = {0, 0, 0};
    bool any = false;
    for (std::size_t c = 0; c < zones.size() && !any; ++c) {
      cell_centre(c, centre);
      bool in_box = true;
      for (int d = 0; d < domain->dimension; d++)
        in_box = in_box && centre[d] >= domain->boxlo[d] && centre[d] <= domain->boxhi[d];
      any = in_box && regions[k]->match(centre[0], centre[1], domain->dimension == 3 ? centre[2] : 0.0);
    }
    if (!any)
      error->all(FLERR, fmt::format("Fix hybrid/mpm: continuum region '{}' contains no grid cell centre of the box "
                                    "(cell {}): make the region span at least one cell, or the cell smaller",
                                    opt->continuum_regions[k], opt->cell));
  }
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
  const double start = MPI_Wtime();
  check_finite_grains("before the rezone");
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
  const double asked = MPI_Wtime();
  check(session->rezone_zones<D>(header, zones, opt->oracle, [&] { return discrete_cells(); }, volumes, zones.size(),
                                 new_zones, cells, ack));
  const double oracle_wait = MPI_Wtime() - asked;
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
  charge(coupler::kTimeOracle, oracle_wait);
  charge(coupler::kTimeRezone, MPI_Wtime() - start - oracle_wait);
  run_timing->rezones++;
  all_timing->rezones++;
}
