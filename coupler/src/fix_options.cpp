#include "coupler/fix_options.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "coupler/oracle.hpp"
#include "coupler/text.hpp"
#include "coupler/tuning.hpp"

namespace coupler {
namespace {

const char *const kKeywords =
    "cell, continuum, hybrid_width, weight, model, youngs, poisson, friction, mu_s, mu_2, I0, diameter, "
    "grain_density, critical_packing, wall, container, touch, cfl, pic, support, fill, points_per_cell, inertia, output, "
    "mpm_state, every, timeout, idle, adaptive, depth, surface_depth, band, surface_packing, dilute, shear_rate, rest_hold, "
    "discrete, grain_type, "
    "seed, steps_per_contact, material, relax, rezone_log, energy_guard";

[[noreturn]] void illegal(const std::string &why) { throw OptionError(why); }

// LAMMPS's utils::is_double / is_integer (the characters only) and atof / atoi after them
bool is_number(const std::string &s, const char *chars) {
  return !s.empty() && s.find_first_not_of(chars) == std::string::npos;
}

double number(const std::string &key, const std::string &val) {
  if (!is_number(val, "0123456789-+.eE")) illegal("keyword '" + key + "' needs a number, not '" + val + "'");
  return std::atof(val.c_str());
}

double positive(const std::string &key, const std::string &val, const char *what) {
  const double v = number(key, val);
  if (!(v > 0.0)) illegal("keyword '" + key + "' must be > 0 (" + what + "), not " + val);
  return v;
}

int integer(const std::string &key, const std::string &val) {
  if (!is_number(val, "0123456789-+") || std::atoi(val.c_str()) <= 0)
    illegal("keyword '" + key + "' needs a positive integer, not '" + val + "'");
  return std::atoi(val.c_str());
}

// a value in [lo, hi] (closed or open at either end), else the message `range`
double within(const std::string &key, const std::string &val, bool ok(double), const std::string &message) {
  const double v = number(key, val);
  if (!ok(v)) illegal(message + val);
  return v;
}

double pic_option(const std::string &val) {
  if (val == "regime") return kPicRegime;
  return within("pic", val, [](double v) { return v >= 0.0 && v <= 1.0; },
                "keyword 'pic' must be in [0, 1] or 'regime' (each node's share from the flow there), not ");
}

}    // namespace

bool set_oracle_option(OracleSettings &oracle, const std::string &key, const std::string &val) {
  if (key == "rest_hold") {
    if (val != "yes" && val != "no")
      illegal("keyword 'rest_hold' must be 'yes' (cells whose material is at rest keep their zones) or 'no', not '" +
              val + "'");
    oracle.rest_hold = val == "yes" ? 1.0 : 0.0;
    return true;
  }
  double *target = nullptr;
  bool fraction = false;    // a packing fraction in (0, 1); else in (0, inf)
  const char *what = "";
  if (key == "depth") target = &oracle.continuum_depth, what = "continuum deeper than depth + band, m";
  else if (key == "surface_depth")
    target = &oracle.surface_depth, what = "continuum deeper than surface_depth + band below a free surface, m";
  else if (key == "band") target = &oracle.band, what = "half width of the hybrid band, m";
  else if (key == "surface_packing") target = &oracle.surface_packing, fraction = true, what = "a packing fraction";
  else if (key == "dilute") target = &oracle.dilute_packing, fraction = true, what = "a packing fraction";
  else if (key == "shear_rate") target = &oracle.max_shear_rate, what = "cells shearing faster are discrete, 1/s";
  else return false;
  const double v = number(key, val);
  if (!(v > 0.0 && v < (fraction ? 1.0 : 1.0e20)))
    illegal("keyword '" + key + "' (" + what + ") must be in (0, " + (fraction ? "1" : "inf") + "), not " + val);
  *target = v;
  return true;
}

void check_oracle_options(FixOptions &o, int dimension) {
  // without a cell yet (it comes from the grains, resolve_grid) the defaults and checks wait
  if (!o.adaptive() || o.cell <= 0.0) return;
  // Defaults: continuum three cells below surfaces and walls, a hybrid band one cell wide on either side.
  if (o.oracle.band <= 0.0) o.oracle.band = o.cell;
  if (o.oracle.continuum_depth <= 0.0) o.oracle.continuum_depth = 3.0 * o.cell;
  // A continuum cell never borders a discrete one if the band is wider than the distance of
  // neighbouring cell centres (coupler/oracle.hpp, update_zones)
  const double closest = 0.5 * std::sqrt(static_cast<double>(dimension)) * o.cell;
  if (!(o.oracle.band > closest))
    illegal("keyword 'band' (" + shortest(o.oracle.band) + ") must exceed " + general(closest, 4) + " (sqrt(" +
            std::to_string(dimension) + ")/2 cells), or continuum cells may border discrete ones");
  // each depth (surface_depth where set) keeps the cells at the free surface discrete
  const auto exceed_band = [&o](const char *key, double depth) {
    if (!(depth > o.oracle.band))
      illegal(std::string("keyword '") + key + "' (" + shortest(depth) + ") must exceed 'band' (" +
              shortest(o.oracle.band) + "): the cells at the free surface must stay discrete");
  };
  exceed_band("depth", o.oracle.continuum_depth);
  if (o.oracle.surface_depth > 0.0) exceed_band("surface_depth", o.oracle.surface_depth);
}

namespace {

// grains of unit diameter per material point in a cell `cell_in_grains` diameters wide
double grains_per_point(int dimension, double cell_in_grains, double packing, int points_per_axis) {
  return packing * std::pow(cell_in_grains, dimension) /
         (grain_volume(dimension, 0.5) * std::pow(static_cast<double>(points_per_axis), dimension));
}

}    // namespace

std::array<double, 3> touched_walls(const FixOptions &o, const double box_lo[3], const double box_hi[3]) {
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) lo[a] = o.container_edge(a, 0, box_lo, box_hi), hi[a] = o.container_edge(a, 1, box_lo, box_hi);
  return touched_walls(lo, hi, o.continuum.touched_faces);
}

