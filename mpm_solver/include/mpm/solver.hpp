#pragma once
// Explicit MPM with quadratic B-splines and APIC (MLS) transfers.
// One step is P2G, grid update, G2P (which also updates each point's stress).
#include <functional>
#include <utility>
#include <vector>

#include "mpm/grid.hpp"
#include "mpm/materials.hpp"
#include "mpm/particles.hpp"
#include "mpm/scene.hpp"

namespace mpm {

/// Steps between re-sorts of the points by grid cell (Solver::sort_points_by_cell), in pure and
/// coupled runs alike: a sort costs about a step, and points, moving well under a cell per step
/// at the CFL step, stay nearly in cell order for tens of steps, so 50 keeps the cache locality
/// for a few percent of the run time.
inline constexpr long kSortEvery = 50;

/// A rigid boundary at the current time, as the grid update applies it.
template <int D>
struct RigidBoundary {
  Boundary spec;
  Vec<D> velocity = Vec<D>::Zero();
  Vec<D> point = Vec<D>::Zero(), normal = Vec<D>::Zero();  ///< plane at time t
  Vec<D> lower = Vec<D>::Zero(), upper = Vec<D>::Zero();   ///< box at time t
};

/// The step whose APIC transfers set the continuum's numerical dissipation, in units of the stable
/// step's dx / (c + |v|max): the cfl the standalone solver steps at by default and the materials
/// were calibrated with.
inline constexpr double kTransferCfl = 0.5;

/// The share of a point's own velocity beyond the grid's field that a step of dt keeps (its FLIP
/// part; APIC keeps none): 1 - dt / reference below the reference step, 0 at or above it. Every
/// APIC transfer smooths the velocity field a little, so a step shorter than the reference (a
/// coupled run's exchange interval, a low cfl) would dissipate more per unit time; keeping this
/// share makes the loss per unit time that of the reference step (docs/design.md section 4.2).
inline double transfer_memory(double dt, double reference) {
  return reference > 0 && dt < reference ? 1.0 - dt / reference : 0.0;
}

template <int D>
class Solver {
 public:
  /// Builds the grid and seeds the material blocks. Throws UserError.
  explicit Solver(const Scene& scene);

  /// Largest step the CFL condition allows for the current velocities.
  double stable_dt() const;
  /// The reference step of transfer_memory: kTransferCfl dx / (c + |v|max).
  double transfer_reference_dt() const { return stable_dt() * (kTransferCfl / scene_.time.cfl); }
  /// The step the next call to step() will take: the stable one, or the
  /// user's fixed step after checking it against the stable one (UserError if unstable).
  double next_dt() const;
  /// Advances by dt (P2G, grid update, G2P), then removes the points that entered an outlet.
  /// Throws UserError if a point leaves the grid or the state stops being finite.
  void step(double dt);

  void p2g(double dt);
  void grid_update(double dt);
  void g2p(double dt);
  /// Moves the clock (and the moving boundaries) on by dt: the end of a step.
  void advance_clock(double dt);
  /// Applies the boundary conditions to velocity v at grid node `node`.
  void constrain_velocity(std::size_t node, Vec<D>& v) const { apply_boundaries(node, v); }
  /// Replaces the points and the clock with a saved state (coupled restarts).
  void restore(Particles<D> points, double time, long steps);
  /// Adds a material point with the given state (coupled runs: points made from grains).
  /// The elastic state is the one that gives `stress`; the stable step accounts for the
  /// point's own density.
  void add_point(const Vec<D>& x, const Vec<D>& v, const Mat<D>& C, double mass, double volume, const Mat<D>& stress,
                 std::uint16_t material = 0);
  /// Reorders the points by grid cell so neighbours in memory are neighbours
  /// on the grid (cache locality, compact per-thread grid ranges).
  void sort_points_by_cell();

