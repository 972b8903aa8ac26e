#include "mpm/coupled_continuum.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "coupler/stencil.hpp"
#include "coupler/zones.hpp"
#include "mpm/state_file.hpp"

namespace mpm {

Scene coupled_scene(const coupler::Hello& hello) {
  const coupler::ContinuumSettings& c = hello.continuum;
  Scene scene;
  scene.dimension = hello.dimension;
  scene.coupled = true;
  for (int a = 0; a < 3; ++a) {
    scene.gravity[a] = c.gravity[a];
    scene.grid.lower[a] = hello.box_lo[a];
    scene.grid.upper[a] = hello.box_hi[a];
  }
  scene.grid.cell_size = hello.cell;
  scene.grid.walls = c.wall_contact == coupler::kWallSticky ? Contact::Sticky
                     : c.wall_contact == coupler::kWallFriction ? Contact::Friction
                                                                 : Contact::Slip;
  scene.grid.wall_friction = c.wall_friction;
  // Container faces inside the box are walls too (the box faces always are).
  const double tiny = 1e-12 * hello.cell;
  for (int a = 0; a < hello.dimension; ++a)
    for (int side = 0; side < 2; ++side) {
      const double plane = side ? c.container_hi[a] : c.container_lo[a];
      const double face = side ? hello.box_hi[a] : hello.box_lo[a];
      if (std::abs(plane - face) <= tiny) continue;
      Boundary wall;
      wall.kind = BoundaryKind::Plane;
      wall.contact = scene.grid.walls;
      wall.friction = c.wall_friction;
      wall.point = {0, 0, 0};
      wall.point[a] = plane;
      wall.normal = {0, 0, 0};
      wall.normal[a] = side ? -1.0 : 1.0;
      scene.boundaries.push_back(wall);
    }
  scene.time.cfl = c.cfl;
  Material m;
  m.name = "grains";
  // The points' own density (grain mass over cell volume) sets their wave speed; this
  // nominal bulk density only has to be valid.
  m.density = c.critical_packing * c.grain_density;
  if (hello.model == coupler::kModelMuI) {
    m.model = ModelKind::MuI;
    m.mu_i.youngs_modulus = c.youngs_modulus;
    m.mu_i.poisson_ratio = c.poisson_ratio;
    m.mu_i.mu_s = c.mu_s;
    m.mu_i.mu_2 = c.mu_2;
    m.mu_i.I0 = c.I0;
    m.mu_i.grain_diameter = c.grain_diameter;
    m.mu_i.grain_density = c.grain_density;
    m.mu_i.critical_density = c.critical_packing * c.grain_density;
  } else {
    m.model = ModelKind::DruckerPrager;
    m.drucker_prager.youngs_modulus = c.youngs_modulus;
    m.drucker_prager.poisson_ratio = c.poisson_ratio;
    m.drucker_prager.friction_angle_deg = c.friction_angle_deg;
  }
  scene.materials.push_back(m);
  scene.output.progress_interval = 0;
  return scene;
}

namespace {
/// Share of the support force each exchange forgets. Both sides feel the force through their
/// transfer weights, which smooth it: a node-to-node oscillating part acts on neither side,
/// so the agreement cannot correct it and a pure integral (no leak) lets it grow without
/// bound (measured in a settled column: vertical stress 10 % above the weight). A 10 % leak
/// keeps it bounded and leaves the steady support within a few percent.
constexpr double kSupportLeak = 0.1;
}  // namespace

template <int D>
CoupledContinuum<D>::CoupledContinuum(const coupler::Hello& hello)
    : hello_(hello), solver_(coupled_scene(hello)), time_(hello.time) {
  const auto& grid = solver_.grid();
  zones_.assign(coupler::num_cells(static_cast<const coupler::GridGeometry<D>&>(grid)), coupler::kDiscrete);
  dem_mass_.assign(grid.num_nodes(), 0.0);
  dem_momentum_.assign(grid.num_nodes(), Vec<D>::Zero());
  support_force_.assign(grid.num_nodes(), Vec<D>::Zero());
  support_mass_.assign(grid.num_nodes(), 0.0);
  touched_slot_.assign(grid.num_nodes(), -1);
  const std::string dir = coupler::get_text(hello.continuum.output_path);
  if (hello.continuum.output_every > 0 && !dir.empty()) {
    Scene scene = solver_.scene();
    scene.output.grid_fields = true;
    writer_ = std::make_unique<SnapshotWriter<D>>(dir, scene);
  }
}

template <int D>
coupler::StepAck CoupledContinuum<D>::convert(double time, std::vector<std::int8_t> zones,
                                              const std::vector<std::vector<coupler::CellMoments<D>>>& per_rank) {
  const auto& geometry = static_cast<const coupler::GridGeometry<D>&>(solver_.grid());
  if (zones.size() != zones_.size()) {
    coupler::StepAck ack;
    ack.status = 1;
    coupler::set_text(ack.message, "the zone map has " + std::to_string(zones.size()) + " cells, the grid " +
                                       std::to_string(zones_.size()));
    return ack;
  }
  zones_ = std::move(zones);
  // Sum the ranks' partial moments per cell, in rank order (deterministic).
  std::map<std::uint64_t, coupler::CellMoments<D>> cells;
  for (const auto& list : per_rank)
    for (const auto& m : list) {
      if (m.cell >= zones_.size()) throw UserError("a DEM rank sent moments for cell " + std::to_string(m.cell) +
                                                   " outside the grid");
      auto it = cells.find(m.cell);
      if (it == cells.end()) cells.emplace(m.cell, m);
      else it->second.add(m);
    }
  const double grain_weight = hello_.continuum.grain_weight;
  for (const auto& [cell, moments] : cells) {
    const double share = zones_[cell] == coupler::kContinuum ? 1.0 : 1.0 - grain_weight;
    for (const auto& p :
         coupler::points_from_moments<D>(moments.scaled(share), geometry, hello_.continuum.points_per_axis, share)) {
      solver_.add_point(p.x, p.v, p.C, p.mass, p.volume, p.stress);
      solver_.points().weight.back() = static_cast<float>(share);
    }
  }
  solver_.sort_points_by_cell();
  time_ = time;
  return totals(0);
}

template <int D>
void CoupledContinuum<D>::advance_to(double time) {
  const double tiny = 1e-12 * std::max(1.0, std::abs(time));
  if (pending_dt_ >= 0) {
    if (std::abs(time - open_time_) <= tiny) return;
    throw UserError("internal: the continuum advanced to t = " + std::to_string(open_time_) +
                    " s for the next exchange, which came at t = " + std::to_string(time) + " s");
  }
  const double interval = time - time_;
  if (interval < -1e-12 * std::max(1.0, std::abs(time)))
    throw UserError("the DEM time went backwards (from " + std::to_string(time_) + " s to " + std::to_string(time) +
                    " s): a coupled run cannot reset its time step counter or time");
  // Times from the DEM side agree to round-off only: an interval of a few ulps is none (the
  // support force divides by it)
  const double span = interval > tiny ? interval : 0.0;
  const double stable = solver_.stable_dt();
  int substeps = 1;
  if (std::isfinite(stable) && stable > 0) substeps = std::max(1, static_cast<int>(std::ceil(span / stable * (1 - 1e-12))));
  const double h = span / substeps;
  for (int k = 0; k + 1 < substeps; ++k) {
    solver_.step(h);
    if (solver_.steps() % 50 == 0) solver_.sort_points_by_cell();
  }
  solver_.p2g(h);
  solver_.grid_update(h);
  pending_dt_ = h;
  open_time_ = time;
  substeps_ = substeps;
  interval_ = span;
}

template <int D>
std::vector<std::vector<coupler::NodeUpdate>> CoupledContinuum<D>::agree(
    const std::vector<std::vector<coupler::NodeRecord>>& per_rank) {
  Grid<D>& grid = solver_.grid();
  const std::size_t n_nodes = grid.num_nodes();
  // DEM mass and momentum of every node over all ranks.
  for (const auto& list : per_rank)
    for (const auto& r : list) {
      if (r.node >= n_nodes)
        throw UserError("a DEM rank sent node " + std::to_string(r.node) + " outside the grid of " +
                        std::to_string(n_nodes) + " nodes");
      if (touched_slot_[r.node] < 0) {
        touched_slot_[r.node] = static_cast<std::int64_t>(touched_.size());
        touched_.push_back(r.node);
      }
      dem_mass_[r.node] += r.mass;
      dem_momentum_[r.node] += Eigen::Map<const Eigen::Vector3d>(r.momentum).head<D>();
    }
  // The agreement: both sides end with the common velocity (p_mpm + p_dem) / (m_mpm + m_dem),
  // which the boundaries then constrain like any grid velocity. dem_momentum_ becomes the
  // answer: the common velocity; dem_mass_ keeps m_dem for lambda / m_dem.
  mismatch_ = 0;
  shared_nodes_ = 0;
  std::vector<Vec<D>> impulse_per_mass(touched_.size()), support(touched_.size(), Vec<D>::Zero());
  // The support force between exchanges: what the agreement had to add over the last
  // interval becomes a steady force for the next one (F += gain * lambda / interval), so
  // grains resting on the continuum are held between exchanges, not only at them.
  const double gain = hello_.continuum.support_gain;
  std::vector<Vec<D>> old_force(touched_.size());
  std::vector<double> old_mass(touched_.size());
  for (std::size_t t = 0; t < touched_.size(); ++t) {
    old_force[t] = support_force_[touched_[t]];
    old_mass[t] = support_mass_[touched_[t]];
  }
  for (std::size_t k : support_nodes_) support_force_[k].setZero(), support_mass_[k] = 0.0;
  support_nodes_.clear();
  for (std::size_t t = 0; t < touched_.size(); ++t) {
    const std::size_t k = touched_[t];
    const double m_dem = dem_mass_[k];
    const Vec<D> v_dem = m_dem > 0 ? Vec<D>(dem_momentum_[k] / m_dem) : Vec<D>::Zero();
    const double m_mpm = grid.mass[k];
    Vec<D> common = v_dem;
    if (m_mpm > 0 && m_dem > 0) {
      const Vec<D> v_mpm = grid.momentum[k];  // a velocity after the grid update
      mismatch_ = std::max(mismatch_, (v_dem - v_mpm).norm());
      common = (m_mpm * v_mpm + m_dem * v_dem) / (m_mpm + m_dem);
      solver_.constrain_velocity(k, common);
      grid.momentum[k] = common;
      ++shared_nodes_;
      if (gain > 0) {
        // A force set when the node held more mass would accelerate what is left there
        // beyond anything the agreement asked for: scale it with the node's reduced mass.
        const double reduced = m_dem * m_mpm / (m_dem + m_mpm);
        const double carry = old_mass[t] > 0 ? std::min(1.0, reduced / old_mass[t]) : 0.0;
        Vec<D> force = ((1.0 - kSupportLeak) * carry) * old_force[t];
        if (interval_ > 0) force += gain * m_dem * (common - v_dem) / interval_;
        support_force_[k] = force;
        support_mass_[k] = reduced;
        support_nodes_.push_back(k);
        support[t] = force / m_dem;
      }
    }
    impulse_per_mass[t] = common - v_dem;  // lambda_i / m_dem_i
    dem_momentum_[k] = common;
  }
  std::vector<std::vector<coupler::NodeUpdate>> replies(per_rank.size());
  for (std::size_t r = 0; r < per_rank.size(); ++r) {
    replies[r].resize(per_rank[r].size());
    for (std::size_t i = 0; i < per_rank[r].size(); ++i) {
      const std::size_t k = per_rank[r][i].node;
      auto& u = replies[r][i];
      const auto t = static_cast<std::size_t>(touched_slot_[k]);
      for (int a = 0; a < D; ++a) {
        u.velocity[a] = dem_momentum_[k][a];
        u.impulse_per_mass[a] = impulse_per_mass[t][a];
        u.support[a] = support[t][a];
      }
    }
  }
  for (std::size_t k : touched_) {
    dem_mass_[k] = 0.0;
    dem_momentum_[k].setZero();
    touched_slot_[k] = -1;
  }
  touched_.clear();
  return replies;
}

/// The points' share of the reaction to the support force, -F_i split over the points by
/// their mass at the node: sum_p m_p a_p = -sum_i F_i exactly. Uses the weights of the
/// current substep's P2G (call before G2P moves the points).
template <int D>
void CoupledContinuum<D>::apply_support_reaction() {
  auto& pts = solver_.points();
  std::fill(pts.body_accel.begin(), pts.body_accel.end(), Vec<D>::Zero());
  if (support_nodes_.empty()) return;
  const Grid<D>& grid = solver_.grid();
  const auto& geometry = static_cast<const coupler::GridGeometry<D>&>(grid);
  for (std::size_t p = 0; p < pts.size(); ++p) {
    Vec<D> a = Vec<D>::Zero();
    coupler::for_each_stencil_node<D>(coupler::QuadraticStencil<D>(grid.to_cell_units(pts.x[p])), geometry,
                                      [&](std::size_t k, double w, const auto&) {
                                        if (grid.mass[k] > 0) a -= (w / grid.mass[k]) * support_force_[k];
                                      });
    pts.body_accel[p] = a;
  }
}

template <int D>
void CoupledContinuum<D>::complete_step() {
  if (pending_dt_ < 0) return;
  apply_support_reaction();
  solver_.g2p(pending_dt_);
  solver_.advance_clock(pending_dt_);
  time_ = open_time_;
  pending_dt_ = -1;
}

template <int D>
coupler::StepAck CoupledContinuum<D>::ack(std::int64_t step, double mass, const Vec<D>& momentum,
                                         const coupler::Spin<D>& angular, double kinetic_energy) const {
  coupler::StepAck a;
  a.step = step;
  a.substeps = substeps_;
  a.points = static_cast<std::int64_t>(solver_.points().size());
  a.shared_nodes = shared_nodes_;
  a.mismatch = mismatch_;
  a.mpm_dt = pending_dt_ >= 0 ? pending_dt_ : 0.0;
  a.mass = mass;
  a.kinetic_energy = kinetic_energy;
  for (int d = 0; d < D; ++d) a.momentum[d] = momentum[d];
  if constexpr (D == 2) a.angular[2] = angular[0];
  else
    for (int d = 0; d < 3; ++d) a.angular[d] = angular[d];
  return a;
}

template <int D>
coupler::StepAck CoupledContinuum<D>::grid_totals(std::int64_t step) const {
  const Grid<D>& grid = solver_.grid();
  double mass = 0, ke = 0;
  Vec<D> p = Vec<D>::Zero();
  coupler::Spin<D> L = coupler::Spin<D>::Zero();
  const auto [first, last] = solver_.active_nodes();
  for (std::size_t k = first; k < last; ++k) {
    const double m = grid.mass[k];
    if (m <= 0) continue;
    const Vec<D>& v = grid.momentum[k];  // a velocity after the grid update
    mass += m;
    p += m * v;
    L += coupler::cross<D>(grid.node_position(grid.node_of(k)), Vec<D>(m * v));
    ke += 0.5 * m * v.squaredNorm();
  }
  return ack(step, mass, p, L, ke);
}

template <int D>
coupler::StepAck CoupledContinuum<D>::totals(std::int64_t step) const {
  const auto& pts = solver_.points();
  double mass = 0, ke = 0;
  Vec<D> p = Vec<D>::Zero();
  coupler::Spin<D> L = coupler::Spin<D>::Zero();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    mass += pts.mass[i];
    p += pts.mass[i] * pts.v[i];
    L += coupler::point_angular_momentum<D>(pts.x[i], pts.v[i], pts.C[i], pts.mass[i], solver_.grid().dx);
    ke += 0.5 * pts.mass[i] * pts.v[i].squaredNorm();
  }
  return ack(step, mass, p, L, ke);
}

