#include "mpm/solver.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <numeric>
#include <sstream>

#include "coupler/bspline.hpp"
#include "coupler/stencil.hpp"
#include "mpm/output.hpp"

namespace mpm {

namespace {

template <int D>
Vec<D> take(const Vec3& v) {
  return Eigen::Map<const Eigen::Vector3d>(v.data()).head<D>();
}

std::string format_vec(const double* x, int n) {
  std::ostringstream s;
  s << '(';
  for (int a = 0; a < n; ++a) s << (a ? ", " : "") << x[a];
  s << ')';
  return s.str();
}

/// Flat index span [first, last] of a stencil's nodes.
template <int D>
std::size_t stencil_span(const Grid<D>& g) {
  std::size_t span = 0;
  for (int a = 0; a < D; ++a) span += 2 * g.stride(a);
  return span;
}

}  // namespace

template <int D>
Solver<D>::Solver(const Scene& scene) : scene_(scene) {
  if (scene.dimension != D)
    throw UserError("internal: scene dimension " + std::to_string(scene.dimension) + " given to a " +
                    std::to_string(D) + "D solver");
  if (!(scene.grid.cell_size > 0)) throw UserError("[grid] cell_size must be > 0");
  if (scene.materials.empty()) throw UserError("the scene defines no [[material]]");
  if (scene.blocks.empty() && !scene.coupled) throw UserError("the scene defines no [[block]] of material");
  const Vec<D> lower = take<D>(scene.grid.lower), upper = take<D>(scene.grid.upper);
  if (!((upper - lower).array() > scene.grid.cell_size).all())
    throw UserError("[grid] upper must exceed lower by at least one cell_size on every axis");
  const double cells = ((upper - lower) / scene.grid.cell_size).array().ceil().prod();
  if (cells > 2e9) throw UserError("[grid] has " + std::to_string(cells) + " cells; increase cell_size");
  grid_ = Grid<D>(lower, upper, scene.grid.cell_size, scene.grid.node_plane);
  gravity_ = take<D>(scene.gravity);

  for (const auto& m : scene.materials) materials_.emplace_back(m);
  for (const auto& b : scene.blocks) seed_block(b);
  if (points_.size() == 0 && !scene.coupled)
    throw UserError("the material blocks contain no points; check their sizes against cell_size");

  for (const auto& b : scene.boundaries) {
    RigidBoundary<D> rb;
    rb.spec = b;
    boundaries_.push_back(rb);
  }
  // Domain faces act as walls of the chosen kind. They come last: applied after the scene's
  // boundaries, they have the final word (a moving lid that reaches a face cannot push
  // material out of the domain).
  for (int a = 0; a < D; ++a)
    for (int side = 0; side < 2; ++side) {
      Boundary wall;
      wall.kind = BoundaryKind::Plane;
      wall.contact = scene.grid.walls;
      wall.friction = scene.grid.wall_friction;
      wall.point = scene.grid.lower;
      if (side) wall.point = scene.grid.upper;
      wall.normal = {0, 0, 0};
      wall.normal[a] = side ? -1.0 : 1.0;
      RigidBoundary<D> rb;
      rb.spec = wall;
      boundaries_.push_back(rb);
    }
  update_rigid_boundaries();

  refresh_stable_step_speeds();
  thread_grids_.resize(static_cast<std::size_t>(omp_get_max_threads()));
  for (std::size_t t = 1; t < thread_grids_.size(); ++t) {
    thread_grids_[t].mass.assign(grid_.num_nodes(), 0.0);
    thread_grids_[t].momentum.assign(grid_.num_nodes(), Vec<D>::Zero());
  }
  sort_points_by_cell();
}

template <int D>
void Solver<D>::seed_block(const Block& block) {
  std::uint16_t mat = 0;
  while (mat < scene_.materials.size() && scene_.materials[mat].name != block.material) ++mat;
  if (mat == scene_.materials.size()) throw UserError("block uses undefined material \"" + block.material + "\"");
  const MaterialModel& model = materials_[mat];

  int per_axis = 2;
  if (block.points_per_cell > 0) {
    per_axis = static_cast<int>(std::lround(std::pow(block.points_per_cell, 1.0 / D)));
    if (static_cast<int>(std::lround(std::pow(per_axis, D))) != block.points_per_cell)
      throw UserError("points_per_cell = " + std::to_string(block.points_per_cell) + " is not a perfect " +
                      (D == 2 ? "square" : "cube"));
  }
  const double spacing = grid_.dx / per_axis;
  const double point_volume = std::pow(spacing, D);

  Vec<D> lo, hi;
  if (block.shape == Shape::Box) {
    lo = take<D>(block.lower);
    hi = take<D>(block.upper);
  } else {
    const Vec<D> c = take<D>(block.center);
    lo = c.array() - block.radius;
    hi = c.array() + block.radius;
    if (D == 3) {
      lo[block.axis] = c[block.axis] - 0.5 * block.height;
      hi[block.axis] = c[block.axis] + 0.5 * block.height;
    }
  }
  auto inside = [&](const Vec<D>& x) {
    if (block.shape == Shape::Box) return (x.array() >= lo.array()).all() && (x.array() < hi.array()).all();
    Vec<D> r = x - take<D>(block.center);
    if (D == 3) {
      if (std::abs(r[block.axis]) > 0.5 * block.height) return false;
      r[block.axis] = 0;
    }
    return r.squaredNorm() < block.radius * block.radius;
  };
  // Lattice aligned with the grid cells: per_axis points per cell and axis.
  IVec<D> first, count;
  for (int a = 0; a < D; ++a) {
    first[a] = static_cast<int>(std::floor((lo[a] - grid_.domain_lower[a]) / spacing));
    count[a] = static_cast<int>(std::ceil((hi[a] - grid_.domain_lower[a]) / spacing)) - first[a];
  }
  const std::size_t before = points_.size();
  const Vec<D> v0 = take<D>(block.velocity);
  const long total = count.template cast<long>().prod();
  for (long n = 0; n < total; ++n) {
    long rest = n;
    Vec<D> x;
    for (int a = D - 1; a >= 0; --a) {
      const long k = first[a] + rest % count[a];
      rest /= count[a];
      x[a] = grid_.domain_lower[a] + (k + 0.5) * spacing;
    }
    if (inside(x) && grid_.in_domain(x)) points_.add(x, v0, model.density * point_volume, point_volume, mat);
  }
  if (block.geostatic && points_.size() > before) {
    // Lithostatic start: sigma_vv = -rho g depth along the last axis, lateral k0 times that.
    double top = -std::numeric_limits<double>::infinity();
    for (std::size_t p = before; p < points_.size(); ++p) top = std::max(top, points_.x[p][D - 1]);
    top += 0.5 * spacing;
    const double g = std::abs(gravity_[D - 1]);
    for (std::size_t p = before; p < points_.size(); ++p) {
      const double sv = -model.density * g * (top - points_.x[p][D - 1]);
      Mat<D> s = Mat<D>::Identity() * (block.k0 * sv);
      s(D - 1, D - 1) = sv;
      points_.stress[p] = s;
      if (model.kind == ModelKind::DruckerPrager) points_.be[p] = elastic_state_for_stress<D>(model, s);
    }
  }
}

template <int D>
void Solver<D>::update_rigid_boundaries() {
  for (auto& b : boundaries_) {
    b.velocity = take<D>(b.spec.velocity);
    const Vec<D> shift = b.velocity * time_;
    b.point = take<D>(b.spec.point) + shift;
    b.normal = take<D>(b.spec.normal).normalized();
    b.lower = take<D>(b.spec.lower) + shift;
    b.upper = take<D>(b.spec.upper) + shift;
  }
}

template <int D>
double Solver<D>::stable_dt() const {
  double boundary_speed = 0;
  for (const auto& b : boundaries_) boundary_speed = std::max(boundary_speed, b.velocity.norm());
  return scene_.time.cfl * grid_.dx / (max_wave_speed_ + std::max(max_speed_, boundary_speed));
}

template <int D>
double Solver<D>::next_dt() const {
  const double stable = stable_dt();
  const double fixed = scene_.time.fixed_dt;
  if (fixed <= 0) return stable;
  if (fixed > stable) {
    std::ostringstream msg;
    msg << "[time] dt = " << fixed << " s is above the stable step " << stable << " s at t = " << time_
        << " s (cfl * dx / (c + |v|max) with wave speed c = " << max_wave_speed_ << " m/s, |v|max = " << max_speed_
        << " m/s); set [time] dt <= " << stable << " or remove dt to use the automatic step";
    throw UserError(msg.str());
  }
  return fixed;
}

template <int D>
void Solver<D>::step(double dt) {
  p2g(dt);
  grid_update(dt);
  g2p(dt);
  advance_clock(dt);
  if (!scene_.outlets.empty()) remove_outflow();
}

template <int D>
void Solver<D>::remove_outflow() {
  std::vector<char> out(points_.size(), 0);
  bool any = false;
  for (const Outlet& o : scene_.outlets) {
    const Vec<D> lo = take<D>(o.lower), hi = take<D>(o.upper);
    for (std::size_t p = 0; p < points_.size(); ++p)
      if ((points_.x[p].array() >= lo.array()).all() && (points_.x[p].array() <= hi.array()).all()) out[p] = 1, any = true;
  }
  if (!any) return;
  for (std::size_t p = 0; p < points_.size(); ++p)
    if (out[p]) outflow_mass_ += points_.mass[p], ++outflow_points_;
  remove_points(points_, out);
}

template <int D>
void Solver<D>::advance_clock(double dt) {
  time_ += dt;
  ++steps_;
  update_rigid_boundaries();
}

template <int D>
void Solver<D>::restore(Particles<D> points, double time, long steps) {
  points_ = std::move(points);
  time_ = time;
  steps_ = steps;
  update_rigid_boundaries();
  // The stable step as the last G2P left it (the steps after a restart take the same substeps and
  // the same transfer_memory as the run that wrote the state).
  refresh_stable_step_speeds();
}

template <int D>
void Solver<D>::refresh_stable_step_speeds() {
  double max_wave4 = 0, max_speed_sq = 0;
  for (std::size_t p = 0; p < points_.size(); ++p) {
    max_wave4 = std::max(max_wave4, wave_speed4(p));
    max_speed_sq = std::max(max_speed_sq, points_.v[p].squaredNorm());
  }
  max_wave_speed_ = std::sqrt(std::sqrt(max_wave4));
  max_speed_ = std::sqrt(max_speed_sq);
}

template <int D>
double Solver<D>::wave_speed4(std::size_t p) const {
  const MaterialModel& model = materials_[points_.material[p]];
  const double Je2 = model.kind == ModelKind::DruckerPrager ? points_.be[p].determinant() : 1.0;
  return model.wave_speed4(points_.mass[p] / points_.volume0[p], points_.J[p], Je2);
}

template <int D>
void Solver<D>::add_point(const Vec<D>& x, const Vec<D>& v, const Mat<D>& C, double mass, double volume,
                          const Mat<D>& stress, std::uint16_t material) {
  const MaterialModel& model = materials_.at(material);
  points_.add(x, v, mass, volume, material);
  const std::size_t p = points_.size() - 1;
  points_.C[p] = C;
  points_.stress[p] = stress;
  if (model.kind == ModelKind::DruckerPrager) points_.be[p] = elastic_state_for_stress<D>(model, stress);
  max_wave_speed_ = std::max(max_wave_speed_, std::sqrt(std::sqrt(wave_speed4(p))));
  max_speed_ = std::max(max_speed_, v.norm());
}

template <int D>
void Solver<D>::p2g(double dt) {
  const std::size_t n_points = points_.size();
  const double dx = grid_.dx;
  const double stress_scale = dt * coupler::kQuadraticInverseInertia / (dx * dx);
  const std::size_t span = stencil_span(grid_);
  const int n_threads = active_threads();
  // Threads that actually ran: OpenMP may give fewer than asked (a thread limit, dynamic
  // adjustment, a call from inside another parallel region), so the points are split by
  // the team obtained and only the grids of that team are summed.
  int team = 1;

  transfer_memory_ = transfer_memory(dt, transfer_reference_dt());
  const bool memory = transfer_memory_ > 0;
  if (memory && grid_.transfer_velocity.empty()) grid_.transfer_velocity.assign(grid_.num_nodes(), Vec<D>::Zero());

  // Clear what the last step touched.
  std::fill(grid_.mass.begin() + active_lo_, grid_.mass.begin() + active_hi_, 0.0);
  std::fill(grid_.momentum.begin() + active_lo_, grid_.momentum.begin() + active_hi_, Vec<D>::Zero());
  if (!grid_.transfer_velocity.empty())
    std::fill(grid_.transfer_velocity.begin() + active_lo_, grid_.transfer_velocity.begin() + active_hi_,
              Vec<D>::Zero());

#pragma omp parallel num_threads(n_threads)
  {
    const int t = omp_get_thread_num();
    const int n = omp_get_num_threads();  // <= n_threads, the same for every member
    if (t == 0) team = n;
    ThreadGrid& tg = thread_grids_[t];
    double* mass = t == 0 ? grid_.mass.data() : tg.mass.data();
    Vec<D>* momentum = t == 0 ? grid_.momentum.data() : tg.momentum.data();
    if (t > 0) {
      std::fill(mass + tg.lo, mass + tg.hi, 0.0);
      std::fill(momentum + tg.lo, momentum + tg.hi, Vec<D>::Zero());
      if (memory && tg.transfer.empty()) tg.transfer.assign(grid_.num_nodes(), Vec<D>::Zero());
      if (!tg.transfer.empty()) std::fill(tg.transfer.begin() + tg.lo, tg.transfer.begin() + tg.hi, Vec<D>::Zero());
    }
    Vec<D>* transfer = !memory ? nullptr : t == 0 ? grid_.transfer_velocity.data() : tg.transfer.data();
    const std::size_t begin = n_points * t / n, end = n_points * (t + 1) / n;
    std::size_t lo = grid_.num_nodes(), hi = 0;
    for (std::size_t p = begin; p < end; ++p) {
      const coupler::QuadraticStencil<D> st(grid_.to_cell_units(points_.x[p]));
      const double m = points_.mass[p];
      // MLS-MPM: the stress force and the APIC affine momentum share one matrix. A coupled run's
      // fill pressure adds to the stress as -p I (docs/design.md section 5.4).
      const double force_scale = stress_scale * points_.volume(p);
      Mat<D> affine = m * points_.C[p] - force_scale * points_.stress[p];
      affine.diagonal().array() += force_scale * points_.fill_pressure[p];
      const Vec<D> mv = m * (points_.v[p] + dt * points_.body_accel[p]);
      const std::size_t base = grid_.index(st.base);
      lo = std::min(lo, base);
      hi = std::max(hi, base + span + 1);
      const Mat<D> affine_dx = affine * dx;
      const Mat<D> carried_dx = (m * dx) * points_.C[p];
      const Vec<D> own = m * points_.v[p];
      coupler::for_each_stencil_node<D>(st, grid_, [&](std::size_t k, double w, const Vec<D>& offset) {
        mass[k] += w * m;
        Vec<D> mom = mv;
        mom.noalias() += affine_dx * offset;
        momentum[k] += w * mom;
        if (memory) {  // the same without the forces
          Vec<D> carried = own;
          carried.noalias() += carried_dx * offset;
          transfer[k] += w * carried;
        }
      });
    }
    tg.lo = lo;
    tg.hi = std::max(lo, hi);
  }
  std::size_t lo = grid_.num_nodes(), hi = 0;
  // Grids of threads outside this call's team hold an earlier call's sums: never read them.
  for (int t = 0; t < team; ++t) {
    lo = std::min(lo, thread_grids_[t].lo);
    hi = std::max(hi, thread_grids_[t].hi);
  }
  hi = std::max(lo, hi);
  // Sum the other threads' contributions into the main grid in thread order
  // (fixed order: results do not depend on scheduling, only on the team size).
  if (team > 1) {
#pragma omp parallel for schedule(static) num_threads(team)
    for (std::size_t k = lo; k < hi; ++k)
      for (int t = 1; t < team; ++t) {
        const ThreadGrid& tg = thread_grids_[t];
        if (k >= tg.lo && k < tg.hi) {
          grid_.mass[k] += tg.mass[k];
          grid_.momentum[k] += tg.momentum[k];
          if (memory) grid_.transfer_velocity[k] += tg.transfer[k];
        }
      }
  }
  active_lo_ = lo;
  active_hi_ = hi;
}

template <int D>
void Solver<D>::apply_boundaries(std::size_t node, Vec<D>& v) const {
  const Vec<D> x = grid_.node_position(grid_.node_of(node));
  auto contact = [&v](const RigidBoundary<D>& b, const Vec<D>& n) {
    const Vec<D> vr = v - b.velocity;
    const double vn = vr.dot(n);
    if (b.spec.contact == Contact::Sticky) {
      v = b.velocity;
      return;
    }
    if (b.spec.separating && vn >= 0.0) return;
    Vec<D> vt = vr - vn * n;
    if (b.spec.contact == Contact::Friction) {
      const double vt_norm = vt.norm();
      if (vt_norm > 0) vt *= std::max(0.0, 1.0 - b.spec.friction * std::abs(vn) / vt_norm);
    }
    v = b.velocity + vt;
  };
  // Nodes on a boundary (to rounding: node positions and planes are computed
  // differently) count as boundary nodes, whatever the compiler's FMA choices.
  const double on = 1e-9 * grid_.dx;
  for (const auto& b : boundaries_) {
    if (b.spec.kind == BoundaryKind::Plane) {
      if ((x - b.point).dot(b.normal) <= on) contact(b, b.normal);
    } else if (b.spec.inside) {
      for (int a = 0; a < D; ++a) {
        if (x[a] <= b.lower[a] + on) contact(b, Vec<D>::Unit(a));
        if (x[a] >= b.upper[a] - on) contact(b, -Vec<D>::Unit(a));
      }
    } else if ((x.array() > b.lower.array() - on).all() && (x.array() < b.upper.array() + on).all()) {
      // Obstacle: push out through the nearest face.
      int axis = 0;
      double best = std::numeric_limits<double>::infinity(), sign = 1;
      for (int a = 0; a < D; ++a) {
        if (x[a] - b.lower[a] < best) best = x[a] - b.lower[a], axis = a, sign = -1;
        if (b.upper[a] - x[a] < best) best = b.upper[a] - x[a], axis = a, sign = 1;
      }
      contact(b, sign * Vec<D>::Unit(axis));
    }
  }
}

template <int D>
void Solver<D>::grid_update(double dt) {
  const std::size_t lo = active_lo_, hi = active_hi_;
  const double keep = std::max(0.0, 1.0 - scene_.time.damping * dt);
  const bool memory = transfer_memory_ > 0;
#pragma omp parallel for schedule(static) num_threads(active_threads())
  for (std::size_t k = lo; k < hi; ++k) {
    const double m = grid_.mass[k];
    if (m <= 0.0) {
      grid_.momentum[k].setZero();
      continue;
    }
    if (memory) grid_.transfer_velocity[k] /= m;
    Vec<D> v = (grid_.momentum[k] / m + dt * gravity_) * keep;
    apply_boundaries(k, v);
    grid_.momentum[k] = v;  // from here on the array holds node velocities
  }
}

template <int D>
void Solver<D>::g2p(double dt) {
  const std::size_t n_points = points_.size();
  const double dx = grid_.dx;
  const double inv_inertia = coupler::kQuadraticInverseInertia / (dx * dx);
  // Points must keep their stencil on the grid: allow 1.5 cells past the domain.
  const Vec<D> lo = grid_.domain_lower.array() - 1.5 * dx, hi = grid_.domain_upper.array() + 1.5 * dx;
  const std::size_t none = std::numeric_limits<std::size_t>::max();
  const bool memory = transfer_memory_ > 0;
  std::size_t first_bad = none;
  double max_speed_sq = 0, max_wave4 = 0, fill_work = 0;
#pragma omp parallel for schedule(static) num_threads(active_threads()) reduction(max : max_speed_sq, max_wave4) \
    reduction(min : first_bad) reduction(+ : fill_work)
  for (std::size_t p = 0; p < n_points; ++p) {
    const coupler::QuadraticStencil<D> st(grid_.to_cell_units(points_.x[p]));
    Vec<D> v = Vec<D>::Zero(), transferred = Vec<D>::Zero();
    Mat<D> B = Mat<D>::Zero();
    coupler::for_each_stencil_node<D>(st, grid_, [&](std::size_t k, double w, const Vec<D>& offset) {
      const Vec<D> wv = w * grid_.momentum[k];
      v += wv;
      B.noalias() += wv * offset.transpose();  // noalias: no temporary for the outer product
      if (memory) transferred += w * grid_.transfer_velocity[k];
    });
    B *= dx;
    const Mat<D> C = inv_inertia * B;
    // APIC takes the grid's field; a step shorter than the reference keeps a share of the point's
    // own velocity beyond it (FLIP), so that the transfers' smoothing per unit time does not grow
    points_.v[p] = memory ? Vec<D>(v + transfer_memory_ * (points_.v[p] - transferred)) : v;
    points_.C[p] = C;
    points_.x[p] += dt * v;
    // the fill pressure's power over the step, with the volume it acted on in P2G
    fill_work += dt * points_.fill_pressure[p] * points_.volume(p) * C.trace();
    const Mat<D> f = Mat<D>::Identity() + dt * C;
    points_.J[p] *= f.determinant();
    const MaterialModel& model = materials_[points_.material[p]];
    if (model.kind == ModelKind::DruckerPrager)
      update_drucker_prager<D>(model, f, points_.be[p], points_.stress[p], points_.plastic_strain[p]);
    else
      update_mu_i<D>(model, C, dt, points_.mass[p] / points_.volume(p), points_.stress[p], points_.plastic_strain[p]);
    const double speed_sq = points_.v[p].squaredNorm();
    max_speed_sq = std::max(max_speed_sq, speed_sq);
    max_wave4 = std::max(max_wave4, wave_speed4(p));
    const bool ok = std::isfinite(speed_sq) && std::isfinite(points_.stress[p].sum()) && points_.J[p] > 0 &&
                    (points_.x[p].array() > lo.array()).all() && (points_.x[p].array() < hi.array()).all();
    if (!ok) first_bad = std::min(first_bad, p);
  }
  max_speed_ = std::sqrt(max_speed_sq);
  fill_work_ += fill_work;
  if (n_points > 0) max_wave_speed_ = std::sqrt(std::sqrt(max_wave4));
  if (first_bad != none) {
    const auto& x = points_.x[first_bad];
    std::ostringstream msg;
    if (!std::isfinite(points_.v[first_bad].squaredNorm()) || !std::isfinite(points_.stress[first_bad].sum()) ||
        !(points_.J[first_bad] > 0)) {
      // A point far lighter than the others goes first whatever the step (its mass divides its
      // grid velocities): say so rather than blame the time step alone.
      const double mean_mass =
          std::accumulate(points_.mass.begin(), points_.mass.end(), 0.0) / static_cast<double>(n_points);
      const double mass_share = points_.mass[first_bad] / mean_mass;
      msg << "the MPM state became non-finite or inverted at step " << steps_ + 1 << " (t = " << time_ + dt
          << " s, point " << first_bad << " at " << format_vec(x.data(), D) << ": J = " << points_.J[first_bad]
          << ", |v| = " << points_.v[first_bad].norm() << " m/s, dt |grad v| = " << dt * points_.C[first_bad].norm()
          << ", mass " << mass_share << " of the mean point's); ";
      if (mass_share < 1e-3)
        msg << "a point that light is a sliver the points' making or a coupling left, not a material the time step "
               "resolves: report it with the input that made it";
      else
        msg << "the time step is too large for this material: lower [time] cfl or dt";
    } else
      msg << "material point " << first_bad << " left the grid domain at t = " << time_ + dt
          << " s, position " << format_vec(x.data(), D) << "; the domain is "
          << format_vec(grid_.domain_lower.data(), D) << " to " << format_vec(grid_.domain_upper.data(), D)
          << ": enlarge [grid] lower/upper or add a boundary that holds the material";
    throw UserError(msg.str());
  }
}

template <int D>
void Solver<D>::sort_points_by_cell() {
  const std::size_t n = points_.size();
  std::vector<std::size_t> key(n);
  for (std::size_t p = 0; p < n; ++p) key[p] = grid_.index(coupler::QuadraticStencil<D>(grid_.to_cell_units(points_.x[p])).base);
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return key[a] < key[b]; });
  auto permute = [&](auto& field) {
    std::remove_reference_t<decltype(field)> sorted(n);
    for (std::size_t i = 0; i < n; ++i) sorted[i] = field[order[i]];
    field.swap(sorted);
  };
  for_each_point_field(points_, [&](const char*, auto& field) { permute(field); });
}