GrainGrid grid_from_grains(int dimension, double grain_diameter, double packing, int points_per_axis) {
  // grains per point grow as cell^dimension: the cell that gives one, scaled up
  const double least = std::pow(kGrainsPerPoint / grains_per_point(dimension, 1.0, packing, points_per_axis),
                                1.0 / dimension);
  const double cell_in_grains = std::max(kSmallestCellInGrains, std::ceil(2.0 * least - 1e-9) / 2.0);
  GrainGrid g;
  g.cell = cell_in_grains * grain_diameter;
  g.smallest_cell = std::max(kSmallestCellInGrains, least) * grain_diameter;
  g.points_per_axis = points_per_axis;
  g.grains_per_point = grains_per_point(dimension, cell_in_grains, packing, points_per_axis);
  return g;
}

double grid_packing(const FixOptions &o, int dimension) {
  if (o.material && o.material->packing_fraction > 0.0) return o.material->packing_fraction;
  return dimension == 2 ? 0.82 : 0.60;
}

std::vector<TouchedSpan> touched_spans(const FixOptions &o, int dimension, const double box_lo[3],
                                       const double box_hi[3]) {
  std::vector<TouchedSpan> spans;
  for (int a = 0; a < dimension; ++a) {
    const std::uint32_t both = face_bit(a, 0) | face_bit(a, 1);
    const double width = o.container_edge(a, 1, box_lo, box_hi) - o.container_edge(a, 0, box_lo, box_hi);
    if ((o.continuum.touched_faces & both) == both && std::isfinite(width) && width > 0) spans.push_back({a, width});
  }
  return spans;
}

