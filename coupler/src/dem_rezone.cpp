#include "coupler/dem_rezone.hpp"

#include <algorithm>
#include <cmath>

#include "coupler/conversion.hpp"
#include "coupler/tuning.hpp"

namespace coupler {
namespace {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;

}    // namespace

template <int D>
std::int64_t slot_of_cell_at(const GridGeometry<D> &grid, const double *x, const CellSlots &slots) {
  const auto c = cell_of<D>(grid, Eigen::Map<const Vec<D>>(x));
  if ((c.array() < 0).any() || (c.array() >= grid.dims.array() - 1).any()) return -1;
  const auto it = slots.find(cell_index<D>(grid, c));
  return it == slots.end() ? -1 : static_cast<std::int64_t>(it->second);
}

template <int D>
std::map<std::size_t, GrainSums<D>> moving_grain_sums(const GridGeometry<D> &grid,
                                                      const std::vector<RezoneCell<D>> &cells,
                                                      const CellSlots &slots, const DemGrains &g,
                                                      const GrainRules &rules) {
  std::map<std::size_t, GrainSums<D>> sums;
  for (int i = 0; i < g.n; i++) {
    if (!g.coupled(i)) continue;
    const std::int64_t k = slot_of_cell_at<D>(grid, g.x[i], slots);
    if (k < 0) continue;
    Spin<D> omega_i;
    if constexpr (D == 2) omega_i[0] = g.omega[i][2];
    else omega_i = Eigen::Map<const Eigen::Vector3d>(g.omega[i]);
    Eigen::Matrix<double, D, D> sv;
    const double *sa = g.stress[i];    // xx yy zz xy xz yz
    if constexpr (D == 2) sv << sa[0], sa[3], sa[3], sa[1];
    else sv << sa[0], sa[3], sa[4], sa[3], sa[1], sa[5], sa[4], sa[5], sa[2];
    const auto c = cell_coords<D>(grid, cells[k].cell);
    const Vec<D> centre = cell_center<D>(grid, c), xi = Eigen::Map<const Vec<D>>(g.x[i]),
                 vi = Eigen::Map<const Vec<D>>(g.v[i]);
    const double e = rules.inertia * g.radius[i] * g.radius[i], solid = rules.solid_mass(g.radius[i]);
    const double m = g.rmass[i];
    auto &sum = sums[static_cast<std::size_t>(k)];
    sum.carried.moments.cell = sum.solid.moments.cell = cells[k].cell;
    sum.carried.add_body(xi, vi, m, m * e * omega_i, e, sv, centre);
    sum.solid.add_body(xi, vi, solid, solid * e * omega_i, e, Eigen::Matrix<double, D, D>::Zero(), centre);
  }
  return sums;
}

template <int D>
void sum_over_ranks(std::vector<BodySums<D>> &sums, MPI_Comm comm) {
  constexpr std::size_t values = kBodySumsValues<D>;
  std::vector<double> local(sums.size() * values), all(sums.size() * values);
  for (std::size_t k = 0; k < sums.size(); ++k) pack_summed_fields<D>(sums[k], &local[k * values]);
  MPI_Allreduce(local.data(), all.data(), static_cast<int>(local.size()), MPI_DOUBLE, MPI_SUM, comm);
  for (std::size_t k = 0; k < sums.size(); ++k) unpack_summed_fields<D>(&all[k * values], sums[k]);
}

template <int D>
std::vector<PlannedGrain<D>> plan_new_grains(const GridGeometry<D> &grid, const std::vector<RezoneCell<D>> &cells,
                                             const std::map<std::size_t, GrainSums<D>> &sums, const DemGrains &g,
                                             const PackingTemplate<D> &tmpl, const GrainRules &rules,
                                             double grain_diameter, const double lo[3], const double hi[3],
                                             MPI_Comm comm) {
  using Mat = Eigen::Matrix<double, D, D>;
  constexpr double kBig = 1.0e20;
  std::vector<PlannedGrain<D>> planned;
  std::vector<std::size_t> making;    // slots of the cells that make grains
  for (std::size_t k = 0; k < cells.size(); ++k)
    if (cells[k].make_grains) making.push_back(k);
  if (making.empty()) return planned;

  // the old grains of these cells, over all ranks: what they carry, and their sums at their
  // solid mass (as members of the new body set)
  std::vector<BodySums<D>> carried(making.size()), solid(making.size());
  for (std::size_t j = 0; j < making.size(); ++j) {
    const auto it = sums.find(making[j]);
    if (it != sums.end()) carried[j] = it->second.carried, solid[j] = it->second.solid;
  }
  sum_over_ranks<D>(carried, comm);
  sum_over_ranks<D>(solid, comm);

  // candidates of every such cell (the same list on every rank)
  std::vector<std::vector<NewGrain<D>>> candidates(making.size());
  std::map<std::size_t, std::vector<std::pair<std::size_t, std::size_t>>> by_cell;    // cell -> (j, index)
  double largest = 0.0;
  for (std::size_t j = 0; j < making.size(); ++j) {
    const auto &cell = cells[making[j]];
    const auto c = cell_coords<D>(grid, cell.cell);
    for (const auto &candidate : template_candidates<D>(cell.cell, grid, tmpl, grain_diameter)) {
      if (!(occupancy_bit<D>(grid, c, candidate.x) & cell.occupancy)) continue;    // no material there
      // inside the continuum's container (where its points are held; a silo's floor blocks lie
      // outside it, and a grain made inside a wall would be shot out by the wall's contact)
      bool inside = true;
      for (int a = 0; a < D; ++a)
        inside = inside && candidate.x[a] - candidate.radius >= lo[a] && candidate.x[a] + candidate.radius <= hi[a];
      if (!inside) continue;
      by_cell[cell.cell].emplace_back(j, candidates[j].size());
      candidates[j].push_back(candidate);
      largest = std::max(largest, candidate.radius);
    }
  }
  // room of each candidate: the largest radius no grain (of any group: walls of frozen grains
  // too) overlaps. A candidate a grain overlaps a little shrinks to fit, down to
  // kSmallestShrink of its size, so the new packing closes up with the old one; one that would
  // have to shrink more is dropped.
  std::vector<std::size_t> offset(making.size() + 1, 0);
  for (std::size_t j = 0; j < making.size(); ++j) offset[j + 1] = offset[j] + candidates[j].size();
  std::vector<double> room(offset.back(), kBig), room_all(offset.back(), kBig);
  for (int i = 0; i < g.n; i++) {
    const Vec<D> xi = Eigen::Map<const Vec<D>>(g.x[i]);
    const int reach = static_cast<int>(std::ceil((g.radius[i] + largest) / grid.dx));
    for_each_cell_within<D>(grid, cell_of<D>(grid, xi), reach, [&](std::uint64_t cell) {
      const auto it = by_cell.find(cell);
      if (it == by_cell.end()) return;
      for (const auto &[j, n] : it->second) {
        double &r = room[offset[j] + n];
        r = std::min(r, (candidates[j][n].x - xi).norm() - g.radius[i]);
      }
    });
  }
  MPI_Allreduce(room.data(), room_all.data(), static_cast<int>(room.size()), MPI_DOUBLE, MPI_MIN, comm);

  for (std::size_t j = 0; j < making.size(); ++j) {
    const auto &cell = cells[making[j]];
    std::vector<NewGrain<D>> kept;
    for (std::size_t n = 0; n < candidates[j].size(); ++n) {
      NewGrain<D> candidate = candidates[j][n];
      // a gap of kTemplateGap diameters, as between template grains
      const double fit = room_all[offset[j] + n] - kTemplateGap * grain_diameter;
      if (fit < kSmallestShrink * candidate.radius) continue;
      candidate.radius = std::min(candidate.radius, fit);
      kept.push_back(candidate);
    }
    CellMoments<D> material = cell.points;
    material.add(carried[j].moments);
    if (!(material.mass > 0)) continue;
    // the new grains move with the continuum's affine field about its centre of mass
    const Vec<D> centre = cell_center<D>(grid, cell_coords<D>(grid, cell.cell));
    const Vec<D> about = cell.points.mass > 0 ? Vec<D>(cell.points.first_moment() / cell.points.mass) : centre;
    const Vec<D> drift = cell.points.mass > 0 ? Vec<D>(cell.points.momentum() / cell.points.mass) : Vec<D>::Zero();
    const Mat gradient = Eigen::Map<const Mat>(cell.gradient);
    // as many new grains as the material fills at their solid mass, nearest its centre first
    // (the same order on every rank)
    std::stable_sort(kept.begin(), kept.end(), [&](const auto &a, const auto &b) {
      return (a.x - about).squaredNorm() < (b.x - about).squaredNorm();
    });
    double filled = solid[j].moments.mass;    // the old grains' and the fitted new ones' solid mass
    for (auto &grain : kept) {
      grain.mass = rules.solid_mass(grain.radius);
      if (filled + 0.5 * grain.mass > material.mass) break;
      grain.v = drift + gradient * (grain.x - about);
      grain.omega.setZero();
      filled += grain.mass;
      planned.push_back({making[j], grain, cell.grain_weight, centre});
    }
  }
  return planned;
}

template <int D>
void add_new_grain(std::map<std::size_t, GrainSums<D>> &sums, const std::vector<RezoneCell<D>> &cells,
                   const PlannedGrain<D> &p, const GrainRules &rules) {
  const NewGrain<D> &grain = p.grain;
  auto &sum = sums[p.slot];
  sum.solid.moments.cell = sum.carried.moments.cell = cells[p.slot].cell;
  sum.solid.add_body(grain.x, grain.v, grain.mass, Spin<D>::Zero(), rules.inertia * grain.radius * grain.radius,
                     Eigen::Matrix<double, D, D>::Zero(), p.centre);
}

template <int D>
std::vector<char> apply_corrections(const GridGeometry<D> &grid, const std::vector<RezoneCell<D>> &cells,
                                    const CellSlots &slots, const std::vector<GrainCorrection<D>> &corrections,
                                    DemGrains &g, const GrainRules &rules) {
  std::map<std::uint64_t, const GrainCorrection<D> *> correction_of;
  for (const auto &gc : corrections) correction_of[gc.cell] = &gc;
  std::vector<char> remove(g.n, 0);
  for (int i = 0; i < g.n; i++) {
    if (!g.coupled(i)) continue;
    const std::int64_t k = slot_of_cell_at<D>(grid, g.x[i], slots);
    if (k < 0) continue;
    const auto it = correction_of.find(cells[k].cell);
    if (it == correction_of.end()) continue;
    const GrainCorrection<D> &gc = *it->second;
    if (gc.remove) {
      remove[i] = 1;
      continue;
    }
    RigidCorrection<D> fix;
    fix.mass_factor = gc.mass_factor;
    fix.velocity = Eigen::Map<const Vec<D>>(gc.velocity);
    fix.omega = Eigen::Map<const Spin<D>>(gc.omega);
    fix.centre = Eigen::Map<const Vec<D>>(gc.centre);
    const Vec<D> dv = fix.increment(Eigen::Map<const Vec<D>>(g.x[i]));
    for (int a = 0; a < D; ++a) g.v[i][a] += dv[a];
    if constexpr (D == 2) g.omega[i][2] += fix.omega[0];
    else
      for (int a = 0; a < 3; a++) g.omega[i][a] += fix.omega[a];
    g.rmass[i] = gc.mass_factor * rules.solid_mass(g.radius[i]);    // the correction scales the solid sums
    g.weight[i] = gc.weight;
  }
  return remove;
}

#define HYBRID_DEM_REZONE(D)                                                                                        \
  template std::int64_t slot_of_cell_at<D>(const GridGeometry<D> &, const double *, const CellSlots &);            \
  template std::map<std::size_t, GrainSums<D>> moving_grain_sums<D>(                                               \
      const GridGeometry<D> &, const std::vector<RezoneCell<D>> &, const CellSlots &, const DemGrains &,            \
      const GrainRules &);                                                                                          \
  template void sum_over_ranks<D>(std::vector<BodySums<D>> &, MPI_Comm);                                           \
  template std::vector<PlannedGrain<D>> plan_new_grains<D>(                                                        \
      const GridGeometry<D> &, const std::vector<RezoneCell<D>> &, const std::map<std::size_t, GrainSums<D>> &,    \
      const DemGrains &, const PackingTemplate<D> &, const GrainRules &, double, const double *, const double *,   \
      MPI_Comm);                                                                                                    \
  template void add_new_grain<D>(std::map<std::size_t, GrainSums<D>> &, const std::vector<RezoneCell<D>> &,        \
                                 const PlannedGrain<D> &, const GrainRules &);                                     \
  template std::vector<char> apply_corrections<D>(const GridGeometry<D> &, const std::vector<RezoneCell<D>> &,     \
                                                  const CellSlots &, const std::vector<GrainCorrection<D>> &,      \
                                                  DemGrains &, const GrainRules &);
HYBRID_DEM_REZONE(2)
HYBRID_DEM_REZONE(3)

}    // namespace coupler
