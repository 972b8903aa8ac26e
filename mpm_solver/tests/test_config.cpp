// Scene config parsing: defaults, validation messages, and the example decks.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "mpm/config.hpp"
#include "mpm/types.hpp"

namespace {

using mpm::parse_scene;

// A valid 2D scene that sets only what is required.
const std::string kMinimal2D = R"(
[grid]
cell_size = 0.01
lower = [0.0, 0.0]
upper = [1.0, 0.5]

[[material]]
name = "sand"

[[block]]
material = "sand"
lower = [0.1, 0.0]
upper = [0.3, 0.2]
)";

/// The UserError message parsing `text` gives; fails the test if it parses.
std::string error_of(const std::string& text) {
  try {
    parse_scene(text, "scene.toml");
  } catch (const mpm::UserError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a UserError for:\n" << text;
  return "";
}

/// kMinimal2D with `from` replaced by `to` (which must occur).
std::string edit(const std::string& from, const std::string& to, std::string text = kMinimal2D) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

TEST(Config, Minimal2DTakesDefaults) {
  const mpm::Scene s = parse_scene(kMinimal2D, "minimal.toml");
  EXPECT_EQ(s.dimension, 2);
  EXPECT_DOUBLE_EQ(s.gravity[0], 0.0);
  EXPECT_DOUBLE_EQ(s.gravity[1], -9.81);
  EXPECT_DOUBLE_EQ(s.gravity[2], 0.0);
  EXPECT_DOUBLE_EQ(s.grid.cell_size, 0.01);
  EXPECT_DOUBLE_EQ(s.grid.upper[0], 1.0);
  EXPECT_DOUBLE_EQ(s.grid.upper[1], 0.5);
  EXPECT_EQ(s.grid.walls, mpm::Contact::Slip);
  EXPECT_DOUBLE_EQ(s.time.cfl, 0.5);
  EXPECT_DOUBLE_EQ(s.time.fixed_dt, 0.0);
  EXPECT_DOUBLE_EQ(s.time.end_time, 1.0);
  EXPECT_EQ(s.output.directory, "mpm_output");
  EXPECT_DOUBLE_EQ(s.output.interval, 0.0);
  EXPECT_FALSE(s.output.grid_fields);
  ASSERT_EQ(s.materials.size(), 1u);
  EXPECT_EQ(s.materials[0].name, "sand");
  EXPECT_EQ(s.materials[0].model, mpm::ModelKind::DruckerPrager);
  EXPECT_DOUBLE_EQ(s.materials[0].density, 1600.0);
  EXPECT_DOUBLE_EQ(s.materials[0].drucker_prager.friction_angle_deg, 30.0);
  ASSERT_EQ(s.blocks.size(), 1u);
  EXPECT_EQ(s.blocks[0].material, "sand");
  EXPECT_EQ(s.blocks[0].shape, mpm::Shape::Box);
  EXPECT_EQ(s.blocks[0].points_per_cell, 0);
  EXPECT_DOUBLE_EQ(s.blocks[0].lower[0], 0.1);
  EXPECT_DOUBLE_EQ(s.blocks[0].upper[1], 0.2);
  EXPECT_FALSE(s.blocks[0].geostatic);
  EXPECT_TRUE(s.boundaries.empty());
}

TEST(Config, ThreeDGravityIsAlongZ) {
  const mpm::Scene s = parse_scene(R"(
dimension = 3
end_time = 0.25
[grid]
cell_size = 0.02
lower = [0, 0, 0]
upper = [1, 1, 0.5]
[[material]]
name = "sand"
[[block]]
material = "sand"
shape = "cylinder"
center = [0.5, 0.5, 0.1]
radius = 0.1
height = 0.2
points_per_cell = 27
)");
  EXPECT_EQ(s.dimension, 3);
  EXPECT_DOUBLE_EQ(s.gravity[0], 0.0);
  EXPECT_DOUBLE_EQ(s.gravity[1], 0.0);
  EXPECT_DOUBLE_EQ(s.gravity[2], -9.81);
  EXPECT_DOUBLE_EQ(s.time.end_time, 0.25);
  ASSERT_EQ(s.blocks.size(), 1u);
  EXPECT_EQ(s.blocks[0].shape, mpm::Shape::Cylinder);
  EXPECT_EQ(s.blocks[0].axis, 2);  // default "z"
  EXPECT_DOUBLE_EQ(s.blocks[0].height, 0.2);
  EXPECT_EQ(s.blocks[0].points_per_cell, 27);
}

TEST(Config, ReadsEveryTableAndAcceptsIntegersAsNumbers) {
  const mpm::Scene s = parse_scene(R"(
gravity = [1, -9]
[grid]
cell_size = 1
lower = [0, 0]
upper = [10, 5]
walls = "friction"
wall_friction = 0.4
[time]
end_time = 2
cfl = 0.3
dt = 1e-4
[output]
directory = "out"
interval = 0.05
grid_fields = true
progress_interval = 0
[[material]]
name = "beads"
model = "mu_i"
grain_density = 2500
youngs_modulus = 2e6
[[block]]
material = "beads"
shape = "cylinder"
center = [5, 2]
radius = 1
velocity = [1, 0]
geostatic = true
k0 = 0.4
[[boundary]]
type = "plane"
contact = "friction"
friction = 0.5
point = [0, 0.5]
normal = [0, 2]
separating = false
[[boundary]]
type = "box"
contact = "sticky"
lower = [4, 4]
upper = [6, 5]
velocity = [0, -0.1]
)");
  EXPECT_DOUBLE_EQ(s.gravity[0], 1.0);
  EXPECT_DOUBLE_EQ(s.gravity[1], -9.0);
  EXPECT_DOUBLE_EQ(s.grid.cell_size, 1.0);
  EXPECT_EQ(s.grid.walls, mpm::Contact::Friction);
  EXPECT_DOUBLE_EQ(s.grid.wall_friction, 0.4);
  EXPECT_DOUBLE_EQ(s.time.end_time, 2.0);  // [time] end_time is accepted too
  EXPECT_DOUBLE_EQ(s.time.cfl, 0.3);
  EXPECT_DOUBLE_EQ(s.time.fixed_dt, 1e-4);
  EXPECT_EQ(s.output.directory, "out");
  EXPECT_DOUBLE_EQ(s.output.interval, 0.05);
  EXPECT_TRUE(s.output.grid_fields);
  EXPECT_DOUBLE_EQ(s.output.progress_interval, 0.0);

  const mpm::Material& m = s.materials.at(0);
  EXPECT_EQ(m.model, mpm::ModelKind::MuI);
  EXPECT_DOUBLE_EQ(m.mu_i.youngs_modulus, 2e6);
  EXPECT_DOUBLE_EQ(m.mu_i.mu_s, 0.382);
  EXPECT_DOUBLE_EQ(m.mu_i.grain_density, 2500.0);
  // critical_density defaults to 0.6 * grain_density, density to critical_density.
  EXPECT_DOUBLE_EQ(m.mu_i.critical_density, 1500.0);
  EXPECT_DOUBLE_EQ(m.density, 1500.0);

  const mpm::Block& b = s.blocks.at(0);
  EXPECT_EQ(b.shape, mpm::Shape::Cylinder);
  EXPECT_DOUBLE_EQ(b.radius, 1.0);
  EXPECT_DOUBLE_EQ(b.velocity[0], 1.0);
  EXPECT_TRUE(b.geostatic);
  EXPECT_DOUBLE_EQ(b.k0, 0.4);

  ASSERT_EQ(s.boundaries.size(), 2u);
  EXPECT_EQ(s.boundaries[0].kind, mpm::BoundaryKind::Plane);
  EXPECT_EQ(s.boundaries[0].contact, mpm::Contact::Friction);
  EXPECT_DOUBLE_EQ(s.boundaries[0].friction, 0.5);
  EXPECT_FALSE(s.boundaries[0].separating);
  EXPECT_DOUBLE_EQ(s.boundaries[0].normal[0], 0.0);  // normalised
  EXPECT_DOUBLE_EQ(s.boundaries[0].normal[1], 1.0);
  EXPECT_EQ(s.boundaries[1].kind, mpm::BoundaryKind::Box);
  EXPECT_EQ(s.boundaries[1].contact, mpm::Contact::Sticky);
  EXPECT_FALSE(s.boundaries[1].inside);
  EXPECT_DOUBLE_EQ(s.boundaries[1].velocity[1], -0.1);
}

TEST(Config, ExplicitMuIDensityIsKept) {
  const mpm::Scene s = parse_scene(edit("name = \"sand\"", "name = \"sand\"\nmodel = \"mu_i\"\ndensity = 1550"));
  EXPECT_DOUBLE_EQ(s.materials.at(0).density, 1550.0);
  EXPECT_DOUBLE_EQ(s.materials.at(0).mu_i.critical_density, 0.6 * 2450.0);
}

TEST(Config, UnknownKeyNamesTableAndSuggests) {
  const std::string msg = error_of(edit("name = \"sand\"", "name = \"sand\"\nfrction_angle = 35"));
  EXPECT_NE(msg.find("scene.toml:9:"), std::string::npos) << msg;  // the line of the bad key
  EXPECT_NE(msg.find("[[material]] #1 (name \"sand\") key \"frction_angle\": unknown key"), std::string::npos) << msg;
  EXPECT_NE(msg.find("did you mean \"friction_angle\"?"), std::string::npos) << msg;
  EXPECT_NE(msg.find("allowed keys in [[material]] are: name, model"), std::string::npos) << msg;
}

TEST(Config, UnknownTopLevelKeyIsCaught) {
  const std::string msg = error_of("dimensoin = 3\n" + kMinimal2D);
  EXPECT_NE(msg.find("key \"dimensoin\": unknown key (did you mean \"dimension\"?)"), std::string::npos) << msg;
  EXPECT_NE(msg.find("scene.toml:1:"), std::string::npos) << msg;
}

TEST(Config, TopLevelKeyAfterTableHeaderIsExplained) {
  // `gravity` written after [grid] lands in the grid table.
  const std::string msg = error_of(edit("cell_size = 0.01", "cell_size = 0.01\ngravity = [0, -1]"));
  EXPECT_NE(msg.find("[grid] key \"gravity\": unknown key"), std::string::npos) << msg;
  EXPECT_NE(msg.find("top-level key"), std::string::npos) << msg;
}

TEST(Config, WrongArrayLengthNamesKey) {
  const std::string msg = error_of(edit("lower = [0.0, 0.0]", "lower = [0.0, 0.0, 0.0]"));
  EXPECT_NE(msg.find("[grid] lower: must be an array of 2 numbers"), std::string::npos) << msg;
  EXPECT_NE(msg.find("got 3 elements"), std::string::npos) << msg;
}

TEST(Config, NegativeCellSize) {
  const std::string msg = error_of(edit("cell_size = 0.01", "cell_size = -0.1"));
  EXPECT_NE(msg.find("[grid] cell_size: must be > 0, got -0.1"), std::string::npos) << msg;
  EXPECT_EQ(msg.rfind("scene.toml:", 0), 0u) << msg;
}

TEST(Config, WrongTypeNamesKeyAndType) {
  const std::string msg = error_of(edit("cell_size = 0.01", "cell_size = \"0.01\""));
  EXPECT_NE(msg.find("[grid] cell_size: must be a number, got string \"0.01\""), std::string::npos) << msg;
}

TEST(Config, BadModelStringListsModels) {
  const std::string msg = error_of(edit("name = \"sand\"", "name = \"sand\"\nmodel = \"mu_I\""));
  EXPECT_NE(msg.find("[[material]] #1 (name \"sand\") model: unknown value \"mu_I\""), std::string::npos) << msg;
  EXPECT_NE(msg.find("did you mean \"mu_i\"?"), std::string::npos) << msg;
  EXPECT_NE(msg.find("\"drucker_prager\", \"mu_i\""), std::string::npos) << msg;
}

TEST(Config, KeyOfOtherModelIsAnError) {
  const std::string msg =
      error_of(edit("name = \"sand\"", "name = \"sand\"\nmodel = \"mu_i\"\nfriction_angle = 30"));
  EXPECT_NE(msg.find("key \"friction_angle\": belongs to model = \"drucker_prager\""), std::string::npos) << msg;
  EXPECT_NE(msg.find("here model = \"mu_i\""), std::string::npos) << msg;
}

TEST(Config, MuIFrictionOrderIsChecked) {
  const std::string msg = error_of(edit("name = \"sand\"", "name = \"sand\"\nmodel = \"mu_i\"\nmu_s = 0.5\nmu_2 = 0.4"));
  EXPECT_NE(msg.find("mu_2: must be > mu_s (0.5), got 0.4"), std::string::npos) << msg;
}

TEST(Config, BlockWithUnknownMaterialListsDefinedOnes) {
  const std::string msg = error_of(edit("material = \"sand\"", "material = \"snad\""));
  EXPECT_NE(msg.find("[[block]] #1 material: no material named \"snad\""), std::string::npos) << msg;
  EXPECT_NE(msg.find("did you mean \"sand\"?"), std::string::npos) << msg;
  EXPECT_NE(msg.find("defined materials are: \"sand\""), std::string::npos) << msg;
}

TEST(Config, DuplicateMaterialName) {
  const std::string msg = error_of(kMinimal2D + "[[material]]\nname = \"sand\"\n");
  EXPECT_NE(msg.find("[[material]] #2 (name \"sand\") name"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unique"), std::string::npos) << msg;
}

TEST(Config, PointsPerCellMustBeAPower) {
  const std::string msg = error_of(edit("material = \"sand\"", "material = \"sand\"\npoints_per_cell = 3"));
  EXPECT_NE(msg.find("[[block]] #1 points_per_cell: must be 0 (default) or n^2"), std::string::npos) << msg;
  EXPECT_NE(msg.find("got 3"), std::string::npos) << msg;
  EXPECT_NO_THROW(parse_scene(edit("material = \"sand\"", "material = \"sand\"\npoints_per_cell = 9")));
}

TEST(Config, BlockOutsideDomainGivesBounds) {
  const std::string msg = error_of(edit("upper = [0.3, 0.2]", "upper = [0.3, 0.7]"));
  EXPECT_NE(msg.find("[[block]] #1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("outside the grid domain"), std::string::npos) << msg;
  EXPECT_NE(msg.find("lower = [0, 0], upper = [1, 0.5]"), std::string::npos) << msg;
}

TEST(Config, EndTimeInBothPlacesIsAnError) {
  const std::string msg = error_of("end_time = 1.0\n[time]\nend_time = 2.0\n" + kMinimal2D);
  EXPECT_NE(msg.find("end_time is given twice"), std::string::npos) << msg;
  EXPECT_NE(msg.find("scene.toml:3:"), std::string::npos) << msg;
}

TEST(Config, SyntaxErrorHasLineAndColumn) {
  const std::string msg = error_of("dimension = 2\n[grid]\ncell_size = = 0.1\n");
  EXPECT_NE(msg.find("TOML syntax error at line 3"), std::string::npos) << msg;
  EXPECT_EQ(msg.rfind("scene.toml:3:", 0), 0u) << msg;
}

TEST(Config, FrictionWallsNeedCoefficient) {
  const std::string msg = error_of(edit("cell_size = 0.01", "cell_size = 0.01\nwalls = \"friction\""));
  EXPECT_NE(msg.find("[grid] wall_friction: required key missing"), std::string::npos) << msg;
  // ...and the coefficient is not accepted with other walls.
  const std::string msg2 = error_of(edit("cell_size = 0.01", "cell_size = 0.01\nwall_friction = 0.3"));
  EXPECT_NE(msg2.find("key \"wall_friction\": belongs to walls = \"friction\""), std::string::npos) << msg2;
}

TEST(Config, ZeroPlaneNormalIsAnError) {
  const std::string msg = error_of(kMinimal2D + "[[boundary]]\npoint = [0, 0]\nnormal = [0, 0]\n");
  EXPECT_NE(msg.find("[[boundary]] #1 normal: must be non-zero"), std::string::npos) << msg;
}

TEST(Config, MissingTablesAreReported) {
  EXPECT_NE(error_of("dimension = 2\n").find("[grid] is missing"), std::string::npos);
  const std::string no_block = kMinimal2D.substr(0, kMinimal2D.find("[[block]]"));
  EXPECT_NE(error_of(no_block).find("no [[block]] given"), std::string::npos);
  // [material] with single brackets: explain the double brackets.
  EXPECT_NE(error_of(edit("[[material]]", "[material]")).find("write [[material]] with double brackets"),
            std::string::npos);
}

TEST(Config, TwoDCylinderRejectsThreeDKeys) {
  const std::string msg = error_of(edit("lower = [0.1, 0.0]\nupper = [0.3, 0.2]",
                                        "shape = \"cylinder\"\ncenter = [0.2, 0.1]\nradius = 0.05\naxis = \"y\""));
  EXPECT_NE(msg.find("key \"axis\": only applies in 3D"), std::string::npos) << msg;
}

TEST(Config, MissingFileNamesPath) {
  try {
    mpm::load_scene("/nonexistent/dir/scene.toml");
    FAIL() << "expected a UserError";
  } catch (const mpm::UserError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/scene.toml"), std::string::npos) << e.what();
  }
}

TEST(Config, ReferenceDocumentsTheKeys) {
  const std::string ref = mpm::config_reference();
  for (const char* s : {"[grid]", "[time]", "[output]", "[[material]]", "[[block]]", "[[boundary]]", "cell_size",
                        "wall_friction", "cfl", "progress_interval", "friction_angle", "critical_density",
                        "points_per_cell", "geostatic", "separating", "0.6 * grain_density", "\"drucker_prager\""})
    EXPECT_NE(ref.find(s), std::string::npos) << s;
}

/// The repository root: three levels above this file (mpm_solver/tests/).
std::filesystem::path repo_root() {
  return std::filesystem::path(__FILE__).parent_path().parent_path().parent_path();
}

TEST(Config, DocsMirrorReference) {
  const std::filesystem::path doc = repo_root() / "docs" / "mpm_solver.md";
  std::ifstream in(doc);
  ASSERT_TRUE(in) << doc;
  std::ostringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  const std::string begin = "<!-- BEGIN config_reference -->\n```text\n", end = "```\n<!-- END config_reference -->";
  const auto b = s.find(begin), e = s.find(end);
  ASSERT_NE(b, std::string::npos) << doc;
  ASSERT_NE(e, std::string::npos) << doc;
  EXPECT_EQ(s.substr(b + begin.size(), e - b - begin.size()), mpm::config_reference())
      << doc << " is out of date: replace its config_reference block with the text above (mpm::config_reference())";
}

TEST(Config, ExampleDecksParse) {
  const std::filesystem::path decks = repo_root() / "input_decks" / "mpm";
  ASSERT_TRUE(std::filesystem::is_directory(decks)) << decks;
  int n = 0;
  for (const auto& entry : std::filesystem::directory_iterator(decks)) {
    if (entry.path().extension() != ".toml") continue;
    ++n;
    EXPECT_NO_THROW({
      try {
        const mpm::Scene s = mpm::load_scene(entry.path().string());
        EXPECT_FALSE(s.blocks.empty());
      } catch (const mpm::UserError& e) {
        ADD_FAILURE() << e.what();
        throw;
      }
    }) << entry.path();
  }
  EXPECT_GE(n, 3);
}

}  // namespace

TEST(Config, OutletIsABoxThatMustOverlapTheDomain) {
  const mpm::Scene s = parse_scene(kMinimal2D + "\n[[outlet]]\nlower = [0.4, -0.1]\nupper = [0.6, 0.05]\n", "o.toml");
  ASSERT_EQ(s.outlets.size(), 1u);
  EXPECT_DOUBLE_EQ(s.outlets[0].upper[1], 0.05);
  EXPECT_DOUBLE_EQ(s.output.outflow_interval, 0.005);
  EXPECT_NE(error_of(kMinimal2D + "\n[[outlet]]\nlower = [0.4, -0.3]\nupper = [0.6, -0.1]\n")
                .find("the outlet lies outside the grid domain (axis y)"),
            std::string::npos);
  EXPECT_NE(error_of(kMinimal2D + "\n[[outlet]]\nlower = [0.4, 0.0]\n").find("upper"), std::string::npos);
}