namespace {

bool divides(double cell, double width) {
  const double n = width / cell;
  return std::abs(n - std::round(n)) <= 1e-6 * std::max(1.0, n);
}

// A warning for a cell that does not divide a width the continuum touches on both sides: the
// upper face then lies inside a cell (the grid's nodes are laid from the lower face).
std::string misfit_note(double cell, const std::vector<TouchedSpan> &spans) {
  for (const TouchedSpan &s : spans)
    if (!divides(cell, s.width)) {
      const std::string axis(1, "xyz"[s.axis]);
      return "; warning: the container's " + axis + " faces the continuum touches are " + general(s.width / cell, 4) +
             " cells apart, so " + axis + "hi lies inside a cell and the continuum's wall there stands up to a cell "
             "past the grains' wall: give a cell that divides " + general(s.width, 6) + " (e.g. " +
             general(s.width / std::max(1L, std::lround(s.width / cell)), 6) + ") or leave cell out";
    }
  return "";
}

}    // namespace

double cell_dividing(double nominal, const std::vector<TouchedSpan> &spans, double smallest) {
  if (spans.empty()) return nominal;
  const double first = spans.front().width;
  // at most this many cells across the first span: none finer than `smallest` (a relative
  // margin, so that a width of exactly n smallest cells still takes n)
  const long most = smallest > 0.0 ? std::max(1L, static_cast<long>(std::floor(first / smallest * (1.0 + 1e-9))))
                                   : std::numeric_limits<long>::max();
  // the counts whose cell lies within a quarter of the nominal one
  const long fewest = std::max(1L, static_cast<long>(std::ceil(first / (1.25 * nominal))));
  const long last = std::min(most, static_cast<long>(std::floor(first / (0.75 * nominal))));
  // the allowed count whose cell is nearest the nominal one; scanned coarsest first, so the coarser
  // of two as near wins (a width of n + 1/2 nominal cells must not be decided by rounding)
  const auto nearest = [&](auto &&allowed) {
    long best = 0;
    for (long n = fewest; n <= last; ++n)
      if (allowed(n) && (best == 0 || std::abs(first / n - nominal) < std::abs(first / best - nominal) * (1.0 - 1e-12)))
        best = n;
    return best;
  };
  const long all = nearest([&](long n) {
    return std::all_of(spans.begin(), spans.end(), [&](const TouchedSpan &s) { return divides(first / n, s.width); });
  });
  if (all > 0) return first / all;
  const long any = nearest([](long) { return true; });
  return first / (any > 0 ? any : std::clamp(std::lround(first / nominal), 1L, most));
}

std::string resolve_grid(FixOptions &o, int dimension, double grain_diameter, const std::vector<TouchedSpan> &spans) {
  ContinuumSettings &c = o.continuum;
  if (!(grain_diameter > 0.0)) {
    if (o.cell <= 0.0) illegal("keyword 'cell' is needed: the group has no grains to choose the MPM grid cell from");
    check_oracle_options(o, dimension);
    return "cell " + general(o.cell, 6) + misfit_note(o.cell, spans);
  }
  const double packing = grid_packing(o, dimension);
  std::string chosen;
  if (o.cell <= 0.0) {
    const int per_axis = o.points_given ? c.points_per_axis : kPointsPerAxis;
    const GrainGrid g = grid_from_grains(dimension, grain_diameter, packing, per_axis);
    o.cell = cell_dividing(g.cell, spans, g.smallest_cell);
    c.points_per_axis = g.points_per_axis;
    chosen = " (chosen from the grains";
    if (o.cell != g.cell)
      chosen += ", fitted to the " + std::string(1, "xyz"[spans.front().axis]) + " width " +
                general(spans.front().width, 6) + " the continuum touches: " +
                std::to_string(std::lround(spans.front().width / o.cell)) + " cells";
    chosen += ")";
  }
  check_oracle_options(o, dimension);
  const double in_grains = o.cell / grain_diameter;
  return "cell " + general(o.cell, 6) + " = " + general(in_grains, 3) + " mean grain diameters" + chosen + ", " +
         std::to_string(c.points_per_axis) + "^" + std::to_string(dimension) +
         " points per cell: a point made from grains carries " +
         general(grains_per_point(dimension, in_grains, packing, c.points_per_axis), 3) + " grains at packing " +
         general(packing, 3) + misfit_note(o.cell, spans);
}

