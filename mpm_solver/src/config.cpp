// Scene config files (TOML) -> Scene, with validation, and the key reference
// printed by `mpm_solver --help`.
//
// One table of key descriptors (kKeys) is the single source of truth: the
// unknown-key check, the "this key belongs to another model/shape" check and
// config_reference() are all driven by it, and every read of a key asserts
// that the key is declared there.
#include "mpm/config.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "mpm/types.hpp"

namespace mpm {
namespace {

// ------------------------------------------------------------- descriptors --

enum class Kind { Number, Integer, String, Bool, Vector, Table, TableArray };

struct KeyDesc {
  const char* table;       ///< "" for the top level, else the table name
  const char* key;
  Kind kind;
  const char* unit;        ///< "" when dimensionless or not a number
  const char* deflt;       ///< default value, or "required ..."
  const char* allowed;     ///< allowed values; "" when any value of the type
  const char* when_key;    ///< the key is only allowed when when_key == when_value
  const char* when_value;
  bool only_3d;            ///< the key is only allowed when dimension = 3
  const char* help;
};

struct TableDesc {
  const char* name;
  const char* title;
  const char* help;
};

constexpr const char* kNone = nullptr;

// clang-format off
const TableDesc kTables[] = {
  {"", "Top level",
   "These keys must come before the first [table] header: TOML puts every key "
   "that follows a header into that table."},
  {"grid", "[grid]  (required)",
   "The background grid: a box domain of square (2D) or cubic (3D) cells. All "
   "material must start, and stay, inside the domain."},
  {"time", "[time]",
   "Time stepping. The step is explicit: dt = cfl * cell_size / (c + |v|max), "
   "c = sqrt((lambda + 2G) / density) the elastic wave speed of the stiffest material. "
   "A step shorter than that at cfl 0.5 (a lower cfl, or a fixed dt) keeps a share "
   "1 - dt/dt(0.5) of each point's velocity beyond the grid's field, so that the "
   "transfers dissipate as much per unit time as at cfl 0.5, not more (docs/design.md 4.2)."},
  {"output", "[output]",
   "Snapshots go to <directory>/points.h5 (HDF5) with <directory>/points.xdmf "
   "for ParaView/VisIt. Per snapshot: position, velocity, mass, volume, stress, "
   "plastic_strain, material (index into the [[material]] list)."},
  {"material", "[[material]]  (one or more)",
   "A granular material. Each [[material]] header starts a new one. Keys of the "
   "model not selected are errors."},
  {"block", "[[block]]  (one or more)",
   "A region filled with material points on a regular lattice, at rest unless "
   "velocity is given. Each [[block]] header starts a new one; it must lie inside "
   "the grid domain."},
  {"boundary", "[[boundary]]  (any number)",
   "A rigid boundary acting on the grid velocities, in addition to the grid walls. "
   "It may move with a prescribed constant velocity."},
  {"outlet", "[[outlet]]  (any number)",
   "A sink: an axis-aligned box inside the grid domain; material points that enter it leave "
   "the run at the end of that step. Their mass and number, summed over the outlets, go to "
   "<output directory>/outflow.dat every [output] outflow_interval (columns: time s, mass out, "
   "points out; mass per unit depth in 2D) and to the --summary figures. A silo's orifice: "
   "a floor with a gap (two obstacle boxes) and an outlet below it."},
};

const KeyDesc kKeys[] = {
  // top level
  {"", "dimension", Kind::Integer, "", "2", "2 or 3", kNone, kNone, false,
   "Spatial dimension. Arrays marked [d] then hold this many numbers. In 2D "
   "everything is per unit depth (mass in kg/m, force in N/m, ...)."},
  {"", "gravity", Kind::Vector, "m/s^2", "-9.81 along the last axis: [0, -9.81] in 2D, [0, 0, -9.81] in 3D", "", kNone, kNone, false,
   "Body acceleration. Tilt it to model an inclined slope."},
  {"", "end_time", Kind::Number, "s", "1.0", "> 0", kNone, kNone, false,
   "Simulated time at which the run stops. May instead be given as [time] end_time, not both."},
  {"", "grid", Kind::Table, "", "required", "", kNone, kNone, false, "The background grid, see [grid]."},
  {"", "time", Kind::Table, "", "optional", "", kNone, kNone, false, "Time stepping, see [time]."},
  {"", "output", Kind::Table, "", "optional", "", kNone, kNone, false, "Output, see [output]."},
  {"", "material", Kind::TableArray, "", "required, at least one", "", kNone, kNone, false, "Materials, see [[material]]."},
  {"", "block", Kind::TableArray, "", "required, at least one", "", kNone, kNone, false, "Material blocks, see [[block]]."},
  {"", "boundary", Kind::TableArray, "", "none", "", kNone, kNone, false, "Rigid boundaries, see [[boundary]]."},
  {"", "outlet", Kind::TableArray, "", "none", "", kNone, kNone, false, "Sinks for material, see [[outlet]]."},

  // [grid]
  {"grid", "cell_size", Kind::Number, "m", "required", "> 0", kNone, kNone, false,
   "Edge length dx of the grid cells. Sets the resolution and, through the CFL "
   "condition, the time step."},
  {"grid", "lower", Kind::Vector, "m", "required", "", kNone, kNone, false,
   "Lower corner of the domain."},
  {"grid", "upper", Kind::Vector, "m", "required", "> lower in every component", kNone, kNone, false,
   "Upper corner of the domain."},
  {"grid", "walls", Kind::String, "", "\"slip\"", "\"slip\", \"sticky\", \"friction\"", kNone, kNone, false,
   "What the domain faces do to material reaching them, like the walls of a "
   "closed box: slip = no penetration, free sliding; sticky = material at the "
   "wall stops; friction = Coulomb friction with coefficient wall_friction."},
  {"grid", "wall_friction", Kind::Number, "", "required when walls = \"friction\"", ">= 0", "walls", "friction", false,
   "Coulomb friction coefficient of the domain faces."},

  // [time]
  {"time", "end_time", Kind::Number, "s", "1.0", "> 0", kNone, kNone, false,
   "Same as the top-level end_time (preferred there); give one, not both."},
  {"time", "cfl", Kind::Number, "", "0.5", "0 < cfl <= 1", kNone, kNone, false,
   "Courant number of the automatic step dt = cfl * cell_size / (c + |v|max)."},
  {"time", "dt", Kind::Number, "s", "0 (automatic)", ">= 0", kNone, kNone, false,
   "Fixed time step; 0 chooses the stable step automatically every step. A fixed "
   "step above the stable one is refused, and the error gives the safe value."},
  {"time", "damping", Kind::Number, "1/s", "0", ">= 0", kNone, kNone, false,
   "Viscous damping rate of the grid velocities (v *= 1 - damping*dt every step). "
   "Only for settling to a quasi-static state; keep 0 for dynamics."},

  // [output]
  {"output", "directory", Kind::String, "", "\"mpm_output\"", "", kNone, kNone, false,
   "Directory for points.h5 and points.xdmf, created if missing. Relative to the "
   "working directory. The command-line option --output overrides it."},
  {"output", "interval", Kind::Number, "s", "0 (first and last state only)", ">= 0", kNone, kNone, false,
   "Simulated time between snapshots."},
  {"output", "grid_fields", Kind::Bool, "", "false", "", kNone, kNone, false,
   "Also write the grid mass and velocity with every snapshot."},
  {"output", "progress_interval", Kind::Number, "s (wall clock)", "5", ">= 0", kNone, kNone, false,
   "Wall-clock seconds between progress lines on standard output; 0 = none."},
  {"output", "outflow_interval", Kind::Number, "s", "0.005", "> 0", kNone, kNone, false,
   "Simulated time between lines of outflow.dat (only with an [[outlet]])."},

  // [[material]]
  {"material", "name", Kind::String, "", "required", "unique among the materials", kNone, kNone, false,
   "Name the blocks use to refer to the material."},
  {"material", "model", Kind::String, "", "\"drucker_prager\"", "\"drucker_prager\", \"mu_i\"", kNone, kNone, false,
   "Constitutive model: hyperelastic Drucker-Prager with Hencky strain (Klar et al. "
   "2016) or hypoelastic mu(I) rheology (Dunatunga & Kamrin 2015)."},
  {"material", "density", Kind::Number, "kg/m^3", "1600 for drucker_prager; critical_density for mu_i", "> 0", kNone, kNone, false,
   "Initial bulk density of the continuum (grains and pores together); sets the point masses."},
  {"material", "youngs_modulus", Kind::Number, "Pa", "1e7", "> 0", kNone, kNone, false,
   "Young's modulus E of the continuum (not of the grain solid). A softer "
   "continuum allows larger steps; keep the elastic strain density*|g|*height/E small."},
  {"material", "poisson_ratio", Kind::Number, "", "0.3", "0 <= poisson_ratio < 0.5", kNone, kNone, false,
   "Poisson's ratio nu of the continuum."},
  {"material", "friction_angle", Kind::Number, "degrees", "30", "0 < friction_angle < 90", "model", "drucker_prager", false,
   "Internal friction angle phi; sets the opening of the Drucker-Prager cone."},
  {"material", "mu_s", Kind::Number, "", "0.382", "> 0", "model", "mu_i", false,
   "Static friction coefficient of mu(I) (glass beads: 0.382)."},
  {"material", "mu_2", Kind::Number, "", "0.644", "> mu_s", "model", "mu_i", false,
   "Limiting friction coefficient of mu(I) at large inertial number (glass beads: 0.644)."},
  {"material", "I0", Kind::Number, "", "0.279", "> 0", "model", "mu_i", false,
   "Reference inertial number of mu(I) (glass beads: 0.279)."},
  {"material", "grain_diameter", Kind::Number, "m", "1e-3", "> 0", "model", "mu_i", false,
   "Grain diameter d in the inertial number I = gammadot_p * d / sqrt(p / grain_density)."},
  {"material", "grain_density", Kind::Number, "kg/m^3", "2450", "> 0", "model", "mu_i", false,
   "Density rho_s of the grain solid."},
  {"material", "critical_density", Kind::Number, "kg/m^3", "0.6 * grain_density", "0 < critical_density < grain_density", "model", "mu_i", false,
   "Bulk density below which the material is disconnected and carries no stress."},

  // [[block]]
  {"block", "material", Kind::String, "", "required", "the name of a [[material]]", kNone, kNone, false,
   "Material of the points."},
  {"block", "shape", Kind::String, "", "\"box\"", "\"box\", \"cylinder\"", kNone, kNone, false,
   "Region filled with points. In 2D a cylinder is a disk."},
  {"block", "lower", Kind::Vector, "m", "required for a box", "", "shape", "box", false,
   "Lower corner of the box."},
  {"block", "upper", Kind::Vector, "m", "required for a box", "> lower in every component", "shape", "box", false,
   "Upper corner of the box."},
  {"block", "center", Kind::Vector, "m", "required for a cylinder", "", "shape", "cylinder", false,
   "Centre of the disk (2D) or of the cylinder (3D, midway along its axis)."},
  {"block", "radius", Kind::Number, "m", "required for a cylinder", "> 0", "shape", "cylinder", false,
   "Radius of the disk or cylinder."},
  {"block", "axis", Kind::String, "", "\"z\"", "\"x\", \"y\", \"z\"", "shape", "cylinder", true,
   "Direction of the cylinder axis (3D only)."},
  {"block", "height", Kind::Number, "m", "required for a 3D cylinder", "> 0", "shape", "cylinder", true,
   "Length of the cylinder along its axis, centred on center (3D only)."},
  {"block", "points_per_cell", Kind::Integer, "", "0 = 2 per axis (4 in 2D, 8 in 3D)",
   "0 or n^dimension for an integer n >= 1: 1, 4, 9, 16, ... in 2D; 1, 8, 27, ... in 3D", kNone, kNone, false,
   "Material points per grid cell, on a regular lattice of n per axis."},
  {"block", "velocity", Kind::Vector, "m/s", "zero", "", kNone, kNone, false,
   "Initial velocity of all points of the block."},
  {"block", "geostatic", Kind::Bool, "", "false", "", kNone, kNone, false,
   "Start from the lithostatic stress instead of zero stress: vertical (last "
   "axis) compressive stress = density * |g_vertical| * depth below the block's "
   "top, horizontal stress = k0 times that. Avoids the initial elastic bounce of "
   "a block at rest."},
  {"block", "k0", Kind::Number, "", "0.5", "0 <= k0 <= 1", "geostatic", "true", false,
   "Lateral stress ratio of the geostatic state (Jaky's estimate: 1 - sin(friction_angle))."},

  // [[boundary]]
  {"boundary", "type", Kind::String, "", "\"plane\"", "\"plane\", \"box\"", kNone, kNone, false,
   "A plane (an infinite wall; a line in 2D) or an axis-aligned box (a container or an obstacle)."},
  {"boundary", "contact", Kind::String, "", "\"slip\"", "\"sticky\", \"slip\", \"friction\"", kNone, kNone, false,
   "Condition on grid velocities moving into the boundary: sticky = no relative "
   "motion; slip = no penetration, free sliding; friction = no penetration, "
   "Coulomb friction with coefficient friction."},
  {"boundary", "friction", Kind::Number, "", "required when contact = \"friction\"", ">= 0", "contact", "friction", false,
   "Coulomb friction coefficient."},
  {"boundary", "separating", Kind::Bool, "", "true", "", kNone, kNone, false,
   "true: material may move away from the boundary (lift-off); false: the "
   "boundary also holds material that moves away from it."},
  {"boundary", "point", Kind::Vector, "m", "required for a plane", "", "type", "plane", false,
   "A point on the plane at time 0."},
  {"boundary", "normal", Kind::Vector, "", "required for a plane", "non-zero; normalised on input", "type", "plane", false,
   "Normal of the plane, pointing into the side where material is allowed."},
  {"boundary", "lower", Kind::Vector, "m", "required for a box", "", "type", "box", false,
   "Lower corner of the box at time 0."},
  {"boundary", "upper", Kind::Vector, "m", "required for a box", "> lower in every component", "type", "box", false,
   "Upper corner of the box at time 0."},
  {"boundary", "inside", Kind::Bool, "", "false", "", "type", "box", false,
   "true: material is kept inside the box (a container); false: kept outside (a rigid obstacle)."},
  {"boundary", "velocity", Kind::Vector, "m/s", "zero", "", kNone, kNone, false,
   "Prescribed constant velocity of the boundary (moving plate, pusher, intruder); "
   "point, lower and upper give its position at time 0."},

  // [[outlet]]
  {"outlet", "lower", Kind::Vector, "m", "required", "", kNone, kNone, false,
   "Lower corner of the outlet box; it must overlap the grid domain."},
  {"outlet", "upper", Kind::Vector, "m", "required", "> lower in every component", kNone, kNone, false,
   "Upper corner of the outlet box."},
};
// clang-format on

const KeyDesc* find_key(std::string_view table, std::string_view key) {
  for (const KeyDesc& d : kKeys)
    if (table == d.table && key == d.key) return &d;
  return nullptr;
}

std::string table_display(std::string_view table) {
  if (table.empty()) return "the top level";
  for (const KeyDesc& d : kKeys)
    if (d.table[0] == '\0' && table == d.key)
      return d.kind == Kind::TableArray ? "[[" + std::string(table) + "]]" : "[" + std::string(table) + "]";
  return std::string(table);
}

// ----------------------------------------------------------------- helpers --

std::string lower_case(std::string_view s) {
  std::string r(s);
  for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

/// Optimal string alignment distance (Levenshtein plus adjacent transpositions).
std::size_t edit_distance(std::string_view a0, std::string_view b0) {
  const std::string a = lower_case(a0), b = lower_case(b0);
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i)
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[n][m];
}

/// The candidate closest to `word` if within edit distance 2, else "".
std::string closest(std::string_view word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = 3;
  for (const std::string& c : candidates) {
    const std::size_t dist = edit_distance(word, c);
    if (dist < best_d && dist < std::min(c.size(), word.size())) {
      best_d = dist;
      best = c;
    }
  }
  return best;
}

std::string quoted_list(const std::vector<std::string>& items) {
  std::string r;
  for (std::size_t i = 0; i < items.size(); ++i) r += (i ? ", \"" : "\"") + items[i] + "\"";
  return r;
}

std::string plain_list(const std::vector<std::string>& items) {
  std::string r;
  for (std::size_t i = 0; i < items.size(); ++i) r += (i ? ", " : "") + items[i];
  return r;
}

std::string fmt(double v) {
  std::ostringstream os;
  os << std::setprecision(10) << v;
  return os.str();
}

std::string fmt_vec(const Vec3& v, int dim) {
  std::string r = "[";
  for (int a = 0; a < dim; ++a) r += (a ? ", " : "") + fmt(v[a]);
  return r + "]";
}

/// A short description of a node for "got ..." in messages.
std::string describe(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::string: return "string \"" + std::string(n.as_string()->get()) + "\"";
    case toml::node_type::integer: return "integer " + std::to_string(n.as_integer()->get());
    case toml::node_type::floating_point: return "number " + fmt(n.as_floating_point()->get());
    case toml::node_type::boolean: return std::string("boolean ") + (n.as_boolean()->get() ? "true" : "false");
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    case toml::node_type::date: return "a date";
    case toml::node_type::time: return "a time";
    case toml::node_type::date_time: return "a date-time";
    default: return "an empty value";
  }
}

std::string prefix(const std::string& source, const toml::source_region* where) {
  if (where && where->begin.line > 0) return source + ":" + std::to_string(where->begin.line) + ": ";
  return source + ": ";
}

// ------------------------------------------------------------ table reader --

/// One TOML table of the scene with its descriptor table name and a label for
/// messages ("[grid]", "[[material]] #2 (name \"sand\")", "" for the top level).
class Tbl {
 public:
  Tbl(const std::string& source, int dim, const toml::table& t, const char* id, std::string label,
      const toml::source_region* where)
      : source_(source), dim_(dim), t_(t), id_(id), label_(std::move(label)), where_(where) {}

