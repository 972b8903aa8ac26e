#include "mpm/coupled_continuum.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <sstream>

#include "coupler/fill_pressure.hpp"
#include "coupler/flow_regime.hpp"
#include "coupler/oracle.hpp"
#include "coupler/stencil.hpp"
#include "coupler/support_force.hpp"
#include "coupler/tuning.hpp"
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
  // the nodes lie on the container faces the continuum touches, as the DEM side's grid's do
  scene.grid.node_plane = coupler::touched_walls(c.container_lo, c.container_hi, c.touched_faces);
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
  m.density = c.nominal_density();
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

template <int D>
CoupledContinuum<D>::CoupledContinuum(const coupler::Hello& hello)
    : hello_(hello), solver_(coupled_scene(hello)), time_(hello.time) {
  const auto& grid = solver_.grid();
  zones_.assign(coupler::num_cells(static_cast<const coupler::GridGeometry<D>&>(grid)), coupler::kDiscrete);
  dem_mass_.assign(grid.num_nodes(), 0.0);
  dem_momentum_.assign(grid.num_nodes(), Vec<D>::Zero());
  support_.assign(grid.num_nodes(), coupler::SupportNode<D>{});
  touched_slot_.assign(grid.num_nodes(), -1);
  const MaterialModel& material = solver_.materials().front();
  fill_modulus_ = hello.continuum.fill_share * material.template bulk_modulus<D>() + hello.continuum.fill_modulus;
  // The fill pressure's stiffness is not in the stable step: it raises the points' wave speed by
  // up to sqrt(1 + K_fill / M), M = lambda + 2G the P-wave modulus of the stable step.
  const double p_wave = material.lame_lambda + 2.0 * material.shear_modulus;
  if (hello.continuum.cfl * std::sqrt(1.0 + fill_modulus_ / p_wave) > 1.0)
    throw UserError("the fill pressure's modulus " + std::to_string(fill_modulus_) + " Pa stiffens the continuum (P-wave "
                    "modulus " + std::to_string(p_wave) + " Pa) past what cfl " + std::to_string(hello.continuum.cfl) +
                    " keeps stable: lower the fix's cfl or fill");
  full_node_mass_ = hello.continuum.packing_fraction * hello.continuum.grain_density * std::pow(grid.dx, D);
  fill_pressure_.assign(grid.num_nodes(), 0.0);
  const std::string dir = coupler::get_text(hello.continuum.output_path);
  if (hello.continuum.output_every > 0 && !dir.empty()) {
    Scene scene = solver_.scene();
    scene.output.grid_fields = true;
    writer_ = std::make_unique<SnapshotWriter<D>>(dir, scene);
  }
}

template <int D>
double CoupledContinuum<D>::grain_share(int zone) const {
  return zone == coupler::kDiscrete ? 1.0 : zone == coupler::kHybrid ? hello_.continuum.grain_weight : 0.0;
}

