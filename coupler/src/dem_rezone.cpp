#include "coupler/dem_rezone.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "coupler/conversion.hpp"
#include "coupler/tuning.hpp"
#include "coupler/zones.hpp"

namespace coupler {
namespace {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;

/// Most Gauss-Seidel sweeps that push made grains off the old ones and each other
/// (relax_candidates; each push is at most a fifth of a radius). A candidate still overlapped
/// after them shrinks to fit, so the bound costs size, never an overlap.
constexpr int kRelaxSweeps = 100;

/// A grain in the candidates' way: centre and radius.
template <int D>
struct Obstacle {
  Vec<D> x;
  double radius;
};

/// A candidate being fitted: where it is now, where the template put it, its radius, which
/// making cell (j) and which of its candidates (n), its cell's lower corner, what is near it.
template <int D>
struct Fitting {
  Vec<D> x, home;
  double radius;
  std::size_t j, n;
  Vec<D> cell_lo;
  std::vector<std::size_t> obstacles, others;    // indices of obstacles and fitting candidates near
};

/// Indices of positions by the grid cell holding them. Positions off the grid are left out: the
/// grid's padding cells keep them far from every candidate (candidates lie in the container).
template <int D>
class CellBins {
 public:
  explicit CellBins(const GridGeometry<D> &grid) : grid_(grid) {}
  void add(const Vec<D> &x, std::size_t i) {
    const Eigen::Matrix<int, D, 1> c = cell_of<D>(grid_, x);
    if (cell_on_grid<D>(grid_, c)) bins_[cell_index<D>(grid_, c)].push_back(i);
  }
  /// Calls f(i) for every position added within `distance` of x (and some farther).
  template <class F>
  void near(const Vec<D> &x, double distance, F &&f) const {
    for_each_cell_within<D>(grid_, cell_of<D>(grid_, x), static_cast<int>(std::ceil(distance / grid_.dx)),
                            [&](std::uint64_t cell) {
                              const auto it = bins_.find(cell);
                              if (it != bins_.end())
                                for (std::size_t i : it->second) f(i);
                            });
  }