  void set_label(std::string label) { label_ = std::move(label); }
  void set_dim(int dim) { dim_ = dim; }
  const std::string& label() const { return label_; }

  /// "[grid] cell_size", or "dimension" at the top level.
  std::string path(std::string_view key) const {
    return label_.empty() ? std::string(key) : label_ + " " + std::string(key);
  }

  [[noreturn]] void fail(const toml::source_region* where, const std::string& msg) const {
    throw UserError(prefix(source_, where) + msg);
  }
  /// An error about the value of `key`, at its line (or the table's when absent).
  [[noreturn]] void fail_key(std::string_view key, const std::string& msg) const {
    const toml::node* n = t_.get(key);
    fail(n ? &n->source() : where_, path(key) + ": " + msg);
  }
  /// An error about the whole table.
  [[noreturn]] void fail_table(const std::string& msg) const {
    fail(where_, label_.empty() ? msg : label_ + ": " + msg);
  }
  [[noreturn]] void missing(std::string_view key, const std::string& why = "") const {
    const KeyDesc* d = desc(key);
    fail(where_, path(key) + ": required key missing" + why + ". " + d->help);
  }

  const KeyDesc* desc(std::string_view key) const {
    const KeyDesc* d = find_key(id_, key);
    if (!d) throw std::logic_error("config.cpp: key \"" + std::string(key) + "\" of table \"" + id_ + "\" has no descriptor");
    return d;
  }
  const toml::node* node(std::string_view key) const {
    desc(key);
    return t_.get(key);
  }
  bool has(std::string_view key) const { return node(key) != nullptr; }

