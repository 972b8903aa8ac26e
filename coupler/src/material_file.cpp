#include "coupler/material_file.hpp"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <vector>
#include <stdexcept>

#include <toml++/toml.h>

#include "coupler/protocol.hpp"

namespace coupler {

namespace {

class Reader {
 public:
  Reader(const std::string& path, const toml::table& root) : path_(path), root_(root) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw std::runtime_error("material file " + path_ + ": " + key + " " + what +
                             " (a material file holds every key of docs/design.md section 4.6)");
  }
  double number(const char* table, const char* key, double lo, double hi) const {
    const std::string name = std::string("[") + table + "] " + key;
    const auto node = root_[table][key];
    if (!node) fail(name, "is missing");
    const auto v = node.value<double>();
    if (!v) fail(name, "must be a number");
    if (!(*v >= lo && *v <= hi)) {
      std::ostringstream range;
      range << "= " << *v << " is outside [" << lo << ", " << hi << "]";
      fail(name, range.str());
    }
    return *v;
  }
  std::string text(const char* table, const char* key) const {
    const auto v = root_[table][key].value<std::string>();
    if (!v) fail(std::string("[") + table + "] " + key, "is missing or not a string");
    return *v;
  }

 private:
  std::string path_;
  const toml::table& root_;
};

}  // namespace

std::string find_material_file(const std::string& name_or_path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_regular_file(name_or_path, ec)) return name_or_path;
  std::vector<std::string> dirs;
  if (name_or_path.find('/') == std::string::npos) {
    if (const char* env = std::getenv("HYBRID_MATERIALS")) {
      std::istringstream list(env);
      for (std::string dir; std::getline(list, dir, ':');)
        if (!dir.empty()) dirs.push_back(dir);
    }
    dirs.push_back(HYBRID_MATERIAL_DIR);
    for (const auto& dir : dirs)
      for (const char* suffix : {"", ".toml"}) {
        const fs::path candidate = fs::path(dir) / (name_or_path + suffix);
        if (fs::is_regular_file(candidate, ec)) return candidate.string();
      }
  }
  std::ostringstream what;
  what << "material file " << name_or_path << " not found";
  if (!dirs.empty()) {
    what << " (as a path, nor as a name in";
    for (const auto& dir : dirs) what << " " << dir;
    what << ")";
  }
  what << "; give the path of a material file, or calibrate one from the grains with tools/calibrate.py "
          "(docs/calibration.md)";
  throw std::runtime_error(what.str());
}

CalibratedMaterial read_material_file(const std::string& path) {
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    std::ostringstream what;
    what << "material file " << path << ": " << e.description();
    if (e.source().begin.line > 0) what << " (line " << e.source().begin.line << ")";
    throw std::runtime_error(what.str());
  }
  const Reader r(path, root);
  CalibratedMaterial m;
  m.path = path;
  m.name = r.text("material", "name");
  m.dimension = static_cast<int>(r.number("material", "dimension", 2, 3));
  m.pair = r.text("contact", "pair");
  m.friction = r.number("contact", "friction", 0, 10);
  m.restitution = r.number("contact", "restitution", 0, 1);
  m.kt_over_kn = r.number("contact", "kt_over_kn", 0, 10);
  m.gammat_over_gamman = r.number("contact", "gammat_over_gamman", 0, 10);
  m.polydispersity = r.number("contact", "polydispersity", 0, 0.9);
  m.stiffness_number = r.number("contact", "stiffness_number", 1, 1e12);
  m.packing_fraction = r.number("continuum", "packing_fraction", 0.05, 1);
  m.critical_packing = r.number("continuum", "critical_packing", 0.05, 1);
  m.youngs_over_kn = r.number("continuum", "youngs_over_kn", 1e-6, 1e6);
  m.poisson = r.number("continuum", "poisson", 0, 0.4999);
  m.mu_s = r.number("continuum", "mu_s", 1e-3, 10);
  m.mu_2 = r.number("continuum", "mu_2", 1e-3, 10);
  m.I0 = r.number("continuum", "I0", 1e-6, 100);
  m.friction_angle = r.number("continuum", "friction_angle", 0.01, 89.99);
  if (!(m.mu_2 > m.mu_s)) r.fail("[continuum] mu_2", "must exceed mu_s");
  if (!(m.packing_fraction > m.critical_packing))
    r.fail("[continuum] packing_fraction", "must exceed critical_packing (the packing at rest is denser than in flow)");
  return m;
}

double restitution(double kn, double gamman, double m_eff) {
  const double zeta = gamman / (2.0 * std::sqrt(kn / m_eff));
  if (zeta >= 1.0) return 0.0;
  return std::exp(-M_PI * zeta / std::sqrt(1.0 - zeta * zeta));
}

std::string contact_mismatch(const CalibratedMaterial& m, const DeckContact& deck) {
  // the decks compute their constants from rounded inputs: 1e-3 relative is "the same law"
  auto differs = [](double a, double b, double tol) { return std::abs(a - b) > tol * std::max(std::abs(b), 1e-12); };
  std::ostringstream out;
  auto say = [&](const char* what, double calibrated, double in_deck) {
    out << (out.tellp() > 0 ? "; " : "") << what << " " << in_deck << " in the deck, " << calibrated
        << " in the calibration";
  };
  if (deck.dimension != m.dimension) say("dimension", m.dimension, deck.dimension);
  if (differs(m.friction, deck.friction, 1e-3)) say("friction mu", m.friction, deck.friction);
  if (deck.kn > 0 && differs(m.kt_over_kn, deck.kt / deck.kn, 1e-3)) say("kt/kn", m.kt_over_kn, deck.kt / deck.kn);
  if (deck.gamman > 0 && differs(m.gammat_over_gamman, deck.gammat / deck.gamman, 1e-3))
    say("gamma_t/gamma_n", m.gammat_over_gamman, deck.gammat / deck.gamman);
  const double e = restitution(deck.kn, deck.gamman, 0.5 * deck.mean_mass);
  if (std::abs(e - m.restitution) > 0.02) say("restitution of a mean-size pair", m.restitution, e);
  return out.str();
}

void apply_material(const CalibratedMaterial& m, double kn, double diameter, ContinuumSettings& c) {
  c.youngs_modulus = m.youngs_over_kn * kn / (m.dimension == 3 ? diameter : 1.0);
  c.poisson_ratio = m.poisson;
  c.friction_angle_deg = m.friction_angle;
  c.mu_s = m.mu_s;
  c.mu_2 = m.mu_2;
  c.I0 = m.I0;
  c.critical_packing = m.critical_packing;
}

double compaction_modulus(const CalibratedMaterial& m, double kn, double diameter) {
  const double p0 = kn / (m.stiffness_number * (m.dimension == 3 ? diameter : 1.0));
  return p0 * m.packing_fraction / (m.packing_fraction - m.critical_packing);
}

}  // namespace coupler