std::string grid_of_run(FixOptions &o, int dimension, std::int64_t grains, const double box_lo[3],
                        const double box_hi[3], std::string &problem) {
  const double diameter = o.continuum.grain_diameter;
  const std::string line = resolve_grid(o, dimension, grains > 0 || o.diameter_given ? diameter : 0.0,
                                        touched_spans(o, dimension, box_lo, box_hi));
  problem.clear();
  // With cells under 2 grain diameters the oracle's packing fraction per cell counts one or two
  // grains and a cell's rests land on a few points: a published 2D collapse with 1.74 d cells
  // went non-finite as its continuum shrank (issue 14), while the same scene ran with 5 d cells.
  // (2 % slack: a deck's cell of 2 nominal diameters passes whatever its grains' sampled mean)
  if (o.adaptive() && o.cell < 0.98 * kSmallestCellInGrains * diameter)
    problem = "cell " + shortest(o.cell) + " is under " + shortest(kSmallestCellInGrains) +
              " grain diameters (mean diameter " + general(diameter, 4) +
              "): adaptive zones need cells that hold several grains. Use cell " +
              general(kSmallestCellInGrains * diameter, 4) + " or more";
  return line;
}

std::string resolve_exchange_interval(FixOptions &o, double dem_dt) {
  const ContinuumSettings &c = o.continuum;
  const double E = c.youngs_modulus, nu = c.poisson_ratio;
  // P-wave modulus lambda + 2G (plane strain and 3D alike) over the MPM's nominal density;
  // points made from grains are denser and slower, so this bounds their step from below
  const double wave_speed =
      std::sqrt(E * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)) / c.nominal_density());
  const double substep = c.cfl * o.cell / wave_speed;
  const double in_steps = substep / dem_dt;
  o.every = std::max(1, static_cast<int>(std::floor(in_steps * (1.0 + 1e-12))));
  std::string line = "exchange every " + std::to_string(o.every) + " step(s) (every auto: the continuum's stable "
                     "substep cfl dx / c = " + shortest(c.cfl) + " x " + general(o.cell, 4) + " m / " +
                     general(wave_speed, 4) + " m/s = " + general(substep, 4) + " s is " + general(in_steps, 3) +
                     " DEM steps of " + general(dem_dt, 4) + " s)";
  if (o.adaptive() && o.adapt_every % o.every != 0) {
    const int given = o.adapt_every;
    o.adapt_every = (given / o.every + 1) * o.every;
    line += "; zone oracle every " + std::to_string(o.adapt_every) + " steps (keyword 'adaptive' " +
            std::to_string(given) + " rounded up to a multiple of it)";
  }
  return line;
}

RezoneLog rezone_log_option(const std::string &value) {
  const auto level = parse_rezone_log(value);
  if (!level)
    illegal(std::string("keyword 'rezone_log' must be ") + kRezoneLogValues + ", not '" + value + "'");
  return *level;
}

bool modify_option(FixOptions &o, const std::string &key, const std::string &value, int dimension) {
  if (key == "rezone_log") {
    o.rezone_log = rezone_log_option(value);
    return true;
  }
  if (key == "pic") {    // the grain update is the DEM side's alone: it may change between runs
    o.continuum.pic = pic_option(value);
    o.pic_given = true;
    return true;
  }
  if (!set_oracle_option(o.oracle, key, value)) return false;
  check_oracle_options(o, dimension);
  return true;
}