  std::optional<double> opt_number(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    double v;
    if (auto* i = n->as_integer()) v = static_cast<double>(i->get());
    else if (auto* f = n->as_floating_point()) v = f->get();
    else fail_key(key, "must be a number, got " + describe(*n));
    if (!std::isfinite(v)) fail_key(key, "must be a finite number, got " + fmt(v));
    return v;
  }
  double number(std::string_view key, double def) const { return opt_number(key).value_or(def); }
  double req_number(std::string_view key) const {
    if (auto v = opt_number(key)) return *v;
    missing(key);
  }

  std::optional<std::int64_t> opt_integer(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    if (auto* i = n->as_integer()) return i->get();
    fail_key(key, "must be an integer, got " + describe(*n));
  }

  std::optional<std::string> opt_string(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    if (auto* s = n->as_string()) return s->get();
    fail_key(key, "must be a string (in quotes), got " + describe(*n));
  }

  std::optional<bool> opt_bool(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    if (auto* b = n->as_boolean()) return b->get();
    fail_key(key, "must be true or false, got " + describe(*n));
  }

  /// An array of `dimension` numbers; the unused third component is 0.
  std::optional<Vec3> opt_vector(std::string_view key) const {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    const std::string want = "an array of " + std::to_string(dim_) + " numbers (dimension = " + std::to_string(dim_) + ")";
    const toml::array* a = n->as_array();
    if (!a) fail_key(key, "must be " + want + ", got " + describe(*n));
    if (static_cast<int>(a->size()) != dim_)
      fail_key(key, "must be " + want + ", got " + std::to_string(a->size()) + (a->size() == 1 ? " element" : " elements"));
    Vec3 v{0, 0, 0};
    for (int i = 0; i < dim_; ++i) {
      const toml::node& e = *a->get(static_cast<std::size_t>(i));
      if (auto* x = e.as_integer()) v[i] = static_cast<double>(x->get());
      else if (auto* f = e.as_floating_point()) v[i] = f->get();
      else fail_key(key, "element " + std::to_string(i + 1) + " must be a number, got " + describe(e));
      if (!std::isfinite(v[i])) fail_key(key, "element " + std::to_string(i + 1) + " must be finite, got " + fmt(v[i]));
    }
    return v;
  }
  Vec3 req_vector(std::string_view key, const std::string& why = "") const {
    if (auto v = opt_vector(key)) return *v;
    missing(key, why);
  }