 private:
  const GridGeometry<D> &grid_;
  std::map<std::uint64_t, std::vector<std::size_t>> bins_;
};

/// Every rank's atoms (of any group) within `distance` of a candidate's cell, the same list in
/// the same order on every rank (collective).
template <int D>
std::vector<Obstacle<D>> obstacles_near(const GridGeometry<D> &grid, const DemGrains &g,
                                        const std::set<std::uint64_t> &candidate_cells, double distance,
                                        MPI_Comm comm) {
  // each cell's distance (cells along the farthest axis) to the nearest candidate cell, up to the
  // farthest reach of a grain here: one look-up per grain (the grains of a large scene are many,
  // the cells making grains at a rezone few)
  double largest_radius = 0;
  for (int i = 0; i < g.n; i++) largest_radius = std::max(largest_radius, g.radius[i]);
  const int farthest = static_cast<int>(std::ceil((largest_radius + distance) / grid.dx));
  std::vector<int> cells_away(num_cells<D>(grid), std::numeric_limits<int>::max());
  for (std::uint64_t candidate : candidate_cells) {
    const Eigen::Matrix<int, D, 1> c = cell_coords<D>(grid, candidate);
    for_each_cell_within<D>(grid, c, farthest, [&](std::uint64_t cell) {
      const int away = (cell_coords<D>(grid, cell) - c).cwiseAbs().maxCoeff();
      cells_away[cell] = std::min(cells_away[cell], away);
    });
  }
  std::vector<double> mine;
  for (int i = 0; i < g.n; i++) {
    const Vec<D> xi = Eigen::Map<const Vec<D>>(g.x[i]);
    const int reach = static_cast<int>(std::ceil((g.radius[i] + distance) / grid.dx));
    const Eigen::Matrix<int, D, 1> c = cell_of<D>(grid, xi);
    bool near = false;
    if (cell_on_grid<D>(grid, c)) near = cells_away[cell_index<D>(grid, c)] <= reach;
    else    // off the grid (a grain outside the box): the cells within reach that are on it
      for_each_cell_within<D>(grid, c, reach,
                              [&](std::uint64_t cell) { near = near || candidate_cells.count(cell) > 0; });
    if (!near) continue;
    mine.insert(mine.end(), xi.data(), xi.data() + D);
    mine.push_back(g.radius[i]);
  }
  int size = 0, count = static_cast<int>(mine.size());
  MPI_Comm_size(comm, &size);
  std::vector<int> counts(size), displs(size + 1, 0);
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
  for (int r = 0; r < size; ++r) displs[r + 1] = displs[r] + counts[r];
  std::vector<double> all(static_cast<std::size_t>(displs[size]));
  MPI_Allgatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, comm);
  std::vector<Obstacle<D>> obstacles(all.size() / (D + 1));
  for (std::size_t k = 0; k < obstacles.size(); ++k) {
    obstacles[k].x = Eigen::Map<const Vec<D>>(&all[k * (D + 1)]);
    obstacles[k].radius = all[k * (D + 1) + D];
  }
  return obstacles;
}

/// The largest radius candidate k may have without overlapping an obstacle or another fitting
/// candidate (at its radius) near it.
template <int D>
double room_of(std::size_t k, const std::vector<Fitting<D>> &fitting, const std::vector<Obstacle<D>> &obstacles) {
  const Fitting<D> &c = fitting[k];
  double room = 1.0e20;
  for (std::size_t o : c.obstacles) room = std::min(room, (c.x - obstacles[o].x).norm() - obstacles[o].radius);
  for (std::size_t m : c.others) room = std::min(room, (c.x - fitting[m].x).norm() - fitting[m].radius);
  return room;
}

/// Pushes the candidates off the obstacles (the candidate moves) and off each other (both move,
/// half each), Gauss-Seidel, until every gap is at least `gap`: each stays within
/// (1 - kSmallestShrink) of its radius of its template place (as far as it could have shrunk),
/// inside its cell (its sums are its cell's) and inside the container [lo, hi].
template <int D>
void relax_candidates(const GridGeometry<D> &grid, std::vector<Fitting<D>> &fitting,
                      const std::vector<Obstacle<D>> &obstacles, double gap, const double lo[3], const double hi[3]) {
  const double edge = 1e-6 * grid.dx;    // keeps a centre off its cell's faces (round-off)
  auto hold = [&](Fitting<D> &c) {
    const Vec<D> moved = c.x - c.home;
    const double leash = (1 - kSmallestShrink) * c.radius, far = moved.norm();
    if (far > leash) c.x = c.home + moved * (leash / far);
    for (int a = 0; a < D; ++a) {    // towards the home, which is inside both
      const double low = std::max(c.cell_lo[a] + edge, lo[a] + c.radius);
      const double high = std::min(c.cell_lo[a] + grid.dx - edge, hi[a] - c.radius);
      if (low <= high) c.x[a] = std::clamp(c.x[a], low, high);
    }
  };
  const double target = 2 * gap;    // aims past the accepted gap: the sweeps converge only asymptotically
  for (int sweep = 0; sweep < kRelaxSweeps; ++sweep) {
    double worst = 0;
    for (std::size_t k = 0; k < fitting.size(); ++k) {
      Fitting<D> &c = fitting[k];
      for (std::size_t o : c.obstacles) {
        const Vec<D> d = c.x - obstacles[o].x;
        const double dist = d.norm(), overlap = c.radius + obstacles[o].radius + target - dist;
        if (overlap <= 0 || !(dist > 0)) continue;
        worst = std::max(worst, overlap);
        c.x += overlap / dist * d;
        hold(c);
      }
      for (std::size_t m : c.others) {
        if (m < k) continue;    // each pair once
        Fitting<D> &b = fitting[m];
        const Vec<D> d = c.x - b.x;
        const double dist = d.norm(), overlap = c.radius + b.radius + target - dist;
        if (overlap <= 0 || !(dist > 0)) continue;
        worst = std::max(worst, overlap);
        c.x += 0.5 * overlap / dist * d;
        b.x -= 0.5 * overlap / dist * d;
        hold(c);
        hold(b);
      }
    }
    if (worst <= target - gap) return;
  }
}

}    // namespace