template <int D>
RunProgress run(Solver<D>& solver, const RunOptions& options, const std::function<void(const RunProgress&)>& progress) {
  using Clock = std::chrono::steady_clock;
  const Scene& scene = solver.scene();
  const double end = scene.time.end_time;
  const double interval = scene.output.interval > 0 ? scene.output.interval : end;
  std::unique_ptr<SnapshotWriter<D>> writer;
  if (options.write_output) {
    writer = std::make_unique<SnapshotWriter<D>>(scene.output.directory, scene);
    writer->write(solver.points(), solver.grid(), solver.time(), solver.steps());
  }
  const auto start = Clock::now();
  auto last_report = start;
  long frame = 1;
  bool state_written = true;
  double next_output = std::min(interval, end);
  const double tiny = 1e-12 * std::max(1.0, end);
  const long first_step = solver.steps();
  auto rate = [&](double wall) { return (solver.steps() - first_step) * double(solver.points().size()) / wall; };
  // the outflow through the outlets: a line every outflow_interval of simulated time
  std::ofstream outflow;
  double next_outflow = solver.time(), recorded = -std::numeric_limits<double>::infinity();
  auto record_outflow = [&] {
    if (!outflow.is_open()) return;
    outflow << solver.time() << ' ' << solver.outflow_mass() << ' ' << solver.outflow_points() << '\n';
    recorded = solver.time();
    while (next_outflow <= recorded + tiny) next_outflow += scene.output.outflow_interval;
  };
  if (options.write_output && !scene.outlets.empty()) {
    const std::string path = scene.output.directory + "/outflow.dat";
    outflow.open(path);
    if (!outflow) throw UserError("cannot write " + path);
    outflow << "# time_s mass_out points_out (mass per unit depth in 2D; mpm_solver [[outlet]])\n";
    outflow.precision(10);
    record_outflow();
  }
  while (solver.time() < end - tiny && (options.max_steps <= 0 || solver.steps() - first_step < options.max_steps)) {
    double dt = solver.next_dt();
    dt = std::min(dt, next_output - solver.time());
    solver.step(dt);
    state_written = false;
    if (solver.time() >= next_outflow - tiny) record_outflow();
    if (solver.steps() % kSortEvery == 0) solver.sort_points_by_cell();
    if (solver.time() >= next_output - tiny) {
      state_written = true;
      if (writer) writer->write(solver.points(), solver.grid(), solver.time(), solver.steps());
      ++frame;
      next_output = std::min(end, frame * interval);
    }
    const auto now = Clock::now();
    const double since = std::chrono::duration<double>(now - last_report).count();
    if (progress && scene.output.progress_interval > 0 && since >= scene.output.progress_interval) {
      const double wall = std::chrono::duration<double>(now - start).count();
      progress({solver.steps(), solver.time(), dt, wall, rate(wall)});
      last_report = now;
    }
  }
  if (solver.time() > recorded + tiny) record_outflow();    // the end of the run
  if (writer && !state_written)  // stopped early by max_steps: keep the last state
    writer->write(solver.points(), solver.grid(), solver.time(), solver.steps());
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  const RunProgress summary{solver.steps(), solver.time(), 0.0, wall, rate(wall)};
  if (progress) progress(summary);
  return summary;
}

template class Solver<2>;
template class Solver<3>;
template RunProgress run<2>(Solver<2>&, const RunOptions&, const std::function<void(const RunProgress&)>&);
template RunProgress run<3>(Solver<3>&, const RunOptions&, const std::function<void(const RunProgress&)>&);

}  // namespace mpm
