// The DEM side's coupled steps as whole sequences (coupler/dem_coupling.hpp).
#include "coupler/dem_coupling.hpp"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <map>

#include "coupler/conversion.hpp"
#include "coupler/oracle.hpp"
#include "coupler/text.hpp"
#include "coupler/zones.hpp"

namespace coupler {

template <int D>
StepOutcome exchange_grains(DemSession &session, MPI_Comm comm, GrainTransfer<D> &transfer, const DemGrains &g,
                            const std::vector<int> &index, StepHeader header, double pic, double **support,
                            std::vector<int> &supported,
                            const std::function<std::vector<GrainRecord>()> &frame_grains, StepAck &ack,
                            ExchangeTally &tally) {
  std::vector<double> xs, vs, ms;
  xs.reserve(3 * index.size()), vs.reserve(3 * index.size()), ms.reserve(index.size());
  for (int i : index) {
    xs.insert(xs.end(), g.x[i], g.x[i] + 3);
    vs.insert(vs.end(), g.v[i], g.v[i] + 3);
    ms.push_back(g.rmass[i]);
  }
  GrainView view;
  view.count = index.size();
  view.x = xs.data();
  view.v = vs.data();
  view.mass = ms.data();
  const auto &nodes = transfer.to_nodes(view);
  std::vector<NodeRecord> records(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    records[k].node = nodes[k].node;
    records[k].mass = nodes[k].mass;
    for (int a = 0; a < D; ++a) records[k].momentum[a] = nodes[k].momentum[a];
  }
  std::int64_t local = static_cast<std::int64_t>(index.size());
  MPI_Allreduce(&local, &tally.coupled, 1, MPI_INT64_T, MPI_SUM, comm);
  header.n_grains = tally.coupled;
  const bool regime = pic == kPicRegime;  // the MPM process answers each node's share
  header.field_shares = regime ? 1 : 0;

  // the agreed node velocities: each coupled grain's velocity update and support acceleration
  auto apply = [&](const std::vector<NodeUpdate> &updates) {
    const double t0 = MPI_Wtime();
    std::vector<AgreedNode<D>> agreed(updates.size());
    for (std::size_t k = 0; k < updates.size(); ++k) {
      for (int a = 0; a < D; ++a) {
        agreed[k].velocity[a] = updates[k].velocity[a];
        agreed[k].impulse_per_mass[a] = updates[k].impulse_per_mass[a];
        agreed[k].support[a] = updates[k].support[a];
      }
      agreed[k].field_share = regime ? updates[k].field_share : pic;
    }
    std::vector<double> dv(index.size() * D), accel(index.size() * D);
    transfer.velocity_updates(view, agreed, dv.data(), accel.data());
    for (int i : supported) support[i][0] = support[i][1] = support[i][2] = 0.0;
    supported.clear();
    for (std::size_t k = 0; k < index.size(); ++k) {
      const int i = index[k];
      bool any = false;
      for (int a = 0; a < D; ++a) {
        const double dva = dv[k * D + a];
        tally.kicked += g.rmass[i] * (g.v[i][a] + 0.5 * dva) * dva;
        g.v[i][a] += dva;
        support[i][a] = accel[k * D + a];
        any = any || accel[k * D + a] != 0.0;
      }
      if (any) supported.push_back(i);
    }
    tally.applying += MPI_Wtime() - t0;
  };
  auto frame = [&] {
    const double t0 = MPI_Wtime();
    auto grains = frame_grains();
    tally.framing += MPI_Wtime() - t0;
    return grains;
  };
  return session.exchange(header, records, apply, frame, ack);
}

template <int D>
StepOutcome ask_zones(DemSession &session, const RezonePlan<D> &plan, const std::vector<signed char> &zones,
                      RezoneAtoms<D> &atoms, ZoneAnswer<D> &answer) {
  // the grains' volume per cell goes to the MPM process, which runs the oracle
  const std::vector<CellGrains> volumes = cell_grains<D>(*plan.grid, atoms.grains());
  const double asked = MPI_Wtime();
  const StepOutcome out = session.settle(session.rezone_zones<D>(
      plan.header, zones, *plan.oracle, atoms.discrete_cells, volumes, zones.size(), answer.zones, answer.cells,
      answer.ack));
  answer.oracle_wait = MPI_Wtime() - asked;
  return out;
}

template <int D>
StepOutcome move_material(DemSession &session, MPI_Comm comm, const RezonePlan<D> &plan,
                          const std::vector<RezoneCell<D>> &cells, RezoneAtoms<D> &atoms, double *const *support,
                          StepAck &ack, RezoneCounts &counts) {
  const GridGeometry<D> &grid = *plan.grid;
  StepOutcome out;

  // (1. the zones: ask_zones) 2. the sums of the grains in the moving cells, before anything changes
  const CellSlots slots = cell_slots<D>(cells);
  std::map<std::size_t, GrainSums<D>> sums = moving_grain_sums<D>(grid, cells, slots, atoms.grains(), plan.rules);

  // 3. enrichment (collective): new grains, their sums with the old ones'
  const double inertia = plan.rules.inertia;
  RezoneGrainEnergy energy;    // this rank's grains of the group; made = after the enrichment - before it
  std::vector<GrainEnergy> initial;    // each old grain's energy before the rezone (made grains follow them)
  {
    const DemGrains old = atoms.grains();
    initial.resize(old.n);
    for (int i = 0; i < old.n; i++)
      if (old.coupled(i)) {
        initial[i] = grain_energy_of(old, i, inertia, plan.gravity);
        energy.made -= initial[i];
      }
  }
  const auto planned = plan_new_grains<D>(grid, cells, sums, atoms.grains(), *plan.packing, plan.rules,
                                          plan.grain_diameter, plan.lo, plan.hi, comm);
  std::int64_t made_local = 0;
  for (const auto &p : planned)
    if (atoms.make(p)) {
      add_new_grain<D>(sums, cells, p, plan.rules);
      made_local++;
    }

  // 4. the MPM process answers what the grains of each cell become
  std::vector<GrainCorrection<D>> corrections;
  std::vector<GrainSums<D>> sum_list;
  for (const auto &kv : sums) sum_list.push_back(kv.second);
  out = session.settle(session.rezone_corrections<D>(sum_list, corrections, ack));
  if (!out.ok()) return out;

  // 5. apply them: delete, or scale and add the rigid velocity increment
  DemGrains now = atoms.grains();    // (new grains may have moved the arrays)
  std::vector<GrainEnergy> before(now.n);
  for (int i = 0; i < now.n; i++)
    if (now.coupled(i)) {
      before[i] = grain_energy_of(now, i, inertia, plan.gravity);
      energy.made += before[i];
    }
  std::vector<signed char> mechanism;    // each grain's cell's, as the MPM process judged it
  const std::vector<char> remove =
      apply_corrections<D>(grid, cells, slots, corrections, now, plan.rules, &mechanism);
  std::int64_t deleted_local = 0;
  for (int i = 0; i < now.n; i++) {
    if (!now.coupled(i)) continue;
    GrainEnergy after;    // (none if removed)
    if (remove[i]) {
      deleted_local++;
      energy.removed -= before[i];
    } else {
      after = grain_energy_of(now, i, inertia, plan.gravity);
      energy.corrected += after;
      energy.corrected -= before[i];
    }
    if (mechanism[i] < 0) continue;    // not in a moving cell: unchanged
    GrainEnergy &tally = energy.by_mechanism[mechanism[i]];
    tally += after;
    if (i < static_cast<int>(initial.size())) tally -= initial[i];
  }
  atoms.remove(remove);

  // 6. the grains' support force now (deleted, made, rescaled grains changed it): the MPM
  // process balances the points' reaction with it
  now = atoms.grains();
  double force_local[3] = {0.0, 0.0, 0.0}, force[3];
  for (int i = 0; i < now.n; i++)
    for (int a = 0; a < 3; a++) force_local[a] += now.rmass[i] * support[i][a];
  MPI_Allreduce(force_local, force, 3, MPI_DOUBLE, MPI_SUM, comm);
  out = session.settle(session.rezone_finish(force, ack));

  const std::int64_t local[2] = {deleted_local, made_local};
  std::int64_t all[2];
  MPI_Allreduce(local, all, 2, MPI_INT64_T, MPI_SUM, comm);
  counts.deleted = all[0], counts.made = all[1];
  double energy_local[RezoneGrainEnergy::kSums], energy_all[RezoneGrainEnergy::kSums];
  energy.to_array(energy_local);
  MPI_Allreduce(energy_local, energy_all, RezoneGrainEnergy::kSums, MPI_DOUBLE, MPI_SUM, comm);
  counts.energy = RezoneGrainEnergy::from_array(energy_all);
  return out;
}

RezoneReport rezone_report(std::int64_t step, const RezoneCounts &counts, const StepAck &ack, double weight,
                           const RezoneAftermath &after) {
  RezoneReport r;
  r.step = step, r.weight = weight, r.lightest = -after.drift[0], r.heaviest = after.drift[1];
  r.mean_carried = after.share_sums[1] > 0 ? after.share_sums[0] / after.share_sums[1] : 1.0;
  r.grains_deleted = counts.deleted, r.grains_made = counts.made, r.hybrid_grains = after.hybrid_grains;
  r.points_made = ack.points_made, r.moved_cells = ack.moved_cells;
  r.continuum_cells = ack.zone_cells[kContinuum], r.hybrid_cells = ack.zone_cells[kHybrid];
  r.discrete_cells = ack.zone_cells[kDiscrete];
  r.rests_moved = ack.rests_moved, r.rests_kept = ack.rests_kept;
  r.grain_energy = counts.energy;
  return r;
}

RezoneAftermath rezone_aftermath(const DemGrains &g, const GrainRules &rules, std::int64_t max_tag, MPI_Comm comm) {
  RezoneAftermath a;
  double drift[2], sums[2];
  mass_drift(g, rules, drift, sums);
  MPI_Allreduce(drift, a.drift, 2, MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(sums, a.share_sums, 2, MPI_DOUBLE, MPI_SUM, comm);
  const std::int64_t hybrid = hybrid_grain_count(g);    // all of them, not only the rezoned cells'
  MPI_Allreduce(&hybrid, &a.hybrid_grains, 1, MPI_INT64_T, MPI_SUM, comm);
  MPI_Allreduce(&max_tag, &a.max_tag, 1, MPI_INT64_T, MPI_MAX, comm);
  return a;
}

void rezone_totals(const double grains_before[7], const double grains_after[7], const StepAck &ack, double before[7],
                   double after[7]) {
  const double points_after[7] = {ack.mass,       ack.momentum[0], ack.momentum[1], ack.momentum[2],
                                  ack.angular[0], ack.angular[1],  ack.angular[2]};
  for (int k = 0; k < 7; k++) before[k] = grains_before[k] + ack.before[k], after[k] = grains_after[k] + points_after[k];
}

std::string new_atoms_problem(std::int64_t made, std::int64_t deleted, std::int64_t natoms, std::int64_t max_natoms,
                              std::int64_t max_tag, std::int64_t max_id, std::int64_t step,
                              const std::string &host, const std::string &id_hint) {
  // as fix deposit and fix pour do: made grains must not overflow the atom count or the IDs
  if (made > deleted && made - deleted > max_natoms - natoms)
    return "too many total atoms: making " + std::to_string(made) + " grains from points at step " +
           std::to_string(step) + " would exceed the largest atom count " + host + " allows (" +
           std::to_string(max_natoms) + ")";
  if (made > 0 && made >= max_id - max_tag)
    return "new atom IDs exceed the largest ID allowed (" + std::to_string(max_id) + "): making " +
           std::to_string(made) + " grains from points at step " + std::to_string(step) + " after ID " +
           std::to_string(max_tag) + "; " + id_hint;
  return "";
}


Hello make_hello(const FixOptions &options, const std::string &host, const std::string &units, int dimension,
                 double dt, const double box_lo[3], const double box_hi[3], std::int64_t step, double time,
                 std::string &problem) {
  Hello hello;
  set_text(hello.host, host);
  set_text(hello.units, units);
  hello.dimension = dimension;
  hello.model = options.model;
  hello.mpm_every = options.every;
  hello.cell = options.cell;
  hello.dt = dt;
  hello.reply_timeout = options.reply_timeout;
  hello.idle_timeout = options.idle_timeout;
  for (int d = 0; d < 3; d++) hello.box_lo[d] = box_lo[d], hello.box_hi[d] = box_hi[d];
  hello.step = step;
  hello.time = time;
  hello.continuum = options.continuum;
  problem.clear();
  for (int d = 0; d < 3; d++)
    for (int side = 0; side < 2; side++) {
      const double v = options.container_edge(d, side, box_lo, box_hi);
      if ((v < box_lo[d] || v > box_hi[d]) && problem.empty())
        problem = std::string("container ") + "xyz"[d] + (side ? " hi" : " lo") + " = " + shortest(v) +
                  " lies outside the box (" + shortest(box_lo[d]) + " to " + shortest(box_hi[d]) + ")";
      (side ? hello.continuum.container_hi : hello.continuum.container_lo)[d] = v;
    }
  return hello;
}

GroupGrains group_grains(const DemGrains &g, const int *type, int ntypes, int dimension, MPI_Comm comm) {
  // sums: diameters, solid masses, volumes; extremes: -min and max diameter, -min and max
  // solid density of the grains of weight 1
  double sums[3] = {0, 0, 0}, extremes[4] = {-1e300, -1e300, -1e300, -1e300};
  int mask = ~0, smallest = ntypes + 1;
  std::int64_t counts[2] = {0, 0};    // grains, grains with a weight below 1
  for (int i = 0; i < g.n; i++) {
    if (!g.coupled(i)) continue;
    const double r = g.radius[i], solid_mass = g.rmass[i] / std::max(g.weight[i], 1e-300), volume = grain_volume(dimension, r);
    sums[0] += 2.0 * r;
    sums[1] += solid_mass;
    sums[2] += volume;
    extremes[0] = std::max(extremes[0], -2.0 * r);
    extremes[1] = std::max(extremes[1], 2.0 * r);
    if (g.weight[i] < 1.0) {
      counts[1]++;
    } else {
      extremes[2] = std::max(extremes[2], -solid_mass / volume);
      extremes[3] = std::max(extremes[3], solid_mass / volume);
    }
    mask &= g.mask[i];
    smallest = std::min(smallest, type[i]);
    counts[0]++;
  }
  GroupGrains gg;
  double all[3], extremes_all[4];
  std::int64_t counts_all[2];
  MPI_Allreduce(sums, all, 3, MPI_DOUBLE, MPI_SUM, comm);
  MPI_Allreduce(extremes, extremes_all, 4, MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(&mask, &gg.common_mask, 1, MPI_INT, MPI_BAND, comm);
  MPI_Allreduce(&smallest, &gg.smallest_type, 1, MPI_INT, MPI_MIN, comm);
  MPI_Allreduce(counts, counts_all, 2, MPI_INT64_T, MPI_SUM, comm);
  gg.count = counts_all[0], gg.weighted = counts_all[1];
  gg.diameter_sum = all[0], gg.solid_mass_sum = all[1], gg.volume_sum = all[2];
  gg.dmin = -extremes_all[0], gg.dmax = extremes_all[1];
  if (gg.count > gg.weighted) gg.density_min = -extremes_all[2], gg.density_max = extremes_all[3];
  return gg;
}

int apply_group_defaults(FixOptions &options, const GroupGrains &gg, int groupbit, double &polydispersity) {
  // mu(I) needs the grain size and solid density; unless given, take them from the grains
  if (gg.count > 0 && !options.diameter_given) options.continuum.grain_diameter = gg.diameter_sum / gg.count;
  if (gg.volume_sum > 0 && !options.density_given) options.continuum.grain_density = gg.solid_mass_sum / gg.volume_sum;
  if (gg.count == 0) {
    if (options.grain_type == 0) options.grain_type = 1;
    return 1 | groupbit;
  }
  // the template's radii are uniform in mean (1 +- p); it needs p < 0.5
  polydispersity = std::min(0.45, (gg.dmax - gg.dmin) / (gg.dmax + gg.dmin));
  if (options.grain_type == 0) options.grain_type = gg.smallest_type;
  return gg.common_mask | 1 | groupbit;
}

std::string density_problem(const FixOptions &options, const GroupGrains &gg, int dimension) {
  // one grain at (1 - tolerance) of the solid density would count as light (kLightGrains)
  const double tolerance = 1.0 - kLightGrains;
  if (gg.weighted > 0 || gg.count == 0 || !(gg.volume_sum > 0)) return "";
  const char *per = dimension == 2 ? "per unit area: mass over pi r^2" : "mass over 4/3 pi r^3";
  if (gg.density_max > (1.0 + tolerance) * gg.density_min)
    return "the group's grains have solid densities from " + general(gg.density_min, 4) + " to " +
           general(gg.density_max, 4) + " (" + per + "), but grains and material points convert at one solid "
           "density (a rezone gives every grain it touches that density's mass): give the group's grains one "
           "density" + std::string(dimension == 2 ? " (a 2D deck: set density/disc, which is per unit area; "
                                                    "set density gives disks a sphere's mass)" : "");
  const double own = gg.solid_mass_sum / gg.volume_sum;
  if (options.density_given && std::abs(options.continuum.grain_density / own - 1.0) > tolerance)
    return "grain_density " + general(options.continuum.grain_density, 4) + " is not the group's grains' own " +
           "solid density " + general(own, 4) + " (" + per + "); grains and material points convert at one " +
           "solid density: drop grain_density (the fix takes the grains') or give the grains that density";
  return "";
}

namespace {
// centre of cell c as a 3-vector (z = 0 in 2D)
template <int D>
void centre_of(const GridGeometry<D> &grid, std::size_t c, double centre[3]) {
  const auto x = cell_center<D>(grid, cell_coords<D>(grid, c));
  centre[0] = centre[1] = centre[2] = 0.0;
  for (int d = 0; d < D; d++) centre[d] = x[d];
}
}    // namespace

template <int D>
int first_empty_region(const GridGeometry<D> &grid, const double box_lo[3], const double box_hi[3], int n,
                       const std::function<bool(int, const double *)> &match) {
  const std::size_t ncells = num_cells<D>(grid);
  double centre[3];
  for (int k = 0; k < n; ++k) {
    bool any = false;
    for (std::size_t c = 0; c < ncells && !any; ++c) {
      centre_of<D>(grid, c, centre);
      bool in_box = true;
      for (int d = 0; d < D; d++) in_box = in_box && centre[d] >= box_lo[d] && centre[d] <= box_hi[d];
      any = in_box && match(k, centre);
    }
    if (!any) return k;
  }
  return -1;
}

namespace {
// the cell of this centre and width dx overlaps the box [lo, hi] (on the first D axes; a cell that
// only shares a face with it does not: a box face may lie on the cell lattice)
template <int D>
bool cell_overlaps(const double centre[3], double dx, const double lo[3], const double hi[3]) {
  for (int d = 0; d < D; d++)
    if (centre[d] + 0.5 * dx <= lo[d] || centre[d] - 0.5 * dx >= hi[d]) return false;
  return true;
}

// region r holds one of cell c's sample points (the centre first: most cells a region touches hold it)
template <int D>
bool samples_inside(const GridGeometry<D> &grid, std::size_t c, const RegionShape &r) {
  double centre[3], x[3];
  centre_of<D>(grid, c, centre);
  if (r.bounded && !cell_overlaps<D>(centre, grid.dx, r.lo, r.hi)) return false;
  if (r.inside(centre)) return true;
  constexpr int n = kCellSamplesPerAxis;
  int samples = 1;
  for (int d = 0; d < D; d++) samples *= n;
  for (int s = 0; s < samples; ++s) {
    int rest = s;
    x[2] = 0.0;
    for (int d = 0; d < D; d++, rest /= n) x[d] = centre[d] + ((rest % n + 0.5) / n - 0.5) * grid.dx;
    if (r.inside(x)) return true;
  }
  return false;
}
}    // namespace

template <int D>
std::vector<std::uint64_t> cells_touched(const GridGeometry<D> &grid, const std::vector<RegionShape> &regions) {
  std::vector<std::uint64_t> cells;
  if (regions.empty()) return cells;
  const std::size_t ncells = num_cells<D>(grid);
  for (std::size_t c = 0; c < ncells; ++c)
    for (const RegionShape &r : regions)
      if (samples_inside<D>(grid, c, r)) {
        cells.push_back(c);
        break;
      }
  return cells;
}

template <int D>
int first_untouching_region(const GridGeometry<D> &grid, const double box_lo[3], const double box_hi[3],
                            const std::vector<RegionShape> &regions) {
  const std::size_t ncells = num_cells<D>(grid);
  for (std::size_t k = 0; k < regions.size(); ++k) {
    bool any = false;
    double centre[3];
    for (std::size_t c = 0; c < ncells && !any; ++c) {
      centre_of<D>(grid, c, centre);
      any = cell_overlaps<D>(centre, grid.dx, box_lo, box_hi) && samples_inside<D>(grid, c, regions[k]);
    }
    if (!any) return static_cast<int>(k);
  }
  return -1;
}

template <int D>
void zone_counts(const GridGeometry<D> &grid, const std::vector<signed char> &zones, const double box_lo[3],
                 const double box_hi[3], std::int64_t counts[3]) {
  counts[0] = counts[1] = counts[2] = 0;
  double centre[3];
  for (std::size_t c = 0; c < zones.size(); ++c) {
    centre_of<D>(grid, c, centre);
    if (cell_overlaps<D>(centre, grid.dx, box_lo, box_hi)) counts[zones[c]]++;    // a face may lie off the lattice
  }
}

std::string zone_counts_line(const std::int64_t n[3]) {
  return "fix hybrid/mpm: " + std::to_string(n[0] + n[1] + n[2]) + " grid cells in the box: " +
         std::to_string(n[kContinuum]) + " continuum, " + std::to_string(n[kHybrid]) + " hybrid, " +
         std::to_string(n[kDiscrete]) + " discrete";
}

template int first_empty_region<2>(const GridGeometry<2> &, const double[3], const double[3], int,
                                   const std::function<bool(int, const double *)> &);
template int first_empty_region<3>(const GridGeometry<3> &, const double[3], const double[3], int,
                                   const std::function<bool(int, const double *)> &);
template std::vector<std::uint64_t> cells_touched<2>(const GridGeometry<2> &, const std::vector<RegionShape> &);
template std::vector<std::uint64_t> cells_touched<3>(const GridGeometry<3> &, const std::vector<RegionShape> &);
template int first_untouching_region<2>(const GridGeometry<2> &, const double[3], const double[3],
                                        const std::vector<RegionShape> &);
template int first_untouching_region<3>(const GridGeometry<3> &, const double[3], const double[3],
                                        const std::vector<RegionShape> &);
template void zone_counts<2>(const GridGeometry<2> &, const std::vector<signed char> &, const double[3],
                             const double[3], std::int64_t[3]);
template void zone_counts<3>(const GridGeometry<3> &, const std::vector<signed char> &, const double[3],
                             const double[3], std::int64_t[3]);

void RestartRecord::write(double out[kValues]) const {
  out[0] = cell, out[1] = static_cast<double>(exchanges), out[2] = static_cast<double>(every);
  out[3] = converted ? 1.0 : 0.0, out[4] = time, out[5] = static_cast<double>(step);
}

RestartRecord RestartRecord::read(const double *in) {
  RestartRecord r;
  r.cell = in[0], r.exchanges = static_cast<std::int64_t>(in[1]), r.every = static_cast<int>(in[2]);
  r.converted = in[3] != 0.0, r.time = in[4], r.step = static_cast<std::int64_t>(in[5]);
  return r;
}

void RestartRecord::write_file(std::FILE *fp) const {
  double list[kValues];
  write(list);
  const int size = sizeof(list);
  std::fwrite(&size, sizeof(int), 1, fp);
  std::fwrite(list, sizeof(double), kValues, fp);
}

std::string frameless_run_warning(int output_every, std::int64_t run_exchanges, std::int64_t run_steps, int every) {
  if (output_every <= 0 || run_exchanges > 0) return "";
  return "Fix hybrid/mpm: this run of " + std::to_string(run_steps) + " step(s) had no exchange (every " +
         std::to_string(every) + "), so it wrote no output frame; frames are those of exchanges: make the run " +
         "reach a multiple of every, or lower every";
}

std::int64_t next_exchange_step(const ExchangeOutlook &o) {
  const std::int64_t next = o.now + o.every;
  if (o.rezone_next || o.restart_file || next > o.last_step) return -1;
  return next;
}

std::string RestartRecord::take_cell(double &input_cell) const {
  if (input_cell <= 0.0) input_cell = cell;
  if (cell == input_cell) return "";
  return "Fix hybrid/mpm: restart file has cell " + shortest(cell) + ", the input says " + shortest(input_cell) +
         "; using " + shortest(input_cell);
}

std::string RestartRecord::state_problem(const std::string &mpm_state_path) const {
  if (!converted || !mpm_state_path.empty()) return "";
  return "Fix hybrid/mpm: the restart file was written after grains became material points; add the keyword "
         "'mpm_state FILE' with the MPM state written next to it (<restart file>.mpm.h5)";
}

std::string state_line(int kind, const std::string &path, std::int64_t points) {
  return std::string("fix hybrid/mpm: MPM state ") + (kind == kStepSave ? "saved to " : "loaded from ") + path + " (" +
         std::to_string(points) + " material points)";
}

std::string gravity_change_problem(const double then[3], const double now[3]) {
  const double scale = std::max(std::sqrt(then[0] * then[0] + then[1] * then[1] + then[2] * then[2]),
                                std::sqrt(now[0] * now[0] + now[1] * now[1] + now[2] * now[2]));
  bool same = true;
  for (int d = 0; d < 3; d++) same = same && std::fabs(now[d] - then[d]) <= 1e-12 * scale;    // round-off only
  if (same) return "";
  auto vec = [](const double *g) { return "(" + shortest(g[0]) + ", " + shortest(g[1]) + ", " + shortest(g[2]) + ")"; };
  return "Fix hybrid/mpm: gravity changed since the coupled run started: " + vec(then) + " m/s^2 then, " + vec(now) +
         " now. The MPM process keeps the gravity of the handshake (and the energy ledger its potential energy): "
         "keep the fix gravity commands unchanged while fix hybrid/mpm is defined";
}

std::string apply_deck_material(FixOptions &options, DeckContact deck) {
  const CalibratedMaterial &m = *options.material;
  deck.mean_mass = options.continuum.grain_density * grain_volume(deck.dimension, 0.5 * options.continuum.grain_diameter);
  const std::string mismatch = contact_mismatch(m, deck);
  if (!mismatch.empty())
    return "Fix hybrid/mpm: material " + m.path + " was calibrated for another contact law (" + mismatch +
           "); measure the continuum's constants for this one (docs/design.md section 4.6)";
  apply_material(m, deck.kn, options.continuum.grain_diameter, options.continuum);
  if (options.fill_auto) options.continuum.fill_modulus = compaction_modulus(m, deck.kn, options.continuum.grain_diameter);
  return "";
}

std::string material_line(const FixOptions &options) {
  const CalibratedMaterial &m = *options.material;
  const ContinuumSettings &c = options.continuum;
  return "fix hybrid/mpm: material " + m.name + " (" + m.path + "): Young's modulus " + general(c.youngs_modulus, 6) +
         " Pa, Poisson's ratio " + general(c.poisson_ratio, 3) + ", friction angle " + general(c.friction_angle_deg, 4) +
         " deg, mu_s " + general(c.mu_s, 4) + ", mu_2 " + general(c.mu_2, 4) + ", I0 " + general(c.I0, 4) +
         ", critical packing " + general(c.critical_packing, 4) +
         (options.fill_auto ? ", fill pressure modulus " + general(c.fill_modulus, 4) + " Pa" : "");
}

MPI_Comm start_dem_job(int *argc, char ***argv, const char *program, const std::string &host) {
  MPI_Init(argc, argv);
  int me = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &me);
  MPI_Comm dem_comm = MPI_COMM_NULL;
  MPI_Comm_split(MPI_COMM_WORLD, kDemColor, me, &dem_comm);
  try {
    install_dem_finalize_hook(dem_comm, host);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "%s: ERROR: %s\n", program, e.what());
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  set_world_barrier_by_hook(true);
  return dem_comm;
}

void end_dem_job(MPI_Comm dem_comm, const std::string &unconnected) {
  set_unconnected_exit_reason(unconnected);
  dem_end_of_job();    // AbortNote if nothing was coupled, MPI_Barrier(MPI_COMM_WORLD)
  MPI_Comm_free(&dem_comm);
  MPI_Finalize();
}

std::string finish_coupled_run(Link &link, std::int64_t last_step, std::string &warning) {
  std::string line;
  try {
    link.finish(last_step);
    line = "fix hybrid/mpm: finished the coupled run after " + std::to_string(link.exchanges()) + " exchange(s)";
  } catch (const PeerError &e) {
    warning = e.what();
  }
  set_peer(nullptr);
  return line;
}

template StepOutcome exchange_grains<2>(DemSession &, MPI_Comm, GrainTransfer<2> &, const DemGrains &,
                                        const std::vector<int> &, StepHeader, double, double **, std::vector<int> &,
                                        const std::function<std::vector<GrainRecord>()> &, StepAck &,
                                        ExchangeTally &);
template StepOutcome exchange_grains<3>(DemSession &, MPI_Comm, GrainTransfer<3> &, const DemGrains &,
                                        const std::vector<int> &, StepHeader, double, double **, std::vector<int> &,
                                        const std::function<std::vector<GrainRecord>()> &, StepAck &,
                                        ExchangeTally &);
template StepOutcome ask_zones<2>(DemSession &, const RezonePlan<2> &, const std::vector<signed char> &,
                                  RezoneAtoms<2> &, ZoneAnswer<2> &);
template StepOutcome ask_zones<3>(DemSession &, const RezonePlan<3> &, const std::vector<signed char> &,
                                  RezoneAtoms<3> &, ZoneAnswer<3> &);
template StepOutcome move_material<2>(DemSession &, MPI_Comm, const RezonePlan<2> &,
                                      const std::vector<RezoneCell<2>> &, RezoneAtoms<2> &, double *const *,
                                      StepAck &, RezoneCounts &);
template StepOutcome move_material<3>(DemSession &, MPI_Comm, const RezonePlan<3> &,
                                      const std::vector<RezoneCell<3>> &, RezoneAtoms<3> &, double *const *,
                                      StepAck &, RezoneCounts &);

std::string guarded_thermo_vector(const EnergyLedger &ledger, MPI_Comm comm, const StepAck &ack,
                                  std::int64_t exchanges, std::int64_t coupled_grains, const double grain_totals[7],
                                  double continuum_start, EnergyGuard *guard, double time, double out[kVecSize]) {
  double local[EnergyLedger::kSums], sums[EnergyLedger::kSums];
  ledger.sums(local);
  MPI_Allreduce(local, sums, EnergyLedger::kSums, MPI_DOUBLE, MPI_SUM, comm);
  thermo_vector(ack, exchanges, coupled_grains, grain_totals, sums, continuum_start, out);
  if (!guard) return std::string();
  std::string made = guard->check(out, time);
  out[kVecGuardShare] = guard->largest_share();
  return made;
}

}    // namespace coupler