template <int D>
std::vector<coupler::RezoneCell<D>> CoupledContinuum<D>::plan_rezone(
    double time, int zone_source, const std::vector<std::int8_t>& given, const coupler::OracleSettings& os,
    const std::vector<std::uint64_t>& discrete_cells, const std::vector<std::vector<coupler::CellGrains>>& volumes) {
  if (step_open()) throw UserError("internal: a rezone while a substep is open");
  const auto& geometry = static_cast<const coupler::GridGeometry<D>&>(solver_.grid());
  const coupler::ContinuumSettings& cs = hello_.continuum;
  const std::size_t n = zones_.size();
  before_ = totals(0);
  rezone_start_energy_ = point_energy();
  std::vector<double> volume(n, 0.0), kinetic(n, 0.0);
  std::vector<double>& grain_mass = cell_grain_mass_;
  grain_mass.assign(n, 0.0);
  for (const auto& list : volumes)
    for (const auto& r : list) {
      if (r.cell >= n)
        throw UserError("a DEM rank sent the grain volume of cell " + std::to_string(r.cell) + " outside the grid");
      if (!std::isfinite(r.volume) || !std::isfinite(r.mass) || !std::isfinite(r.kinetic) || r.volume < 0 ||
          r.mass < 0 || r.kinetic < 0)
        throw UserError("a DEM rank sent a non-finite or negative grain volume, mass or kinetic energy for cell " +
                        std::to_string(r.cell) + " (volume " + std::to_string(r.volume) + ", mass " +
                        std::to_string(r.mass) + ", kinetic energy " + std::to_string(r.kinetic) +
                        "): a grain's size, mass, position or velocity is not finite");
      volume[r.cell] += r.volume;
      grain_mass[r.cell] += r.mass;
      kinetic[r.cell] += r.kinetic;
    }
  auto& pts = solver_.points();
  std::vector<std::uint8_t> has_points(n, 0);
  std::vector<std::uint32_t> point_count(n, 0);
  std::vector<double> point_mass(n, 0.0);
  std::vector<std::size_t> point_cell(pts.size());
  for (std::size_t p = 0; p < pts.size(); ++p) {
    point_cell[p] = coupler::cell_index<D>(geometry, coupler::cell_of<D>(geometry, pts.x[p]));
    has_points[point_cell[p]] = 1;
    ++point_count[point_cell[p]];
    point_mass[point_cell[p]] += pts.mass[p];
    kinetic[point_cell[p]] += 0.5 * pts.mass[p] * pts.v[p].squaredNorm();
  }

  // still material (the oracle's measure of rest, coupler::material_still; without gravity only
  // empty cells are still)
  const double rest_speed = this->rest_speed();
  std::vector<double> material_mass(n);
  for (std::size_t c = 0; c < n; ++c) material_mass[c] = grain_mass[c] + point_mass[c];
  const std::vector<std::uint8_t> still = coupler::material_still(kinetic, material_mass, rest_speed);

  // The new zones
  std::vector<std::int8_t> next;
  if (zone_source == coupler::kZonesGiven) {
    if (given.size() != n)
      throw UserError("the zone map has " + std::to_string(given.size()) + " cells, the grid " + std::to_string(n));
    for (std::size_t c = 0; c < n; ++c)
      if (given[c] != coupler::kDiscrete && given[c] != coupler::kHybrid && given[c] != coupler::kContinuum)
        throw UserError("the zone map gives cell " + std::to_string(c) + " the unknown zone " +
                        std::to_string(static_cast<int>(given[c])) + " (0 discrete, 1 hybrid, 2 continuum)");
    next = given;
  } else {
    coupler::OracleInputs<D> in;
    if (os.max_shear_rate > 0) {
      // the fastest shearing point of each cell (grains' velocities are too noisy for a shear
      // rate per cell: a cell turned discrete stays so until its zone wants points again)
      in.shear_rate.assign(n, 0.0);
      for (std::size_t p = 0; p < pts.size(); ++p)
        in.shear_rate[point_cell[p]] = std::max(in.shear_rate[point_cell[p]], coupler::shear_rate<D>(pts.C[p]));
    }
    // container faces: beyond a discrete boundary, a surface of the material; beyond a face the
    // continuum may touch, solid (material that stays discrete: coupler/oracle.hpp, box_cells)
    in.container_lo = Eigen::Map<const Eigen::Vector3d>(cs.container_lo).head<D>();
    in.container_hi = Eigen::Map<const Eigen::Vector3d>(cs.container_hi).head<D>();
    in.touched_faces = cs.touched_faces;
    // the fix's discrete regions (an orifice, an intruder) are boundaries of the material too
    for (std::uint64_t c : discrete_cells)
      if (c >= n) throw UserError("a discrete region's cell " + std::to_string(c) + " is outside the grid");
    in.discrete_cells = discrete_cells;
    in.grain_volume = volume;
    in.has_points = has_points;
    // material at rest keeps its zones (coupler::hold_zones_at_rest)
    in.rest_speed = rest_speed;
    if (zone_source == coupler::kZonesOracle && os.rest_hold > 0 && in.rest_speed > 0) {
      in.kinetic = std::move(kinetic);  // the hold is its last use
      in.mass = std::move(material_mass);
    }
    // at the start there are no previous zones to step from: the oracle goes to its fixed point
    if (zone_source != coupler::kZonesInitial) in.previous = zones_;
    next = coupler::oracle_zones<D>(geometry, in, os);
  }

  // Cells whose material moves: a changed zone, material of the wrong kind for the zone
  // (points that drifted into a discrete cell, grains into a continuum cell), a hybrid cell
  // whose grains drained out (kStarvedGrains), or a discrete cell whose grains came from a
  // hybrid one lighter than their solid mass (kLightGrains) and points near that can give it
  // (kRestReach: the cells whose points stay in a continuum or hybrid zone).
  std::vector<std::uint8_t> carriers(n, 0);
  for (std::size_t c = 0; c < n; ++c) carriers[c] = has_points[c] && next[c] != coupler::kDiscrete;
  auto carriers_near = [&](std::size_t c) {
    bool found = false;
    coupler::for_each_cell_within<D>(geometry, coupler::cell_coords<D>(geometry, c), coupler::kRestReach,
                                     [&](std::uint64_t cell) { found = found || carriers[cell]; });
    return found;
  };
  moving_.clear();
  std::vector<std::int64_t> slot(n, -1);
  repairs_.resize(n);
  for (std::size_t c = 0; c < n; ++c) {
    const bool grains = volume[c] > 0, points = has_points[c] != 0;
    if (!grains && !points) continue;
    const bool stray = (next[c] == coupler::kDiscrete && points) || (next[c] == coupler::kContinuum && grains);
    const bool starved = next[c] == coupler::kHybrid && points &&
                         grain_mass[c] < coupler::kStarvedGrains * grain_share(coupler::kHybrid) * (grain_mass[c] + point_mass[c]);
    const bool light = next[c] == coupler::kDiscrete && grains &&
                       grain_mass[c] < coupler::kLightGrains * cs.grain_density * volume[c] && carriers_near(c);
    if (next[c] == zones_[c] && !stray && !starved && !light) continue;
    // a repair (the zone stays, its grains starved or light) of a cell at rest whose grains and
    // points are those of its last repair: the rezone would do what it did then, and that left it so
    const bool repair = next[c] == zones_[c] && !stray && coupler::still_around<D>(geometry, still, c);
    if (repair && repairs_[c].same(volume[c], grain_mass[c], point_count[c])) continue;
    repairs_[c] = repair ? Repair{volume[c], grain_mass[c], point_count[c]} : Repair{};

    slot[c] = static_cast<std::int64_t>(moving_.size());
    MovingCell m;
    m.plan.cell = c;
    m.plan.zone = next[c];
    m.mechanism = coupler::rezone_mechanism(zones_[c], next[c]);
    m.plan.grain_weight = next[c] == coupler::kHybrid ? cs.grain_weight : 1.0;
    m.points.moments.cell = c;
    moving_.push_back(std::move(m));
  }
  for (std::size_t p = 0; p < pts.size(); ++p) {
    const std::int64_t k = slot[point_cell[p]];
    if (k < 0) continue;
    MovingCell& m = moving_[static_cast<std::size_t>(k)];
    m.members.push_back(p);
    const auto c = coupler::cell_coords<D>(geometry, point_cell[p]);
    add_point_body(m.points, p, coupler::cell_center<D>(geometry, c));
    Eigen::Map<Mat<D>>(m.plan.gradient) += pts.mass[p] * pts.C[p];
    m.plan.occupancy |= coupler::occupancy_of_point<D>(geometry, c, pts.x[p], 2.0 * std::pow(pts.volume(p), 1.0 / D));
  }
  std::vector<coupler::RezoneCell<D>> plans;
  plans.reserve(moving_.size());
  for (MovingCell& m : moving_) {
    if (m.points.moments.mass > 0) Eigen::Map<Mat<D>>(m.plan.gradient) /= m.points.moments.mass;
    // New grains where the zone wants grains and the cell's material is more than
    // kHeaviestGrains times its grains' solid mass (a hybrid cell's points take some surplus),
    // and wherever a discrete cell holds points (it should hold none).
    const double share = grain_share(m.plan.zone);
    const double material = grain_mass[m.plan.cell] + m.points.moments.mass;
    const double grain_solid_mass = cs.grain_density * volume[m.plan.cell];
    m.plan.make_grains = share > 0 && !m.members.empty() &&
                         (m.plan.zone == coupler::kDiscrete || material > coupler::kHeaviestGrains * grain_solid_mass);
    m.plan.points = m.points.moments;
    plans.push_back(m.plan);
  }

  zones_ = std::move(next);
  if (cell_in_box_.size() != n) {  // the box and the grid are the run's: once
    const Vec<D> lo = Eigen::Map<const Eigen::Vector3d>(hello_.box_lo).head<D>();
    const Vec<D> hi = Eigen::Map<const Eigen::Vector3d>(hello_.box_hi).head<D>();
    cell_in_box_.resize(n);
    for (std::size_t c = 0; c < n; ++c) {
      const Vec<D> x = coupler::cell_center<D>(geometry, coupler::cell_coords<D>(geometry, c));
      cell_in_box_[c] = (x.array() >= lo.array()).all() && (x.array() <= hi.array()).all();
    }
  }
  std::fill(std::begin(zone_cells_), std::end(zone_cells_), 0);
  for (std::size_t c = 0; c < n; ++c) zone_cells_[zones_[c]] += cell_in_box_[c];
  if (pts.size() == 0) time_ = time;  // an empty continuum starts its clock with its first points
  return plans;
}