  const Scene& scene() const { return scene_; }
  const Particles<D>& points() const { return points_; }
  Particles<D>& points() { return points_; }
  const Grid<D>& grid() const { return grid_; }
  Grid<D>& grid() { return grid_; }
  const std::vector<MaterialModel>& materials() const { return materials_; }
  double time() const { return time_; }
  long steps() const { return steps_; }
  /// Below this many points per thread a step runs serially (default 4096).
  void set_min_points_per_thread(std::size_t n) { min_points_per_thread_ = n; }
  /// Flat node range [first, second) the last P2G touched: no node outside holds mass.
  std::pair<std::size_t, std::size_t> active_nodes() const { return {active_lo_, active_hi_}; }
  /// Largest point speed after the last G2P (or at start).
  double max_speed() const { return max_speed_; }
  /// Mass and number of the points the outlets have removed so far.
  double outflow_mass() const { return outflow_mass_; }
  long outflow_points() const { return outflow_points_; }
  /// The work the points' fill pressure (Particles::fill_pressure, a coupled run's) has done on
  /// them so far, J (J/m in 2D): sum over G2Ps of p tr(grad v) V dt, positive where it spreads
  /// them. Part of what a coupled run's ledger counts as the continuum's own steps.
  double fill_work() const { return fill_work_; }

 private:
  void seed_block(const Block& block);
  /// Fourth power of point p's P-wave speed in its current state (MaterialModel::wave_speed4).
  double wave_speed4(std::size_t p) const;
  /// The largest P-wave speed (wave_speed4, as G2P takes it) and point speed over the points:
  /// the stable step of a solver that has not stepped yet, or restored its points.
  void refresh_stable_step_speeds();
  void apply_boundaries(std::size_t node, Vec<D>& v) const;
  void update_rigid_boundaries();
  /// Removes the points inside an outlet, adding them to the outflow.
  void remove_outflow();
  /// Threads worth using: small scenes run serially, since a parallel region
  /// costs more than it saves below a few thousand points per thread.
  int active_threads() const {
    const auto n = static_cast<int>(thread_grids_.size());
    return points_.size() >= min_points_per_thread_ * thread_grids_.size() ? n : 1;
  }

  Scene scene_;
  std::vector<MaterialModel> materials_;
  Particles<D> points_;
  Grid<D> grid_;
  Vec<D> gravity_ = Vec<D>::Zero();
  std::vector<RigidBoundary<D>> boundaries_;
  double max_wave_speed_ = 0;
  double max_speed_ = 0;
  double fill_work_ = 0;
  double time_ = 0;
  long steps_ = 0;
  double outflow_mass_ = 0;
  long outflow_points_ = 0;
  std::size_t min_points_per_thread_ = 4096;

  // Per-thread scratch grids for P2G (thread 0 writes the main grid), each
  // with the flat node range it touched, so clearing and summing stay local.
  struct ThreadGrid {
    std::vector<double> mass;
    std::vector<Vec<D>> momentum;
    std::vector<Vec<D>> transfer;  ///< momentum of the transfer alone (sized when first used)
    std::size_t lo = 0, hi = 0;
  };
  std::vector<ThreadGrid> thread_grids_;
  /// Flat node range the last P2G touched (all threads): what the grid
  /// update visits and the next P2G clears.
  std::size_t active_lo_ = 0, active_hi_ = 0;
  /// transfer_memory of the step P2G opened (G2P keeps this share of the points' own velocity).
  double transfer_memory_ = 0;
};

/// What a run reports as it goes.
struct RunProgress {
  long step;
  double time, dt, wall_seconds, point_steps_per_second;
};

struct RunOptions {
  bool write_output = true;
  long max_steps = 0;  ///< >0: stop after this many steps even before the end time
};

/// Runs `solver` to the scene's end time, writing snapshots at the output
/// interval (first and last frames always) when asked, and calling `progress`
/// every progress_interval wall seconds and once at the end.
template <int D>
RunProgress run(Solver<D>& solver, const RunOptions& options, const std::function<void(const RunProgress&)>& progress);

}  // namespace mpm