  /// A string from a fixed set; returns its index in `options`.
  int choice(std::string_view key, const std::vector<std::string>& options, int def) const {
    auto s = opt_string(key);
    if (!s) return def;
    for (std::size_t i = 0; i < options.size(); ++i)
      if (*s == options[i]) return static_cast<int>(i);
    std::string msg = "unknown value \"" + *s + "\"";
    const std::string near = closest(*s, options);
    if (!near.empty()) msg += " (did you mean \"" + near + "\"?)";
    fail_key(key, msg + "; allowed values are: " + quoted_list(options));
  }

  /// Requires `ok`, else "<path>: must be <what>, got <value>".
  void check(bool ok, std::string_view key, const std::string& what, double got) const {
    if (!ok) fail_key(key, "must be " + what + ", got " + fmt(got));
  }

  /// Unknown keys (with a "did you mean"), then keys that belong to another
  /// model / shape / type than the one selected (selectors: key -> value), or
  /// to 3D only.
  void check_keys(const std::map<std::string, std::string>& selectors = {}) const {
    std::vector<std::pair<const toml::key*, const toml::node*>> entries;
    for (const auto& [k, v] : t_) entries.emplace_back(&k, &v);
    std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
      const auto &sa = a.first->source().begin, &sb = b.first->source().begin;
      return sa.line != sb.line ? sa.line < sb.line : sa.column < sb.column;
    });
    for (const auto& [k, v] : entries)
      if (!find_key(id_, k->str())) unknown_key(*k);
    for (const auto& [k, v] : entries) {
      const KeyDesc* d = find_key(id_, k->str());
      const std::string where = (label_.empty() ? std::string("top-level") : label_) + " key \"" + std::string(k->str()) + "\"";
      if (d->when_key) {
        auto it = selectors.find(d->when_key);
        if (it == selectors.end()) throw std::logic_error("config.cpp: selector missing for " + std::string(d->when_key));
        if (it->second != d->when_value) {
          std::vector<std::string> own;
          for (const KeyDesc& o : kKeys)
            if (id_ == o.table && o.when_key && std::string_view(o.when_key) == d->when_key && it->second == o.when_value)
              own.push_back(o.key);
          std::string msg = where + ": belongs to " + d->when_key + " = \"" + d->when_value + "\", but here " +
                            d->when_key + " = \"" + it->second + "\"";
          if (!own.empty()) msg += "; the keys for " + std::string(d->when_key) + " = \"" + it->second + "\" are: " + plain_list(own);
          fail(&k->source(), msg);
        }
      }
      if (d->only_3d && dim_ != 3)
        fail(&k->source(), where + ": only applies in 3D (dimension = 3); this scene has dimension = " + std::to_string(dim_));
    }
  }

 private:
  [[noreturn]] void unknown_key(const toml::key& k) const {
    const std::string key(k.str());
    std::vector<std::string> allowed;
    for (const KeyDesc& d : kKeys)
      if (id_ == d.table) allowed.push_back(d.key);
    std::string msg = (label_.empty() ? std::string("top-level") : label_) + " key \"" + key + "\": unknown key";
    const std::string near = closest(key, allowed);
    if (!near.empty()) msg += " (did you mean \"" + near + "\"?)";
    // A known key in the wrong table: the classic TOML slip is a top-level key
    // written after a [table] header, which puts it into that table.
    std::vector<std::string> homes;
    for (const KeyDesc& d : kKeys)
      if (key == d.key && id_ != d.table) homes.push_back(table_display(d.table));
    if (!homes.empty()) {
      if (homes.front() == "the top level")
        msg += "; \"" + key + "\" is a top-level key: move it above the first [table] header (TOML puts every key "
               "after a [table] header into that table)";
      else
        msg += "; \"" + key + "\" is a key of " + plain_list(homes);
    }
    msg += "; allowed keys " + (label_.empty() ? std::string("at the top level") : "in " + table_display(id_)) +
           " are: " + plain_list(allowed);
    fail(&k.source(), msg);
  }

  const std::string& source_;
  int dim_;
  const toml::table& t_;
  std::string id_;
  std::string label_;
  const toml::source_region* where_;
};