template <int D>
void CoupledContinuum<D>::add_point_body(coupler::BodySums<D>& sums, std::size_t p, const Vec<D>& reference) const {
  const auto& pts = solver_.points();
  const double dx = solver_.grid().dx;
  const coupler::Spin<D> spin = (pts.mass[p] * dx * dx / coupler::kQuadraticInverseInertia) * coupler::axial<D>(pts.C[p]);
  sums.add_body(pts.x[p], pts.v[p], pts.mass[p], spin, dx * dx / 2, Mat<D>(pts.stress[p] * pts.volume(p)), reference);
}

template <int D>
void CoupledContinuum<D>::correct_points(const std::vector<std::size_t>& members, const coupler::RigidCorrection<D>& fix) {
  auto& pts = solver_.points();
  const Mat<D> spin = coupler::skew<D>(fix.omega);
  for (std::size_t p : members) {
    pts.mass[p] *= fix.mass_factor;
    pts.volume0[p] *= fix.mass_factor;  // same density, same deformation state
    pts.v[p] += fix.increment(pts.x[p]);
    pts.C[p] += spin;
  }
}

template <int D>
double CoupledContinuum<D>::energy_created(const std::vector<std::size_t>& members,
                                           const coupler::RigidCorrection<D>& fix) const {
  // kinetic energy (with the APIC affine part, dx^2/4 |C|^2) after the correction minus before
  const auto& pts = solver_.points();
  const Mat<D> spin = coupler::skew<D>(fix.omega);
  const double inertia = 0.25 * solver_.grid().dx * solver_.grid().dx;
  double change = 0;
  for (std::size_t p : members) {
    const double before = pts.v[p].squaredNorm() + inertia * pts.C[p].squaredNorm();
    const double after = (pts.v[p] + fix.increment(pts.x[p])).squaredNorm() + inertia * (pts.C[p] + spin).squaredNorm();
    change += 0.5 * pts.mass[p] * (fix.mass_factor * after - before);
  }
  return change;
}