FixOptions parse_fix_options(const std::vector<std::string> &words, int dimension, int ntypes,
                             const std::function<bool(const std::string &)> &region_exists) {
  FixOptions o;
  ContinuumSettings &c = o.continuum;
  std::vector<std::string> constants_given;    // material constants on the fix line (not with 'material')
  bool every_given = false;                    // keyword every (else auto with adaptive zones)
  const std::size_t narg = words.size();
  std::size_t iarg = 0;
  while (iarg < narg) {
    const std::string &key = words[iarg];
    if (iarg + 2 > narg) illegal("keyword '" + key + "' needs a value");
    const std::string &val = words[iarg + 1];
    std::size_t used = 2;
    if (key == "youngs" || key == "poisson" || key == "friction" || key == "mu_s" || key == "mu_2" || key == "I0" ||
        key == "critical_packing")
      constants_given.push_back(key);
    if (key == "cell") o.cell = positive(key, val, "the MPM grid cell size");
    else if (key == "material") {
      try {
        o.material = read_material_file(find_material_file(val));
      } catch (const std::exception &e) {
        illegal(std::string("keyword 'material': ") + e.what());
      }
      if (o.material->dimension != dimension)
        illegal("keyword 'material': " + val + " was calibrated in " + std::to_string(o.material->dimension) +
                "D, this run is " + std::to_string(dimension) + "D");
    } else if (key == "continuum") o.continuum_regions.push_back(val);
    else if (key == "discrete") o.discrete_regions.push_back(val);
    else if (key == "hybrid_width") o.hybrid_width = integer(key, val);
    else if (key == "weight")
      c.grain_weight = within(key, val, [](double v) { return v > 0.0 && v < 1.0; },
                              "keyword 'weight' (the share of a hybrid cell's mass its grains keep) must be between "
                              "0 and 1, not ");
    else if (key == "model") {
      if (val == "drucker_prager") o.model = kModelDruckerPrager;
      else if (val == "mu_i") o.model = kModelMuI;
      else illegal("keyword 'model' must be drucker_prager or mu_i, not '" + val + "'");
    } else if (key == "youngs") c.youngs_modulus = positive(key, val, "Pa");
    else if (key == "poisson")
      c.poisson_ratio = within(key, val, [](double v) { return v > -1.0 && v < 0.5; },
                               "keyword 'poisson' must be in (-1, 0.5), not ");
    else if (key == "friction")
      c.friction_angle_deg = within(key, val, [](double v) { return v >= 0.0 && v < 90.0; },
                                    "keyword 'friction' (friction angle, degrees) must be in [0, 90), not ");
    else if (key == "mu_s") c.mu_s = positive(key, val, "static friction of mu(I)");
    else if (key == "mu_2") c.mu_2 = positive(key, val, "limit friction of mu(I)");
    else if (key == "I0") c.I0 = positive(key, val, "inertial number scale of mu(I)");
    else if (key == "diameter") c.grain_diameter = positive(key, val, "grain diameter, m"), o.diameter_given = true;
    else if (key == "grain_density") c.grain_density = positive(key, val, "kg/m^3"), o.density_given = true;
    else if (key == "critical_packing")
      c.critical_packing = within(key, val, [](double v) { return v > 0.0 && v < 1.0; },
                                  "keyword 'critical_packing' must be in (0, 1), not ");
    else if (key == "wall") {
      if (val == "sticky") c.wall_contact = kWallSticky;
      else if (val == "slip") c.wall_contact = kWallSlip;
      else if (val == "friction") {
        if (iarg + 3 > narg) illegal("keyword 'wall friction' needs the friction coefficient");
        c.wall_contact = kWallFriction;
        c.wall_friction = number("wall friction", words[iarg + 2]);
        if (c.wall_friction < 0.0) illegal("keyword 'wall friction' needs a coefficient >= 0");
        used = 3;
      } else illegal("keyword 'wall' must be sticky, slip or friction MU, not '" + val + "'");
    } else if (key == "container") {
      // xlo xhi ylo yhi (zlo zhi): walls of the continuum; INF = the box face
      const std::size_t nval = 2 * dimension;
      if (iarg + 1 + nval > narg)
        illegal("keyword 'container' needs " + std::to_string(nval) + " values (xlo xhi ylo yhi" +
                (dimension == 3 ? " zlo zhi" : "") + "; INF = the box face)");
      for (std::size_t k = 0; k < nval; k++) {
        const std::string &v = words[iarg + 1 + k];
        o.container_given[k] = v != "INF" && v != "EDGE";
        if (o.container_given[k]) o.container_value[k] = number("container", v);
      }
      used = 1 + nval;
    } else if (key == "touch") {
      // a container face the continuum may reach (its wall law stands for the DEM wall)
      const int nfaces = 2 * dimension;
      const int f = static_cast<int>(std::find(kFaceNames, kFaceNames + 6, val) - kFaceNames);
      if (val == "all")
        for (int k = 0; k < nfaces; k++) c.touched_faces |= face_bit(k / 2, k % 2);
      else if (f < nfaces) c.touched_faces |= face_bit(f / 2, f % 2);
      else if (f < 6) illegal("keyword 'touch' face '" + val + "' needs a 3D box (a 2D box has no z faces)");
      else
        illegal(std::string("keyword 'touch' needs a container face (xlo, xhi, ylo, yhi") +
                (nfaces == 6 ? ", zlo, zhi" : "") + " or all), not '" + val + "'");
    } else if (key == "cfl")
      c.cfl = within(key, val, [](double v) { return v > 0.0 && v <= 1.0; }, "keyword 'cfl' must be in (0, 1], not ");
    else if (key == "pic") {
      o.pic_given = true;
      c.pic = pic_option(val);
    } else if (key == "support")
      c.support_gain = within(key, val, [](double v) { return v >= 0.0 && v <= 1.0; },
                              "keyword 'support' (gain of the support force between exchanges) must be in [0, 1], "
                              "not ");
    else if (key == "energy_guard")
      o.energy_guard = within(key, val, [](double v) { return v >= 0.0; },
                              "keyword 'energy_guard' (the energy the coupling may make, as a share of the scene's "
                              "energy scale; 0 = unguarded) must be >= 0, not ");
    else if (key == "fill") {
      o.fill_auto = val == "auto";
      c.fill_share = o.fill_auto ? 0.0
                                 : within(key, val, [](double v) { return v >= 0.0 && v <= 1.0; },
                                          "keyword 'fill' (auto: the fill pressure's modulus from the calibration, "
                                          "or a share of the continuum's bulk modulus; 0 = none) must be auto or in "
                                          "[0, 1], not ");
    }
    else if (key == "points_per_cell") {
      c.points_per_axis = integer(key, val);
      o.points_given = true;
      if (c.points_per_axis > 4) illegal("keyword 'points_per_cell' (points per cell and axis) must be 1 to 4");
    } else if (key == "inertia") o.inertia = positive(key, val, "I = inertia m r^2");
    else if (key == "output") {
      if (iarg + 3 > narg) illegal("keyword 'output' needs a file name and an interval in exchanges");
      o.output_path = val;
      c.output_every = integer("output", words[iarg + 2]);
      if (o.output_path.size() >= sizeof(c.output_path))
        illegal("keyword 'output': the file name is longer than " + std::to_string(sizeof(c.output_path) - 1) +
                " characters");
      set_text(c.output_path, o.output_path);
      used = 3;
    } else if (key == "adaptive") o.adapt_every = integer(key, val);
    else if (set_oracle_option(o.oracle, key, val)) {
    } else if (key == "grain_type") o.grain_type = integer(key, val);
    else if (key == "seed") o.template_seed = integer(key, val);
    else if (key == "relax")
      o.relax_time = within(key, val, [](double v) { return v >= 0.0; },
                            "keyword 'relax' (relaxation time of the velocity agreement, s; 0 = close the gap at "
                            "every exchange) must be >= 0, not ");
    else if (key == "steps_per_contact")
      o.warn_steps_per_contact = within(key, val, [](double v) { return v > kUnstableStepsPerContact; },
                                        "keyword 'steps_per_contact' (warn below this many DEM steps per contact) "
                                        "must exceed pi/2, where velocity Verlet goes unstable, not ");
    else if (key == "rezone_log") o.rezone_log = rezone_log_option(val);
    else if (key == "mpm_state") o.mpm_state_path = val;
    else if (key == "every") {
      o.every_auto = val == "auto";
      o.every = o.every_auto ? 1 : integer(key, val);
      every_given = true;
    }
    else if (key == "timeout") o.reply_timeout = positive(key, val, "seconds");
    else if (key == "idle")
      o.idle_timeout = within(key, val, [](double v) { return !(v < 0.0); },
                              "keyword 'idle' must be >= 0 seconds (0 = wait forever), not ");
    else
      illegal("unknown keyword '" + key + "' (known keywords: " + kKeywords + ")");
    iarg += used;
  }
  if (o.fill_auto && !o.material)
    illegal("keyword 'fill auto' needs 'material': the fill pressure's modulus comes from the calibration's packing "
            "and pressure (or give a share of the bulk modulus, fill S)");
  if (o.material && !constants_given.empty())
    illegal("keyword '" + constants_given.front() + "' conflicts with 'material', which sets the continuum's "
            "constants from the calibration; leave one out");
  for (const auto &[kind, ids] : {std::make_pair("continuum", &o.continuum_regions),
                                  std::make_pair("discrete", &o.discrete_regions)})
    for (const auto &rid : *ids)
      if (!region_exists(rid))
        illegal(std::string(kind) + " region '" + rid + "' does not exist (define it with the region command first)");
  if (!o.discrete_regions.empty() && !o.adaptive())
    illegal("keyword 'discrete' needs adaptive zones (keyword 'adaptive'): with fixed zones, leave the region "
            "out of the continuum regions instead");
  if (c.touched_faces != 0 && !o.adaptive())
    illegal("keyword 'touch' needs adaptive zones (keyword 'adaptive'): with fixed zones, the continuum regions "
            "decide where the continuum is");
  if (o.inertia < 0.0) o.inertia = dimension == 2 ? 0.5 : 0.4;
  // Moving zones exchange once per continuum substep unless told otherwise: the MPM process never
  // steps past an exchange, so a shorter interval only splits its stable substep into several
  // (the 80k-disk silo every 10: four substeps where one would do, 8.2x faster than LAMMPS
  // instead of 10.1x), and the 50 d collapse and the silos keep their accuracy at it
  // (bench/results/adaptive_accuracy.md; a band in a fast surface flow wants a shorter
  // interval, docs/design.md sections 5.2 and 7.3).
  if (o.adaptive() && !every_given) o.every_auto = true;
  if (o.adaptive() && !o.every_auto && o.adapt_every % o.every != 0)
    illegal("keyword 'adaptive' (" + std::to_string(o.adapt_every) + " steps) must be a multiple of 'every' (" +
            std::to_string(o.every) + "): zones change right after an exchange");
  check_oracle_options(o, dimension);
  // With moving zones the hybrid band lies inside the flow: taking the agreed field there
  // (pic 1) erases the grains' fluctuations at every exchange and damps the flow (a column
  // collapse ran out 35 % short), while the impulse rule (pic 0) leaves the hybrid grains of a
  // settling deposit wandering (1.7-2.2x the DEM's steps to rest). Each node's rule from the
  // flow regime there does both (docs/design.md section 5.3).
  if (o.adaptive() && !o.pic_given) c.pic = kPicRegime;
  // The fill pressure stiffens the points it acts on by up to fill x K < fill x M (M the P-wave
  // modulus the stable step is set by): their wave speed grows by under sqrt(1 + fill).
  if (c.cfl * std::sqrt(1.0 + c.fill_share) > 1.0)
    illegal("keywords 'cfl' " + shortest(c.cfl) + " and 'fill' " + shortest(c.fill_share) +
            ": the fill pressure raises the continuum's wave speed by up to sqrt(1 + fill), so cfl must be at most " +
            shortest(1.0 / std::sqrt(1.0 + c.fill_share)) + " with it; lower cfl or fill");
  // The fill a node of points and grains may hold (the fill pressure's reference): the packing the
  // grid's cell is chosen for.
  c.packing_fraction = grid_packing(o, dimension);
  if (o.grain_type > ntypes)
    illegal("keyword 'grain_type' " + std::to_string(o.grain_type) + " is not an atom type (1 to " +
            std::to_string(ntypes) + ")");
  return o;
}

}    // namespace coupler