/// The tables of an array of tables `[[name]]` (empty if absent).
std::vector<const toml::table*> table_array(const Tbl& top, const char* name) {
  std::vector<const toml::table*> out;
  const toml::node* n = top.node(name);
  if (!n) return out;
  if (n->is_table())
    top.fail(&n->source(), std::string(name) + ": write [[" + name + "]] with double brackets; each [[" + name +
                               "]] header starts one entry of a list");
  const toml::array* a = n->as_array();
  if (!a) top.fail_key(name, "must be a list of tables written as [[" + std::string(name) + "]], got " + describe(*n));
  for (std::size_t i = 0; i < a->size(); ++i) {
    const toml::node& e = *a->get(i);
    if (!e.is_table())
      top.fail(&e.source(), std::string(name) + " entry #" + std::to_string(i + 1) + ": must be a table, got " + describe(e));
    out.push_back(e.as_table());
  }
  return out;
}

const toml::table* sub_table(const Tbl& top, const char* name) {
  const toml::node* n = top.node(name);
  if (!n) return nullptr;
  if (n->is_array_of_tables())
    top.fail(&n->source(), std::string("[[") + name + "]]: write [" + name + "] with single brackets; there is only one " + name + " table");
  if (!n->is_table()) top.fail_key(name, "must be a table ([" + std::string(name) + "]), got " + describe(*n));
  return n->as_table();
}

const std::vector<std::string> kContactNames = {"sticky", "slip", "friction"};
constexpr Contact kContacts[] = {Contact::Sticky, Contact::Slip, Contact::Friction};

int contact_index(Contact c) {
  for (int i = 0; i < 3; ++i)
    if (kContacts[i] == c) return i;
  return 1;
}

void check_box(const Tbl& t, const Vec3& lo, const Vec3& hi, int dim) {
  for (int a = 0; a < dim; ++a)
    if (!(hi[a] > lo[a]))
      t.fail_key("upper", "must be > lower in every component; got lower = " + fmt_vec(lo, dim) + ", upper = " + fmt_vec(hi, dim));
}

// ----------------------------------------------------------------- parsing --