template <int D>
std::vector<coupler::GrainCorrection<D>> CoupledContinuum<D>::complete_rezone(
    const std::vector<std::vector<coupler::GrainSums<D>>>& grains) {
  const auto& geometry = static_cast<const coupler::GridGeometry<D>&>(solver_.grid());
  std::map<std::uint64_t, std::size_t> slot;
  for (std::size_t k = 0; k < moving_.size(); ++k) slot.emplace(moving_[k].plan.cell, k);
  std::vector<coupler::BodySums<D>> carried(moving_.size()), solid(moving_.size());
  for (const auto& list : grains)  // rank order: deterministic
    for (const auto& g : list) {
      const auto it = slot.find(g.carried.moments.cell);
      if (it == slot.end())
        throw UserError("a DEM rank sent grain sums for cell " + std::to_string(g.carried.moments.cell) +
                        ", which is not being rezoned");
      carried[it->second].add(g.carried);
      solid[it->second].add(g.solid);
    }

  // 1. How each cell's material splits, as fractions of it: its grains, each at its new weight
  // times its solid mass (never heavier or lighter than their density allows), its points, and
  // a rest for the points of the neighbouring cells where the cell keeps none (discrete) or too
  // few for what the grains leave.
  struct Split {
    double grains = 0, points = 0, rest = 0;
  };
  std::vector<Split> split(moving_.size());
  std::vector<coupler::CellMoments<D>> total(moving_.size());
  for (std::size_t k = 0; k < moving_.size(); ++k) {
    const MovingCell& m = moving_[k];
    total[k] = carried[k].moments;
    total[k].add(m.points.moments);
    total[k].cell = m.plan.cell;
    if (!(total[k].mass > 0)) continue;
    const double share = grain_share(m.plan.zone), point_share = 1.0 - share;
    Split& s = split[k];
    if (share > 0 && solid[k].moments.mass > 0) s.grains = share * solid[k].moments.mass / total[k].mass;
    s.points = point_share > 0 && 1.0 - s.grains >= 0.5 * point_share ? 1.0 - s.grains : point_share;
    s.rest = 1.0 - s.grains - s.points;
  }

  constexpr double kRoundOff = 1e-12;      // rests below this fraction of a cell's material are round-off
  constexpr double kSmallestPart = 1e-6;   // smallest fraction of a cell's material grains or points take
  for (std::size_t k = 0; k < moving_.size(); ++k) {
    Split& s = split[k];
    if (std::abs(s.rest) < kRoundOff) {  // round-off: to the larger part, never into a zero one
      (s.grains > s.points ? s.grains : s.points) += s.rest;
      s.rest = 0;
    }
    // too small a part for its points' rigid correction (rotation rate of round-off over round-off)
    if (s.points > 0 && s.points < kSmallestPart && solid[k].moments.mass > 0) s.grains += s.points, s.points = 0;
  }

  // 2. The cells' points: corrected onto their part, renewed (too few), made, or removed.
  auto& pts = solver_.points();
  std::vector<char> remove(pts.size(), 0);
  moved_cells_ = static_cast<std::int64_t>(moving_.size());
  points_made_ = points_removed_ = 0;
  std::vector<std::vector<std::size_t>> own(moving_.size());  // the points each cell keeps or made
  // a rigid correction of points, its change of their energy tallied under `tally` (rezone_energy_)
  auto correct_tallied = [&](const std::vector<std::size_t>& members, const coupler::RigidCorrection<D>& fix,
                             typename RezoneEnergy::Parts& tally, std::size_t k) {
    const auto before = energy_parts(members);
    correct_points(members, fix);
    const auto change = energy_parts(members) - before;
    tally += change;
    rezone_energy_.by_mechanism[moving_[k].mechanism] += change;
  };
  auto make_points = [&](std::size_t k, double part, float label) {
    const MovingCell& m = moving_[k];
    const std::size_t first = own[k].size();
    const Vec<D> centre = coupler::cell_center<D>(geometry, coupler::cell_coords<D>(geometry, m.plan.cell));
    coupler::BodySums<D> material = carried[k];  // new points move with the material's affine field
    material.add(m.points);
    const auto& cs = hello_.continuum;
    for (const auto& p : coupler::points_from_moments<D>(total[k].scaled(part), geometry, cs.points_per_axis, part,
                                                         material.affine_motion(centre),
                                                         Eigen::Map<const Eigen::Vector3d>(cs.container_lo).head<D>(),
                                                         Eigen::Map<const Eigen::Vector3d>(cs.container_hi).head<D>())) {
      solver_.add_point(p.x, p.v, p.C, p.mass, p.volume, p.stress);
      pts.weight.back() = label;
      own[k].push_back(pts.size() - 1);
      remove.push_back(0);
      ++points_made_;
    }
    const auto made = energy_parts({own[k].begin() + static_cast<std::ptrdiff_t>(first), own[k].end()});
    rezone_energy_.made += made;
    rezone_energy_.by_mechanism[m.mechanism] += made;
  };
  // the points' weight label is their zone's share (1 for points a discrete cell keeps)
  auto label_of = [&](const MovingCell& m) {
    const double nominal = 1.0 - grain_share(m.plan.zone);
    return static_cast<float>(nominal > 0 ? nominal : 1.0);
  };
  for (std::size_t k = 0; k < moving_.size(); ++k) {
    const MovingCell& m = moving_[k];
    const Split& s = split[k];
    const coupler::BodySums<D>& P = m.points;
    const Vec<D> centre = coupler::cell_center<D>(geometry, coupler::cell_coords<D>(geometry, m.plan.cell));
    // Points carrying less than half their part are renewed, as stray grains are (above).
    const bool thin = P.moments.mass > 0 && P.moments.mass < 0.5 * s.points * total[k].mass;
    if (P.moments.mass > 0 && (s.points <= 0 || thin)) {
      for (std::size_t p : m.members) remove[p] = 1;
      points_removed_ += static_cast<std::int64_t>(m.members.size());
    }
    if (!(s.points > 0)) continue;
    if (P.moments.mass > 0 && !thin) {
      correct_tallied(m.members, coupler::rigid_correction<D>(P, total[k].scaled(s.points), centre),
                      rezone_energy_.corrected, k);
      for (std::size_t p : m.members) pts.weight[p] = label_of(m);
      own[k] = m.members;
    } else if (total[k].mass > 0) {
      make_points(k, s.points, label_of(m));
    }
  }

  // 3. The rests go to the surviving points of the nearest cells that stay continuum or hybrid
  // (one rigid correction each: exact): the cells within the smallest reach, up to coupler::kRestReach,
  // whose points carry at least kRestCarriers times the rest (their masses change by at most
  // 1/2; the cells around the rest keep the correction's rotation small). A cell whose grains
  // and points already hold its volume of solid grain material takes no surplus: rests given
  // again and again to the same points piled up there (a 100 d collapse: 7 % of the material in
  // 8 points, 40 times a cell's solid content, creeping through grains at rest). With no such
  // points near, the cell keeps its rest: its grains take a deficit, and a surplus up to
  // kHeaviestKept times their solid share (by less than half a grain's where new grains were
  // made to fit), its points the remainder (a discrete cell's then wait there for room for grains).
  // A deficit is not taken from points already light (under coupler::kLightestDebtor of a point's
  // mass at the packing): taken again and again from the same points behind a flow's front,
  // deficits of at most half their mass each drained them to 1e-8 of it (the 100 d collapse with
  // the back wall and the floor touched: slivers in the hybrid cells at its front held pressures
  // a hundred times the continuum's, and one went non-finite at t = 0.62 s).
  constexpr double kRestCarriers = 2.0;
  const double lightest_debtor =
      coupler::kLightestDebtor * full_node_mass_ / std::pow(static_cast<double>(hello_.continuum.points_per_axis), D);
  std::map<std::uint64_t, std::vector<std::size_t>> carriers;  // cell -> its points that can take a rest
  const bool rests = std::any_of(split.begin(), split.end(), [](const Split& s) { return s.rest != 0; });
  for (std::size_t p = 0; rests && p < pts.size(); ++p) {  // (most rezones leave no rest)
    if (remove[p]) continue;
    const std::uint64_t c = coupler::cell_index<D>(geometry, coupler::cell_of<D>(geometry, pts.x[p]));
    if (zones_[c] != coupler::kDiscrete) carriers[c].push_back(p);
  }
  // the grains' carried mass per cell once this rezone's cells are done, and a cell's solid content
  for (std::size_t k = 0; rests && k < moving_.size(); ++k)
    cell_grain_mass_[moving_[k].plan.cell] = split[k].grains * total[k].mass;
  const double solid_content = hello_.continuum.grain_density * std::pow(geometry.dx, D);
  auto full = [&](std::uint64_t cell, const std::vector<std::size_t>& members) {
    double material = cell_grain_mass_[cell];
    for (std::size_t p : members) material += pts.mass[p];
    return material >= solid_content;
  };
  rest_moved_ = rest_kept_ = 0;
  for (std::size_t k = 0; k < moving_.size(); ++k) {
    Split& s = split[k];
    if (s.rest == 0) continue;
    const coupler::CellMoments<D> rest = total[k].scaled(s.rest);
    const auto c = coupler::cell_coords<D>(geometry, moving_[k].plan.cell);
    const Vec<D> centre = coupler::cell_center<D>(geometry, c);
    auto correction = [&](const std::vector<std::size_t>& members, const coupler::CellMoments<D>& part) {
      coupler::BodySums<D> now;
      for (std::size_t p : members) add_point_body(now, p, centre);
      coupler::CellMoments<D> target = now.moments;
      target.add(part);
      return coupler::rigid_correction<D>(now, target, centre);
    };
    auto give = [&](const std::vector<std::size_t>& members, const coupler::CellMoments<D>& part) {
      correct_tallied(members, correction(members, part), rezone_energy_.rests, k);
    };
    // Of the reaches whose carriers hold enough mass, the one whose correction creates the least
    // kinetic energy: moving a rest keeps its angular momentum exactly by spinning the carriers
    // up, ~ (rest's lever arm x momentum)^2 / (2 carriers' inertia) (the energy ledger measured
    // rests that multiplied a patch's energy 250-fold).
    std::vector<std::size_t> members, candidate;
    double created_least = std::numeric_limits<double>::infinity();
    const double needed = kRestCarriers * std::abs(rest.mass);
    for (int reach = 1; reach <= coupler::kRestReach; ++reach) {
      candidate.clear();
      double mass = 0;
      coupler::for_each_cell_within<D>(geometry, c, reach, [&](std::uint64_t cell) {
        const auto it = carriers.find(cell);
        if (it == carriers.end() || (rest.mass > 0 && full(cell, it->second))) return;
        for (std::size_t p : it->second)
          if (rest.mass > 0 || pts.mass[p] >= lightest_debtor) candidate.push_back(p), mass += pts.mass[p];
      });
      if (!(mass >= needed)) continue;
      const double created = energy_created(candidate, correction(candidate, rest));
      if (created < created_least) created_least = created, members = candidate;
    }
    if (!members.empty()) {
      give(members, rest);
      ++rest_moved_;
    } else {
      ++rest_kept_;
      // the grains up to kHeaviestKept times their solid share, the points the remainder
      const double share = grain_share(moving_[k].plan.zone);
      const double most = share * coupler::kHeaviestKept * solid[k].moments.mass / total[k].mass;
      const double to_grains = solid[k].moments.mass > 0 ? std::min(s.rest, std::max(0.0, most - s.grains)) : 0.0;
      s.grains += to_grains;
      const double remainder = s.rest - to_grains;
      if (remainder > kRoundOff) {
        const coupler::CellMoments<D> left = total[k].scaled(remainder);
        double own_mass = 0;
        for (std::size_t p : own[k]) own_mass += pts.mass[p];
        const MovingCell& m = moving_[k];
        if (own_mass >= 0.5 * left.mass) {
          give(own[k], left);
        } else if (own[k].empty() && !m.members.empty() && m.points.moments.mass >= 0.5 * left.mass) {
          // Points step 2 removed (a discrete cell's waiting points) take the remainder again,
          // corrected rigidly onto it: remade at the cell's lattice at every rezone, they jumped
          // there and lost their deformation, and the run made and removed them again and again.
          for (std::size_t p : m.members) remove[p] = 0, pts.weight[p] = 1.0f;
          points_removed_ -= static_cast<std::int64_t>(m.members.size());
          correct_tallied(m.members, coupler::rigid_correction<D>(m.points, left, centre), rezone_energy_.rests, k);
          own[k] = m.members;
        } else {
          make_points(k, remainder, 1.0f);
        }
      } else {
        s.grains += remainder;
      }
      cell_grain_mass_[moving_[k].plan.cell] = s.grains * total[k].mass;
    }
    s.rest = 0;
  }

  // 4. What the grains of each cell become.
  std::vector<coupler::GrainCorrection<D>> corrections;
  for (std::size_t k = 0; k < moving_.size(); ++k) {
    const MovingCell& m = moving_[k];
    if (!(solid[k].moments.mass > 0)) continue;
    const Vec<D> centre = coupler::cell_center<D>(geometry, coupler::cell_coords<D>(geometry, m.plan.cell));
    coupler::GrainCorrection<D> gc;
    gc.cell = m.plan.cell;
    gc.mechanism = m.mechanism;
    gc.weight = m.plan.grain_weight;
    if (split[k].grains <= 0) gc.remove = 1;
    else {
      const auto fix = coupler::rigid_correction<D>(solid[k], total[k].scaled(split[k].grains), centre);
      gc.mass_factor = fix.mass_factor;
      for (int a = 0; a < D; ++a) gc.velocity[a] = fix.velocity[a], gc.centre[a] = fix.centre[a];
      for (int a = 0; a < fix.omega.size(); ++a) gc.omega[a] = fix.omega[a];
    }
    corrections.push_back(gc);
  }
  // new points go to their cells' places in the order; a rezone that made or removed none (most
  // of the oracle's steps once the material rests) leaves it to the solver's periodic sort
  if (points_made_ > 0 || points_removed_ > 0) {
    std::vector<std::size_t> removed[coupler::kMechanisms];    // only moving cells' points are removed
    for (const MovingCell& m : moving_)
      for (std::size_t p : m.members)
        if (remove[p]) removed[m.mechanism].push_back(p);
    for (int mechanism = 0; mechanism < coupler::kMechanisms; ++mechanism) {
      const auto parts = energy_parts(removed[mechanism]);
      rezone_energy_.removed -= parts;
      rezone_energy_.by_mechanism[mechanism] -= parts;
    }
    remove_points(pts, remove);
    solver_.sort_points_by_cell();
  }
  moving_.clear();
  const double rezone_change = point_energy() - rezone_start_energy_;
  ledger_.rezone += rezone_change;
  ledger_.energy += rezone_change;
  return corrections;
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
    if (solver_.steps() % kSortEvery == 0) solver_.sort_points_by_cell();
  }
  solver_.p2g(h);
  solver_.grid_update(h);
  pending_dt_ = h;
  open_time_ = time;
  substeps_ = substeps;
  interval_ = span;
}

