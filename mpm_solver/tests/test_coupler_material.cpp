// Material files (docs/design.md section 4.6) read by fix hybrid/mpm's keyword `material`
// (coupler/material_file.hpp): every key checked, the contact law compared, the constants applied.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "coupler/material_file.hpp"
#include "coupler/protocol.hpp"

namespace {

const char* const kValid = R"([material]
name = "disks"
dimension = 2
[contact]
pair = "gran/hooke/history"
friction = 0.5
restitution = 0.5
kt_over_kn = 0.2857142857142857
gammat_over_gamman = 0.5
polydispersity = 0.1
stiffness_number = 1000.0
[continuum]
packing_fraction = 0.82
critical_packing = 0.79
youngs_over_kn = 0.8
poisson = 0.25
mu_s = 0.28
mu_2 = 0.55
I0 = 0.3
friction_angle = 16.26
)";

std::string write(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path.string();
}

std::string error_of(const std::string& text) {
  try {
    coupler::read_material_file(write("material_error.toml", text));
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  return text.replace(text.find(from), from.size(), to);
}

}  // namespace

TEST(coupler_material, ReadsEveryKey) {
  const auto m = coupler::read_material_file(write("material_ok.toml", kValid));
  EXPECT_EQ(m.name, "disks");
  EXPECT_EQ(m.dimension, 2);
  EXPECT_EQ(m.pair, "gran/hooke/history");
  EXPECT_DOUBLE_EQ(m.friction, 0.5);
  EXPECT_DOUBLE_EQ(m.youngs_over_kn, 0.8);
  EXPECT_DOUBLE_EQ(m.mu_2, 0.55);
  EXPECT_DOUBLE_EQ(m.friction_angle, 16.26);
}

TEST(coupler_material, ErrorsNameTheKey) {
  EXPECT_NE(error_of(replaced(kValid, "mu_s = 0.28\n", "")).find("[continuum] mu_s is missing"), std::string::npos);
  EXPECT_NE(error_of(replaced(kValid, "poisson = 0.25", "poisson = 0.7")).find("[continuum] poisson = 0.7 is outside"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kValid, "I0 = 0.3", "I0 = \"x\"")).find("[continuum] I0 must be a number"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(kValid, "mu_2 = 0.55", "mu_2 = 0.2")).find("mu_2 must exceed mu_s"), std::string::npos);
  EXPECT_NE(error_of(replaced(kValid, "critical_packing = 0.79", "critical_packing = 0.83"))
                .find("packing_fraction must exceed critical_packing"),
            std::string::npos);
  EXPECT_NE(error_of("[material\n").find("material file"), std::string::npos);
}

// The fill pressure's modulus from the calibration (fix keyword `fill auto`): the calibration
// compressed the grains to p0 = kn / kappa (2D; kn / (kappa d) in 3D), densifying them from the
// critical packing 0.79 to 0.82, so p0 per relative densification (0.82 - 0.79) / 0.82.
TEST(coupler_material, CompactionModulusIsTheCalibrationsPressureOverItsDensification) {
  auto m = coupler::read_material_file(write("material_ok.toml", kValid));
  EXPECT_NEAR(coupler::compaction_modulus(m, 4e5, 0.002), 400.0 * 0.82 / 0.03, 1e-9);
  m.dimension = 3;
  EXPECT_NEAR(coupler::compaction_modulus(m, 4e5, 0.002), 400.0 / 0.002 * 0.82 / 0.03, 1e-6);
}

TEST(coupler_material, RestitutionOfAHookeanPair) {
  // e from the decks' damping formula: gamma_n = 2 zeta sqrt(kn/m_eff), zeta = -ln e / sqrt(pi^2 + ln^2 e)
  for (double e : {0.1, 0.5, 0.9}) {
    const double kn = 1e5, m_eff = 2e-3, zeta = -std::log(e) / std::sqrt(M_PI * M_PI + std::log(e) * std::log(e));
    EXPECT_NEAR(coupler::restitution(kn, 2 * zeta * std::sqrt(kn / m_eff), m_eff), e, 1e-12);
  }
  EXPECT_EQ(coupler::restitution(1.0, 10.0, 1.0), 0.0);  // overdamped
}

TEST(coupler_material, ContactLawMustMatchAndSetsTheConstants) {
  const auto m = coupler::read_material_file(write("material_ok.toml", kValid));
  coupler::DeckContact deck;
  deck.dimension = 2;
  deck.friction = 0.5;
  deck.kn = 4e5;
  deck.kt = deck.kn * 2 / 7;
  deck.mean_mass = 7.85e-3;
  const double zeta = -std::log(0.5) / std::sqrt(M_PI * M_PI + std::log(0.5) * std::log(0.5));
  deck.gamman = 2 * zeta * std::sqrt(deck.kn / (0.5 * deck.mean_mass));
  deck.gammat = 0.5 * deck.gamman;
  EXPECT_EQ(coupler::contact_mismatch(m, deck), "");
  auto other = deck;
  other.friction = 0.3;
  other.kt = other.kn;
  const std::string why = coupler::contact_mismatch(m, other);
  EXPECT_NE(why.find("friction mu 0.3 in the deck, 0.5 in the calibration"), std::string::npos) << why;
  EXPECT_NE(why.find("kt/kn 1 in the deck"), std::string::npos) << why;

  coupler::ContinuumSettings c;
  coupler::apply_material(m, deck.kn, 0.002, c);
  EXPECT_DOUBLE_EQ(c.youngs_modulus, 0.8 * 4e5);  // 2D: E = youngs_over_kn kn
  EXPECT_DOUBLE_EQ(c.friction_angle_deg, 16.26);
  EXPECT_DOUBLE_EQ(c.critical_packing, 0.79);
  auto m3 = m;
  m3.dimension = 3;
  coupler::apply_material(m3, 100.0, 0.002, c);
  EXPECT_DOUBLE_EQ(c.youngs_modulus, 0.8 * 100.0 / 0.002);  // 3D: E = youngs_over_kn kn / d
}

TEST(coupler_material, FindsAPathOrANameInTheMaterialDirectories) {
  const auto path = write("material_found.toml", kValid);
  EXPECT_EQ(coupler::find_material_file(path), path);
  // a name: looked up with and without .toml in $HYBRID_MATERIALS
  const auto dir = std::filesystem::path(path).parent_path().string();
  ::setenv("HYBRID_MATERIALS", ("/no/such/dir:" + dir).c_str(), 1);
  EXPECT_EQ(coupler::find_material_file("material_found"), path);
  EXPECT_EQ(coupler::find_material_file("material_found.toml"), path);
  // the project's own calibrated materials are found by name without any setting
  ::unsetenv("HYBRID_MATERIALS");
  const auto disks = coupler::find_material_file("disks_2d");
  EXPECT_EQ(coupler::read_material_file(disks).dimension, 2);
  try {
    coupler::find_material_file("no_such_material");
    FAIL() << "an unknown material was found";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no_such_material not found"), std::string::npos) << what;
    EXPECT_NE(what.find("input_decks/materials"), std::string::npos) << what;
    EXPECT_NE(what.find("tools/calibrate.py"), std::string::npos) << what;
  }
}