Scene build_scene(const toml::table& root, const std::string& source) {
  Scene s;

  // Top level. The dimension comes first: arrays depend on it.
  Tbl top(source, 2, root, "", "", nullptr);
  top.check_keys();
  if (auto d = top.opt_integer("dimension")) {
    if (*d != 2 && *d != 3) top.fail_key("dimension", "must be 2 or 3, got " + std::to_string(*d));
    s.dimension = static_cast<int>(*d);
  }
  const int dim = s.dimension;
  top.set_dim(dim);
  s.gravity = Vec3{0, 0, 0};
  s.gravity[dim - 1] = -9.81;
  if (auto g = top.opt_vector("gravity")) s.gravity = *g;

  // [grid]
  const toml::table* grid_t = sub_table(top, "grid");
  if (!grid_t) top.fail_table("[grid] is missing; it needs at least cell_size, lower and upper");
  {
    Tbl g(source, dim, *grid_t, "grid", "[grid]", &grid_t->source());
    const int walls = g.choice("walls", kContactNames, contact_index(s.grid.walls));
    s.grid.walls = kContacts[walls];
    g.check_keys({{"walls", kContactNames[walls]}});
    s.grid.cell_size = g.req_number("cell_size");
    g.check(s.grid.cell_size > 0, "cell_size", "> 0", s.grid.cell_size);
    s.grid.lower = g.req_vector("lower");
    s.grid.upper = g.req_vector("upper");
    check_box(g, s.grid.lower, s.grid.upper, dim);
    double nodes = 1;
    for (int a = 0; a < dim; ++a) {
      const double extent = s.grid.upper[a] - s.grid.lower[a];
      if (extent < s.grid.cell_size)
        g.fail_key("cell_size", "must not exceed the domain extent; cell_size = " + fmt(s.grid.cell_size) +
                                    " but upper - lower = " + fmt(extent) + " along axis " + std::string(1, "xyz"[a]));
      nodes *= extent / s.grid.cell_size + 7;
    }
    if (nodes > static_cast<double>(std::numeric_limits<int>::max()))
      g.fail_key("cell_size", "gives a grid of about " + fmt(nodes) + " nodes, too many (limit " +
                                  std::to_string(std::numeric_limits<int>::max()) + "); increase cell_size or shrink the domain");
    if (s.grid.walls == Contact::Friction) {
      if (!g.has("wall_friction")) g.missing("wall_friction", " (walls = \"friction\" needs it)");
      s.grid.wall_friction = g.req_number("wall_friction");
      g.check(s.grid.wall_friction >= 0, "wall_friction", ">= 0", s.grid.wall_friction);
    }
  }

  // end_time: top level (preferred) or [time], not both. Then [time].
  const toml::table* time_t = sub_table(top, "time");
  std::optional<Tbl> tm;
  if (time_t) {
    tm.emplace(source, dim, *time_t, "time", "[time]", &time_t->source());
    tm->check_keys();
  }
  if (top.has("end_time") && tm && tm->has("end_time"))
    top.fail(&tm->node("end_time")->source(),
             "end_time is given twice, at the top level (line " + std::to_string(top.node("end_time")->source().begin.line) +
                 ") and in [time]; keep one (the top level is preferred)");
  if (top.has("end_time")) {
    s.time.end_time = *top.opt_number("end_time");
    top.check(s.time.end_time > 0, "end_time", "> 0", s.time.end_time);
  }
  if (tm) {
    if (tm->has("end_time")) {
      s.time.end_time = *tm->opt_number("end_time");
      tm->check(s.time.end_time > 0, "end_time", "> 0", s.time.end_time);
    }
    s.time.cfl = tm->number("cfl", s.time.cfl);
    tm->check(s.time.cfl > 0 && s.time.cfl <= 1, "cfl", "in (0, 1]", s.time.cfl);
    s.time.fixed_dt = tm->number("dt", s.time.fixed_dt);
    tm->check(s.time.fixed_dt >= 0, "dt", ">= 0 (0 = automatic)", s.time.fixed_dt);
    s.time.damping = tm->number("damping", s.time.damping);
    tm->check(s.time.damping >= 0, "damping", ">= 0", s.time.damping);
  }

  // [output]
  if (const toml::table* out_t = sub_table(top, "output")) {
    Tbl o(source, dim, *out_t, "output", "[output]", &out_t->source());
    o.check_keys();
    if (auto d = o.opt_string("directory")) {
      if (d->empty()) o.fail_key("directory", "must not be empty");
      s.output.directory = *d;
    }
    s.output.interval = o.number("interval", s.output.interval);
    o.check(s.output.interval >= 0, "interval", ">= 0", s.output.interval);
    s.output.grid_fields = o.opt_bool("grid_fields").value_or(s.output.grid_fields);
    s.output.progress_interval = o.number("progress_interval", s.output.progress_interval);
    o.check(s.output.progress_interval >= 0, "progress_interval", ">= 0", s.output.progress_interval);
    s.output.outflow_interval = o.number("outflow_interval", s.output.outflow_interval);
    o.check(s.output.outflow_interval > 0, "outflow_interval", "> 0", s.output.outflow_interval);
  }

  // [[material]]
  const std::vector<std::string> model_names = {"drucker_prager", "mu_i"};
  std::vector<std::string> names;
  std::vector<int> name_line;
  const auto mats = table_array(top, "material");
  if (mats.empty()) top.fail_table("no [[material]] given; at least one is required");
  for (std::size_t i = 0; i < mats.size(); ++i) {
    Tbl m(source, dim, *mats[i], "material", "[[material]] #" + std::to_string(i + 1), &mats[i]->source());
    Material mat;
    const auto name = m.opt_string("name");
    if (name) m.set_label(m.label() + " (name \"" + *name + "\")");
    const int model = m.choice("model", model_names, 0);
    mat.model = model == 0 ? ModelKind::DruckerPrager : ModelKind::MuI;
    m.check_keys({{"model", model_names[model]}});
    if (!name) m.missing("name");
    if (name->empty()) m.fail_key("name", "must not be empty");
    for (std::size_t j = 0; j < names.size(); ++j)
      if (names[j] == *name)
        m.fail_key("name", "\"" + *name + "\" is already the name of [[material]] #" + std::to_string(j + 1) + " (line " +
                               std::to_string(name_line[j]) + "); material names must be unique");
    names.push_back(*name);
    name_line.push_back(static_cast<int>(mats[i]->source().begin.line));
    mat.name = *name;

    const double E = m.number("youngs_modulus", 1.0e7);
    m.check(E > 0, "youngs_modulus", "> 0", E);
    const double nu = m.number("poisson_ratio", 0.3);
    m.check(nu >= 0 && nu < 0.5, "poisson_ratio", "in [0, 0.5)", nu);

    if (mat.model == ModelKind::DruckerPrager) {
      auto& p = mat.drucker_prager;
      p.youngs_modulus = E;
      p.poisson_ratio = nu;
      p.friction_angle_deg = m.number("friction_angle", p.friction_angle_deg);
      m.check(p.friction_angle_deg > 0 && p.friction_angle_deg < 90, "friction_angle", "in (0, 90) degrees",
              p.friction_angle_deg);
      mat.density = m.number("density", mat.density);
    } else {
      auto& p = mat.mu_i;
      p.youngs_modulus = E;
      p.poisson_ratio = nu;
      p.mu_s = m.number("mu_s", p.mu_s);
      m.check(p.mu_s > 0, "mu_s", "> 0", p.mu_s);
      p.mu_2 = m.number("mu_2", p.mu_2);
      m.check(p.mu_2 > p.mu_s, "mu_2", "> mu_s (" + fmt(p.mu_s) + ")", p.mu_2);
      p.I0 = m.number("I0", p.I0);
      m.check(p.I0 > 0, "I0", "> 0", p.I0);
      p.grain_diameter = m.number("grain_diameter", p.grain_diameter);
      m.check(p.grain_diameter > 0, "grain_diameter", "> 0", p.grain_diameter);
      p.grain_density = m.number("grain_density", p.grain_density);
      m.check(p.grain_density > 0, "grain_density", "> 0", p.grain_density);
      p.critical_density = m.number("critical_density", 0.6 * p.grain_density);
      m.check(p.critical_density > 0 && p.critical_density < p.grain_density, "critical_density",
              "in (0, grain_density = " + fmt(p.grain_density) + ")", p.critical_density);
      mat.density = m.number("density", p.critical_density);
    }
    m.check(mat.density > 0, "density", "> 0", mat.density);
    s.materials.push_back(mat);
  }

  // [[block]]
  const std::vector<std::string> shape_names = {"box", "cylinder"};
  const std::vector<std::string> axis_names = {"x", "y", "z"};
  const auto blocks = table_array(top, "block");
  if (blocks.empty()) top.fail_table("no [[block]] given; at least one is required to place material");
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    Tbl b(source, dim, *blocks[i], "block", "[[block]] #" + std::to_string(i + 1), &blocks[i]->source());
    Block blk;
    const int shape = b.choice("shape", shape_names, 0);
    blk.shape = shape == 0 ? Shape::Box : Shape::Cylinder;
    const auto geo = b.opt_bool("geostatic");
    blk.geostatic = geo.value_or(blk.geostatic);
    b.check_keys({{"shape", shape_names[shape]}, {"geostatic", blk.geostatic ? "true" : "false"}});

    const auto mat = b.opt_string("material");
    if (!mat) b.missing("material", "; defined materials are: " + quoted_list(names));
    if (std::find(names.begin(), names.end(), *mat) == names.end()) {
      std::string msg = "no material named \"" + *mat + "\"";
      const std::string near = closest(*mat, names);
      if (!near.empty()) msg += " (did you mean \"" + near + "\"?)";
      b.fail_key("material", msg + "; defined materials are: " + quoted_list(names));
    }
    blk.material = *mat;

    Vec3 lo{0, 0, 0}, hi{0, 0, 0};  // bounding box, for the domain check
    if (blk.shape == Shape::Box) {
      blk.lower = b.req_vector("lower", " (a box needs lower and upper)");
      blk.upper = b.req_vector("upper", " (a box needs lower and upper)");
      check_box(b, blk.lower, blk.upper, dim);
      lo = blk.lower;
      hi = blk.upper;
    } else {
      blk.center = b.req_vector("center", " (a cylinder needs center and radius)");
      if (!b.has("radius")) b.missing("radius", " (a cylinder needs center and radius)");
      blk.radius = b.req_number("radius");
      b.check(blk.radius > 0, "radius", "> 0", blk.radius);
      if (dim == 3) {
        blk.axis = b.choice("axis", axis_names, 2);
        if (!b.has("height")) b.missing("height", " (a 3D cylinder needs height)");
        blk.height = b.req_number("height");
        b.check(blk.height > 0, "height", "> 0", blk.height);
      }
      for (int a = 0; a < dim; ++a) {
        const double half = (dim == 3 && a == blk.axis) ? 0.5 * blk.height : blk.radius;
        lo[a] = blk.center[a] - half;
        hi[a] = blk.center[a] + half;
      }
    }

    if (auto ppc = b.opt_integer("points_per_cell")) {
      bool ok = *ppc == 0;
      std::int64_t n = 1;
      for (; !ok && n <= 64; ++n) {
        const std::int64_t p = dim == 2 ? n * n : n * n * n;
        if (p == *ppc) ok = true;
        if (p >= *ppc) break;
      }
      if (!ok)
        b.fail_key("points_per_cell", "must be 0 (default) or n^" + std::to_string(dim) + " for an integer n >= 1 (" +
                                          (dim == 2 ? "1, 4, 9, 16, ..." : "1, 8, 27, 64, ...") + "), got " +
                                          std::to_string(*ppc));
      blk.points_per_cell = static_cast<int>(*ppc);
    }
    if (auto v = b.opt_vector("velocity")) blk.velocity = *v;
    if (blk.geostatic) {
      blk.k0 = b.number("k0", blk.k0);
      b.check(blk.k0 >= 0 && blk.k0 <= 1, "k0", "in [0, 1]", blk.k0);
    }

    const double tol = 1e-9 * s.grid.cell_size;
    for (int a = 0; a < dim; ++a)
      if (lo[a] < s.grid.lower[a] - tol || hi[a] > s.grid.upper[a] + tol)
        b.fail_table("the block extends outside the grid domain: it spans " + fmt_vec(lo, dim) + " to " + fmt_vec(hi, dim) +
                     ", the grid domain is lower = " + fmt_vec(s.grid.lower, dim) + ", upper = " +
                     fmt_vec(s.grid.upper, dim) + " (axis " + std::string(1, "xyz"[a]) + ")");
    s.blocks.push_back(blk);
  }

  // [[boundary]]
  const std::vector<std::string> type_names = {"plane", "box"};
  const auto bounds = table_array(top, "boundary");
  for (std::size_t i = 0; i < bounds.size(); ++i) {
    Tbl b(source, dim, *bounds[i], "boundary", "[[boundary]] #" + std::to_string(i + 1), &bounds[i]->source());
    Boundary bd;
    const int type = b.choice("type", type_names, 0);
    bd.kind = type == 0 ? BoundaryKind::Plane : BoundaryKind::Box;
    const int contact = b.choice("contact", kContactNames, contact_index(bd.contact));
    bd.contact = kContacts[contact];
    b.check_keys({{"type", type_names[type]}, {"contact", kContactNames[contact]}});
    if (bd.contact == Contact::Friction) {
      if (!b.has("friction")) b.missing("friction", " (contact = \"friction\" needs it)");
      bd.friction = b.req_number("friction");
      b.check(bd.friction >= 0, "friction", ">= 0", bd.friction);
    }
    bd.separating = b.opt_bool("separating").value_or(bd.separating);
    if (bd.kind == BoundaryKind::Plane) {
      bd.point = b.req_vector("point", " (a plane needs point and normal)");
      const Vec3 n = b.req_vector("normal", " (a plane needs point and normal)");
      const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      if (!(len > 0)) b.fail_key("normal", "must be non-zero, got " + fmt_vec(n, dim));
      for (int a = 0; a < 3; ++a) bd.normal[a] = n[a] / len;
    } else {
      bd.lower = b.req_vector("lower", " (a box needs lower and upper)");
      bd.upper = b.req_vector("upper", " (a box needs lower and upper)");
      check_box(b, bd.lower, bd.upper, dim);
      bd.inside = b.opt_bool("inside").value_or(bd.inside);
    }
    if (auto v = b.opt_vector("velocity")) bd.velocity = *v;
    s.boundaries.push_back(bd);
  }

  // [[outlet]]
  const auto outlets = table_array(top, "outlet");
  for (std::size_t i = 0; i < outlets.size(); ++i) {
    Tbl o(source, dim, *outlets[i], "outlet", "[[outlet]] #" + std::to_string(i + 1), &outlets[i]->source());
    o.check_keys();
    Outlet out;
    out.lower = o.req_vector("lower", " (an outlet is a box: lower and upper)");
    out.upper = o.req_vector("upper", " (an outlet is a box: lower and upper)");
    check_box(o, out.lower, out.upper, dim);
    for (int a = 0; a < dim; ++a)
      if (out.upper[a] <= s.grid.lower[a] || out.lower[a] >= s.grid.upper[a])
        o.fail_table("the outlet lies outside the grid domain (axis " + std::string(1, "xyz"[a]) + "): it spans " +
                     fmt_vec(out.lower, dim) + " to " + fmt_vec(out.upper, dim) + ", the domain is " +
                     fmt_vec(s.grid.lower, dim) + " to " + fmt_vec(s.grid.upper, dim) +
                     "; material would leave the grid before reaching it");
    s.outlets.push_back(out);
  }
  return s;
}