template <int D>
double CoupledContinuum<D>::rest_speed() const {
  const auto& cs = hello_.continuum;
  return coupler::kRestSpeed * std::sqrt(Eigen::Map<const Eigen::Vector3d>(cs.gravity).norm() * cs.grain_diameter);
}

template <int D>
std::vector<double> CoupledContinuum<D>::touched_field_shares() {
  // mass-weighted over the points of the current substep's P2G: sum_p N_ip m_p share_p / sum_p N_ip m_p,
  // share_p from the point's inertial number and its speed (coupler/flow_regime.hpp)
  std::vector<double> share(touched_.size(), 0.0), mass(touched_.size(), 0.0);
  const auto& pts = solver_.points();
  const Grid<D>& grid = solver_.grid();
  const auto& geometry = static_cast<const coupler::GridGeometry<D>&>(grid);
  // The stencil bases that reach a touched node (the node less 0-2 cells per axis), so that only
  // the points of the band and its edge are visited in full: this runs on the exchange's
  // critical path, and the band is a small part of a large continuum.
  if (reaching_base_.size() != grid.num_nodes()) reaching_base_.assign(grid.num_nodes(), 0);
  std::vector<std::size_t> marked;
  constexpr int kStencilNodes = D == 2 ? 9 : 27;
  for (std::size_t k : touched_) {
    const auto node = geometry.node_of(k);
    for (int o = 0; o < kStencilNodes; ++o) {
      auto base = node;
      bool on_grid = true;
      for (int a = 0, rest = o; a < D; ++a, rest /= 3) on_grid = on_grid && (base[a] -= rest % 3) >= 0;
      if (!on_grid) continue;
      const std::size_t b = geometry.index(base);
      if (!reaching_base_[b]) reaching_base_[b] = 1, marked.push_back(b);
    }
  }
  const double d = hello_.continuum.grain_diameter, rho = hello_.continuum.grain_density;
  const double rest_speed = this->rest_speed();  // without gravity only material at rest is still
  for (std::size_t p = 0; p < pts.size(); ++p) {
    const coupler::QuadraticStencil<D> stencil(grid.to_cell_units(pts.x[p]));
    if (!reaching_base_[geometry.index(stencil.base)]) continue;
    const double q = coupler::field_share(coupler::inertial_number<D>(pts.C[p], pts.stress[p], d, rho)) *
                     coupler::still_share(pts.v[p].norm(), rest_speed);
    coupler::for_each_stencil_node<D>(stencil, geometry, [&](std::size_t k, double w, const auto&) {
      const std::int64_t t = touched_slot_[k];
      if (t < 0) return;
      share[t] += w * pts.mass[p] * q;
      mass[t] += w * pts.mass[p];
    });
  }
  for (std::size_t b : marked) reaching_base_[b] = 0;
  for (std::size_t t = 0; t < share.size(); ++t) share[t] = mass[t] > 0 ? share[t] / mass[t] : 0.0;
  return share;
}