template <int D>
void CoupledContinuum<D>::save(const std::string& path, std::int64_t dem_step, std::int64_t exchanges) const {
  ContinuumState<D> state;
  state.points = solver_.points();
  state.zones = zones_;
  for (std::size_t k : support_nodes_) {
    state.support_nodes.push_back(k);
    state.support_forces.push_back(support_force_[k]);
    state.support_masses.push_back(support_mass_[k]);
  }
  state.time = time_;
  state.solver_time = solver_.time();
  state.solver_steps = solver_.steps();
  state.dem_step = dem_step;
  state.exchanges = exchanges;
  state.cell = hello_.cell;
  for (int a = 0; a < 3; ++a) state.box_lo[a] = hello_.box_lo[a], state.box_hi[a] = hello_.box_hi[a];
  state.model = hello_.model;
  save_state<D>(path, state);
}

template <int D>
void CoupledContinuum<D>::load(const std::string& path) {
  ContinuumState<D> state = load_state<D>(path);
  const double tol = 1e-12 * hello_.cell;
  bool same_grid = std::abs(state.cell - hello_.cell) <= tol && state.model == hello_.model;
  for (int a = 0; a < D; ++a)
    same_grid = same_grid && std::abs(state.box_lo[a] - hello_.box_lo[a]) <= tol &&
                std::abs(state.box_hi[a] - hello_.box_hi[a]) <= tol;
  if (!same_grid || state.zones.size() != zones_.size())
    throw UserError("the MPM state " + path + " was saved with another box, cell size or model than this run's "
                    "fix hybrid/mpm line; restart with the same box, cell and model");
  zones_ = std::move(state.zones);
  for (std::size_t k : support_nodes_) support_force_[k].setZero(), support_mass_[k] = 0.0;
  support_nodes_.clear();
  for (std::size_t i = 0; i < state.support_nodes.size(); ++i) {
    const std::size_t k = state.support_nodes[i];
    if (k >= support_force_.size()) throw UserError("the MPM state " + path + " names a node outside the grid");
    support_force_[k] = state.support_forces[i];
    support_mass_[k] = state.support_masses[i];
    support_nodes_.push_back(k);
  }
  time_ = state.time;
  solver_.restore(std::move(state.points), state.solver_time, state.solver_steps);
  pending_dt_ = -1;
}