// --------------------------------------------------------------- reference --

std::string wrap(const std::string& text, std::size_t indent, std::size_t width = 79) {
  std::istringstream words(text);
  std::string word, out, line(indent, ' ');
  bool empty = true;
  while (words >> word) {
    if (!empty && line.size() + 1 + word.size() > width) {
      out += line + "\n";
      line.assign(indent, ' ');
      empty = true;
    }
    line += (empty ? "" : " ") + word;
    empty = false;
  }
  if (!empty) out += line + "\n";
  return out;
}

const char* kind_name(Kind k) {
  switch (k) {
    case Kind::Number: return "number";
    case Kind::Integer: return "integer";
    case Kind::String: return "string";
    case Kind::Bool: return "true/false";
    case Kind::Vector: return "[d] array of numbers";
    case Kind::Table: return "table";
    case Kind::TableArray: return "array of tables";
  }
  return "";
}

}  // namespace

Scene parse_scene(std::string_view text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(text, std::string_view(source));
  } catch (const toml::parse_error& e) {
    const auto& b = e.source().begin;
    throw UserError(source + ":" + std::to_string(b.line) + ":" + std::to_string(b.column) +
                    ": TOML syntax error at line " + std::to_string(b.line) + ", column " + std::to_string(b.column) +
                    ": " + std::string(e.description()));
  }
  return build_scene(root, source);
}