template <int D>
std::vector<std::vector<coupler::NodeUpdate>> CoupledContinuum<D>::agree(
    const std::vector<std::vector<coupler::NodeRecord>>& per_rank, bool field_shares) {
  Grid<D>& grid = solver_.grid();
  const std::size_t n_nodes = grid.num_nodes();
  // Every record is checked before any is added: a bad one leaves the node sums untouched.
  for (std::size_t rank = 0; rank < per_rank.size(); ++rank)
    for (const auto& r : per_rank[rank]) {
      if (r.node >= n_nodes)
        throw UserError("a DEM rank sent node " + std::to_string(r.node) + " outside the grid of " +
                        std::to_string(n_nodes) + " nodes");
      bool finite = std::isfinite(r.mass);
      for (int a = 0; a < 3; ++a) finite = finite && std::isfinite(r.momentum[a]);
      if (!finite || r.mass < 0)
        throw UserError("DEM rank " + std::to_string(rank) + " sent a " +
                        (finite ? "negative" : "non-finite (NaN or inf)") + " mass or momentum for node " +
                        std::to_string(r.node) + " (mass " + std::to_string(r.mass) +
                        " kg, momentum " + std::to_string(r.momentum[0]) + ", " + std::to_string(r.momentum[1]) + ", " +
                        std::to_string(r.momentum[2]) + "): a coupled grain's mass, position or velocity is not "
                        "finite - the DEM run went unstable (check the time step) or its input set a NaN");
    }
  // DEM mass and momentum of every node over all ranks.
  for (const auto& list : per_rank)
    for (const auto& r : list) {
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
  double shared_mass = 0, excess_mass = 0;  // the overlap of the two sides (StepAck::overlap)
  // The agreement closes the gap between the sides' node velocities as a relaxation of time
  // agreement_time: by the share 1 - exp(-T / agreement_time) over an interval T (all of it
  // when agreement_time is 0, the reference method). Closing it whole at every exchange damps
  // the grains' fluctuations once per exchange, so the flow depended on the exchange interval
  // (collapse runout -26 % exchanging every step, -9 % every 5; docs/fix_hybrid_mpm.md).
  const double tau = hello_.continuum.agreement_time;
  const double closing = tau > 0 && interval_ > 0 ? -std::expm1(-interval_ / tau) : 1.0;
  // the energy ledger: the continuum's own steps since the last bracket, then the agreement
  const double energy_before = grid_energy();
  ledger_.physics += energy_before - ledger_.energy;
  double agreement_change = 0;
  std::vector<Vec<D>> impulse_per_mass(touched_.size()), support(touched_.size(), Vec<D>::Zero());
  // The support force between exchanges: what the agreement had to add over the last
  // interval becomes a steady force for the next one (coupler/support_force.hpp), so grains
  // resting on the continuum are held between exchanges, not only at them.
  const double gain = hello_.continuum.support_gain;
  std::vector<coupler::SupportNode<D>> old_support(touched_.size());
  for (std::size_t t = 0; t < touched_.size(); ++t) old_support[t] = support_[touched_[t]];
  for (std::size_t k : support_nodes_) support_[k] = coupler::SupportNode<D>{};
  support_nodes_.clear();
  for (std::size_t k : fill_nodes_) fill_pressure_[k] = 0.0;
  fill_nodes_.clear();
  for (std::size_t t = 0; t < touched_.size(); ++t) {
    const std::size_t k = touched_[t];
    const double m_dem = dem_mass_[k];
    const Vec<D> v_dem = m_dem > 0 ? Vec<D>(dem_momentum_[k] / m_dem) : Vec<D>::Zero();
    const double m_mpm = grid.mass[k];
    Vec<D> common = v_dem;
    if (m_mpm > 0 && m_dem > 0) {
      const Vec<D> v_mpm = grid.momentum[k];  // a velocity after the grid update
      mismatch_ = std::max(mismatch_, (v_dem - v_mpm).norm());
      Vec<D> agreed = (m_mpm * v_mpm + m_dem * v_dem) / (m_mpm + m_dem);
      solver_.constrain_velocity(k, agreed);
      // each side moves the share `closing` of the way to the agreed velocity (both by the same
      // momentum, opposite: exact); common is the grains' side from here on
      const Vec<D> v_mpm_new = v_mpm + closing * (agreed - v_mpm);
      common = v_dem + closing * (agreed - v_dem);
      grid.momentum[k] = v_mpm_new;
      agreement_change += 0.5 * m_mpm * (v_mpm_new.squaredNorm() - v_mpm.squaredNorm());
      ++shared_nodes_;
      shared_mass += m_mpm + m_dem;
      if (full_node_mass_ > 0) excess_mass += std::max(0.0, m_mpm + m_dem - full_node_mass_);
      // the mixture's overfill: points and grains together above the packing's mass push the
      // points apart until the next exchange (docs/design.md section 5.4)
      if (fill_modulus_ > 0) {
        const double pressure = coupler::fill_pressure(m_mpm + m_dem, full_node_mass_, fill_modulus_);
        if (pressure > 0) fill_pressure_[k] = pressure, fill_nodes_.push_back(k);
      }
      if (gain > 0) {
        const double reduced = m_dem * m_mpm / (m_dem + m_mpm);
        support_[k] = coupler::next_support<D>(old_support[t], v_dem - v_mpm, reduced, closing,
                                               m_dem * (common - v_dem), interval_, gain);
        support_nodes_.push_back(k);
        support[t] = support_[k].force / m_dem;
      }
    }
    impulse_per_mass[t] = common - v_dem;  // lambda_i / m_dem_i
    dem_momentum_[k] = common;
  }
  ledger_.agreement += agreement_change;
  ledger_.energy = energy_before + agreement_change;
  overlap_ = shared_mass > 0 ? excess_mass / shared_mass : 0.0;
  // pic regime's shares act at the agreement's rate too: of its grains' deviations from the
  // node velocity, a node's field rule closes the share `closing` over the interval. Applied
  // whole at every exchange they erased the fluctuations once per exchange, so exchanging every
  // step ran a collapse out 7.6 % short on the mean of three packings, its surface 3.1-3.4 % of H0
  // off, where every 10 was within the runs' spread (docs/design.md 5.3).
  std::vector<double> shares = field_shares ? touched_field_shares() : std::vector<double>{};
  for (std::size_t t = 0; t < shares.size(); ++t) {
    const double m = dem_mass_[touched_[t]];
    field_rule_.mass += m;
    field_rule_.quasi_static += shares[t] >= 1.0 ? m : 0.0;
    field_rule_.flowing += shares[t] <= 0.0 ? m : 0.0;
    field_rule_.share += m * shares[t];
    shares[t] *= closing;
    field_rule_.applied += m * shares[t];
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
      if (field_shares) u.field_share = shares[t];
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
/// their mass at the node: sum_p m_p a_p = -sum_i F_i exactly; and each point's fill pressure,
/// its nodes' interpolated (an isotropic stress: its forces on the nodes sum to zero, so it
/// moves no momentum). Uses the weights of the current substep's P2G (call before G2P moves
/// the points).
template <int D>
void CoupledContinuum<D>::apply_exchange_loads() {
  auto& pts = solver_.points();
  std::fill(pts.body_accel.begin(), pts.body_accel.end(), Vec<D>::Zero());
  std::fill(pts.fill_pressure.begin(), pts.fill_pressure.end(), 0.0);
  if (support_nodes_.empty() && fill_nodes_.empty()) return;
  const Grid<D>& grid = solver_.grid();
  const auto& geometry = static_cast<const coupler::GridGeometry<D>&>(grid);
  for (std::size_t p = 0; p < pts.size(); ++p) {
    Vec<D> a = Vec<D>::Zero();
    double fill = 0;
    coupler::for_each_stencil_node<D>(coupler::QuadraticStencil<D>(grid.to_cell_units(pts.x[p])), geometry,
                                      [&](std::size_t k, double w, const auto&) {
                                        if (grid.mass[k] > 0) a -= (w / grid.mass[k]) * support_[k].force;
                                        fill += w * fill_pressure_[k];
                                      });
    pts.body_accel[p] = a;
    pts.fill_pressure[p] = fill;
  }
}

template <int D>
void CoupledContinuum<D>::balance_support(const Vec<D>& grain_force) {
  // A rezone deletes, makes and rescales grains and points that the support force acts on:
  // what no longer cancels is spread over the points by mass, so that the grains' and the
  // points' support forces still add up to zero (the force stays where it is elsewhere; dropping
  // it at every rezone made the grains rattle).
  auto& pts = solver_.points();
  Vec<D> force = grain_force;
  double mass = 0;
  for (std::size_t p = 0; p < pts.size(); ++p) {
    force += pts.mass[p] * pts.body_accel[p];
    mass += pts.mass[p];
  }
  if (!(mass > 0)) return;
  const Vec<D> correction = -force / mass;
  for (auto& a : pts.body_accel) a += correction;
}

template <int D>
void CoupledContinuum<D>::complete_step() {
  if (pending_dt_ < 0) return;
  apply_exchange_loads();
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
  a.overlap = overlap_;
  a.mpm_dt = pending_dt_ >= 0 ? pending_dt_ : 0.0;
  a.mass = mass;
  a.kinetic_energy = kinetic_energy;
  for (int d = 0; d < D; ++d) a.momentum[d] = momentum[d];
  for (int z = 0; z < 3; ++z) a.zone_cells[z] = zone_cells_[z];
  a.moved_cells = moved_cells_;
  a.points_made = points_made_;
  a.points_removed = points_removed_;
  a.rests_moved = rest_moved_;
  a.rests_kept = rest_kept_;
  a.energy = ledger_.energy;
  a.energy_physics = ledger_.physics;
  a.energy_agreement = ledger_.agreement;
  a.energy_rezone = ledger_.rezone;
  a.energy_fill = solver_.fill_work() - ledger_.fill_start;
  a.before[0] = before_.mass;
  for (int d = 0; d < 3; ++d) a.before[1 + d] = before_.momentum[d], a.before[4 + d] = before_.angular[d];
  if constexpr (D == 2) a.angular[2] = angular[0];
  else
    for (int d = 0; d < 3; ++d) a.angular[d] = angular[d];
  return a;
}

template <int D>
double CoupledContinuum<D>::potential(double mass, const Vec<D>& x) const {
  return -mass * Eigen::Map<const Eigen::Vector3d>(hello_.continuum.gravity).head<D>().dot(x);
}

template <int D>
double CoupledContinuum<D>::grid_energy() const {
  const Grid<D>& grid = solver_.grid();
  double energy = 0;
  const auto [first, last] = solver_.active_nodes();
  for (std::size_t k = first; k < last; ++k) {
    const double m = grid.mass[k];
    if (m <= 0) continue;
    energy += 0.5 * m * grid.momentum[k].squaredNorm() + potential(m, grid.node_position(grid.node_of(k)));
  }
  return energy + elastic_energy();
}

template <int D>
double CoupledContinuum<D>::elastic_energy(std::size_t p) const {
  const auto& pts = solver_.points();
  return pts.volume(p) * solver_.materials()[pts.material[p]].template elastic_energy_density<D>(pts.stress[p]);
}

template <int D>
double CoupledContinuum<D>::elastic_energy() const {
  double energy = 0;
  for (std::size_t p = 0; p < solver_.points().size(); ++p) energy += elastic_energy(p);
  return energy;
}

template <int D>
typename CoupledContinuum<D>::RezoneEnergy::Parts CoupledContinuum<D>::energy_parts(
    const std::vector<std::size_t>& members) const {
  const auto& pts = solver_.points();
  // APIC: a point's affine field C carries kinetic energy 1/2 m (dx^2/4) |C|^2 (the quadratic
  // B-spline's inertia D = dx^2/4 I), which its P2G hands to the grid
  const double dx = solver_.grid().dx, inertia = 0.25 * dx * dx;
  typename RezoneEnergy::Parts parts;
  for (std::size_t p : members) {
    parts.kinetic += 0.5 * pts.mass[p] * (pts.v[p].squaredNorm() + inertia * pts.C[p].squaredNorm());
    parts.potential += potential(pts.mass[p], pts.x[p]);
    parts.elastic += elastic_energy(p);
  }
  return parts;
}

template <int D>
double CoupledContinuum<D>::point_energy() const {
  std::vector<std::size_t> all(solver_.points().size());
  std::iota(all.begin(), all.end(), std::size_t{0});
  return energy_parts(all).total();
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
    state.support_forces.push_back(support_[k].force);
    state.support_masses.push_back(support_[k].reduced_mass);
    state.support_budgets.push_back(support_[k].budget);
    state.support_gaps.push_back(support_[k].gap);
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
  for (std::size_t k : fill_nodes_) fill_pressure_[k] = 0.0;  // the points carry theirs
  fill_nodes_.clear();
  for (std::size_t k : support_nodes_) support_[k] = coupler::SupportNode<D>{};
  support_nodes_.clear();
  for (std::size_t i = 0; i < state.support_nodes.size(); ++i) {
    const std::size_t k = state.support_nodes[i];
    if (k >= support_.size()) throw UserError("the MPM state " + path + " names a node outside the grid");
    support_[k].force = state.support_forces[i];
    support_[k].reduced_mass = state.support_masses[i];
    support_[k].budget = state.support_budgets[i];
    support_[k].gap = state.support_gaps[i];
    support_nodes_.push_back(k);
  }
  time_ = state.time;
  solver_.restore(std::move(state.points), state.solver_time, state.solver_steps);
  pending_dt_ = -1;
  ledger_ = EnergyLedger{};  // the ledger starts again with the continued run
  ledger_.energy = point_energy();
  ledger_.fill_start = solver_.fill_work();
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