template <int D>
void CoupledContinuum<D>::write_frame(const std::vector<std::vector<coupler::GrainRecord>>& grains,
                                      std::int64_t step) {
  if (!writer_) return;
  GrainFrame frame;
  for (const auto& list : grains)
    for (const auto& g : list) {
      frame.id.push_back(g.id);
      frame.x.insert(frame.x.end(), g.x, g.x + 3);
      frame.v.insert(frame.v.end(), g.v, g.v + 3);
      frame.radius.push_back(g.radius);
      frame.mass.push_back(g.mass);
      frame.weight.push_back(g.weight);
      frame.zone.push_back(static_cast<std::int8_t>(g.zone));
    }
  const auto& pts = solver_.points();
  const auto& geometry = static_cast<const coupler::GridGeometry<D>&>(solver_.grid());
  PointCoupling coupling;
  coupling.zone.resize(pts.size());
  coupling.weight.assign(pts.weight.begin(), pts.weight.end());
  for (std::size_t i = 0; i < pts.size(); ++i)
    coupling.zone[i] = zones_[coupler::cell_index<D>(geometry, coupler::cell_of<D>(geometry, pts.x[i]))];
  writer_->write(pts, solver_.grid(), time_, step, &frame, &coupling);
}

template class CoupledContinuum<2>;
template class CoupledContinuum<3>;

}  // namespace mpm