template <int D>
std::int64_t slot_of_cell_at(const GridGeometry<D> &grid, const double *x, const CellSlots &slots) {
  const auto c = cell_of<D>(grid, Eigen::Map<const Vec<D>>(x));
  if (!cell_on_grid<D>(grid, c)) return -1;
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
  std::set<std::uint64_t> candidate_cells;
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
      candidate_cells.insert(cell.cell);
      candidates[j].push_back(candidate);
      largest = std::max(largest, candidate.radius);
    }
  }
  // A candidate an old grain (of any rank and group: walls of frozen grains too) overlaps by
  // more than it could shrink (1 - kSmallestShrink of its radius) is dropped: an overlap would
  // inject elastic energy. The others keep their template size: pushed off the old grains and
  // each other (relax_candidates, each within that same distance of its template place); only
  // what is left overlapped after that shrinks to fit, down to kSmallestShrink. Shrinking alone
  // made the grains of a long silo discharge smaller than the DEM's (docs/design.md 5.6).
  const double gap = kTemplateGap * grain_diameter, moves = 2 * (1 - kSmallestShrink) * largest;
  const std::vector<Obstacle<D>> obstacles = obstacles_near<D>(grid, g, candidate_cells, largest + gap + moves, comm);
  double largest_obstacle = 0;
  CellBins<D> obstacle_bins(grid);
  for (std::size_t o = 0; o < obstacles.size(); ++o) {
    obstacle_bins.add(obstacles[o].x, o);
    largest_obstacle = std::max(largest_obstacle, obstacles[o].radius);
  }
  std::vector<Fitting<D>> fitting;
  CellBins<D> candidate_bins(grid);
  for (std::size_t j = 0; j < making.size(); ++j) {
    const Vec<D> cell_lo = grid.node_position(cell_coords<D>(grid, cells[making[j]].cell));
    for (std::size_t n = 0; n < candidates[j].size(); ++n) {
      Fitting<D> c{candidates[j][n].x, candidates[j][n].x, candidates[j][n].radius, j, n, cell_lo, {}, {}};
      obstacle_bins.near(c.x, c.radius + largest_obstacle + gap + moves, [&](std::size_t o) {
        if ((c.x - obstacles[o].x).norm() < c.radius + obstacles[o].radius + gap + moves) c.obstacles.push_back(o);
      });
      fitting.push_back(std::move(c));
      if (room_of<D>(fitting.size() - 1, fitting, obstacles) - gap < kSmallestShrink * fitting.back().radius)
        fitting.pop_back();
      else
        candidate_bins.add(fitting.back().x, fitting.size() - 1);
    }
  }
  for (std::size_t k = 0; k < fitting.size(); ++k)
    candidate_bins.near(fitting[k].x, 2 * largest + gap + moves, [&](std::size_t m) {
      if (m != k && (fitting[k].x - fitting[m].x).norm() < fitting[k].radius + fitting[m].radius + gap + moves)
        fitting[k].others.push_back(m);
    });
  relax_candidates<D>(grid, fitting, obstacles, gap, lo, hi);

  std::vector<std::vector<NewGrain<D>>> fitted(making.size());
  std::vector<double> fits(fitting.size());
  for (std::size_t k = 0; k < fitting.size(); ++k)    // a gap of kTemplateGap diameters, as between template grains
    fits[k] = room_of<D>(k, fitting, obstacles) - gap;
  for (std::size_t k = 0; k < fitting.size(); ++k) {
    if (fits[k] < kSmallestShrink * fitting[k].radius) continue;
    NewGrain<D> candidate = candidates[fitting[k].j][fitting[k].n];
    candidate.x = fitting[k].x;
    candidate.radius = std::min(candidate.radius, fits[k]);
    fitted[fitting[k].j].push_back(candidate);
  }

  for (std::size_t j = 0; j < making.size(); ++j) {
    const auto &cell = cells[making[j]];
    std::vector<NewGrain<D>> &kept = fitted[j];
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
                                    DemGrains &g, const GrainRules &rules, std::vector<signed char> *mechanisms) {
  std::map<std::uint64_t, const GrainCorrection<D> *> correction_of;
  for (const auto &gc : corrections) correction_of[gc.cell] = &gc;
  std::vector<char> remove(g.n, 0);
  if (mechanisms) mechanisms->assign(g.n, -1);
  for (int i = 0; i < g.n; i++) {
    if (!g.coupled(i)) continue;
    const std::int64_t k = slot_of_cell_at<D>(grid, g.x[i], slots);
    if (k < 0) continue;
    const auto it = correction_of.find(cells[k].cell);
    if (it == correction_of.end()) continue;
    const GrainCorrection<D> &gc = *it->second;
    if (mechanisms && gc.mechanism >= 0 && gc.mechanism < kMechanisms)    // (the ledger's only use of it)
      (*mechanisms)[i] = static_cast<signed char>(gc.mechanism);
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
                                                  DemGrains &, const GrainRules &, std::vector<signed char> *);
HYBRID_DEM_REZONE(2)
HYBRID_DEM_REZONE(3)

}    // namespace coupler