Scene load_scene(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw UserError("scene file \"" + path + "\" not found");
  if (std::filesystem::is_directory(path, ec))
    throw UserError("scene file \"" + path + "\" is a directory, not a TOML file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UserError("cannot open scene file \"" + path + "\" for reading");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw UserError("error reading scene file \"" + path + "\"");
  return parse_scene(text.str(), path);
}

std::string config_reference() {
  std::string r;
  r += wrap("A scene is a TOML file (https://toml.io). Units are SI (m, s, kg, Pa); angles are in degrees. "
            "In 2D every quantity is per unit depth. \"[d] array\" means an array of `dimension` numbers, "
            "e.g. [0.1, 0.2] in 2D or [0.1, 0.2, 0.3] in 3D; vectors are (x, y) or (x, y, z). Integers "
            "are accepted where numbers are expected. Unknown keys are errors. Keys that are not "
            "given take the default shown.", 0);
  for (const TableDesc& t : kTables) {
    r += "\n";
    r += t.title;
    r += "\n" + std::string(std::string(t.title).size(), '-') + "\n";
    r += wrap(t.help, 0);
    for (const KeyDesc& d : kKeys) {
      if (std::string_view(d.table) != t.name) continue;
      r += "\n  " + std::string(d.key) + " : " + kind_name(d.kind);
      if (*d.unit) r += ", " + std::string(d.unit);
      r += "\n";
      const std::string deflt = d.deflt;
      std::string attrs = deflt.rfind("required", 0) == 0 ? "R" + deflt.substr(1) + "."
                          : d.kind == Kind::Table ? std::string("Optional.")
                                                  : "Default: " + deflt + ".";
      if (*d.allowed) attrs += " Allowed: " + std::string(d.allowed) + ".";
      if (d.when_key) attrs += " Only with " + std::string(d.when_key) + " = " +
                               (std::string_view(d.when_value) == "true" ? std::string("true")
                                                                         : "\"" + std::string(d.when_value) + "\"") +
                               (d.only_3d ? ", in 3D." : ".");
      else if (d.only_3d) attrs += " 3D only.";
      r += wrap(attrs, 6);
      r += wrap(d.help, 6);
    }
  }
  r += "\nMinimal scene\n-------------\n";
  r += "  end_time = 1.0\n"
       "  [grid]\n"
       "  cell_size = 0.01\n"
       "  lower = [0.0, 0.0]\n"
       "  upper = [1.0, 0.5]\n"
       "  [[material]]\n"
       "  name = \"sand\"\n"
       "  [[block]]\n"
       "  material = \"sand\"\n"
       "  lower = [0.0, 0.0]\n"
       "  upper = [0.2, 0.2]\n";
  return r;
}

}  // namespace mpm
