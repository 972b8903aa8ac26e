// The fix line's options (coupler/fix_options.hpp): defaults, what each keyword sets, and the
// message of every kind of bad line (the fix prints it after "Illegal fix hybrid/mpm command: ").
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

#include "coupler/fix_options.hpp"

namespace {

std::vector<std::string> words(const std::string &line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

bool region_known(const std::string &id) { return id == "core" || id == "outlet"; }

coupler::FixOptions parse(const std::string &line, int dimension = 2, int ntypes = 2) {
  return coupler::parse_fix_options(words(line), dimension, ntypes, region_known);
}

std::string error_of(const std::string &line, int dimension = 2, int ntypes = 2) {
  try {
    parse(line, dimension, ntypes);
  } catch (const coupler::OptionError &e) {
    return e.what();
  }
  return "(no error)";
}

TEST(FixOptions, DefaultsAreTheDocumented) {
  const auto o = parse("cell 0.01");
  EXPECT_DOUBLE_EQ(o.cell, 0.01);
  EXPECT_EQ(o.every, 1);
  EXPECT_EQ(o.hybrid_width, 2);
  EXPECT_EQ(o.adapt_every, 0);
  EXPECT_EQ(o.model, coupler::kModelDruckerPrager);
  EXPECT_EQ(o.template_seed, 12345);
  EXPECT_DOUBLE_EQ(o.reply_timeout, 30.0);
  EXPECT_DOUBLE_EQ(o.idle_timeout, 600.0);
  EXPECT_DOUBLE_EQ(o.inertia, 0.5);    // disks
  EXPECT_DOUBLE_EQ(parse("cell 0.01", 3).inertia, 0.4);
  EXPECT_DOUBLE_EQ(o.continuum.grain_weight, 0.5);
  EXPECT_DOUBLE_EQ(o.continuum.pic, 1.0);
  EXPECT_EQ(o.continuum.wall_contact, coupler::kWallSlip);
  EXPECT_EQ(o.rezone_log, coupler::RezoneLog::kSummary);
  EXPECT_FALSE(o.material);
  EXPECT_FALSE(o.splits());
  const double lo[3] = {0, 0, 0}, hi[3] = {1, 2, 3};
  EXPECT_DOUBLE_EQ(o.container_edge(1, 1, lo, hi), 2.0);
}

TEST(FixOptions, KeywordsSetTheirValues) {
  const auto o = parse("cell 0.005 continuum core continuum outlet hybrid_width 1 weight 0.3 model mu_i every 10 "
                       "wall friction 0.5 container 0 INF 0.1 INF output frames 20 inertia 0.25 rezone_log quiet "
                       "points_per_cell 3 timeout 5 idle 0 mpm_state s.h5 seed 7 grain_type 2 relax 0");
  EXPECT_EQ(o.continuum_regions, (std::vector<std::string>{"core", "outlet"}));
  EXPECT_TRUE(o.splits());
  EXPECT_EQ(o.hybrid_width, 1);
  EXPECT_DOUBLE_EQ(o.continuum.grain_weight, 0.3);
  EXPECT_EQ(o.model, coupler::kModelMuI);
  EXPECT_EQ(o.every, 10);
  EXPECT_EQ(o.continuum.wall_contact, coupler::kWallFriction);
  EXPECT_DOUBLE_EQ(o.continuum.wall_friction, 0.5);
  const double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
  EXPECT_DOUBLE_EQ(o.container_edge(0, 0, lo, hi), 0.0);
  EXPECT_DOUBLE_EQ(o.container_edge(0, 1, lo, hi), 1.0);    // INF: the box face
  EXPECT_DOUBLE_EQ(o.container_edge(1, 0, lo, hi), 0.1);
  EXPECT_EQ(o.output_path, "frames");
  EXPECT_EQ(coupler::get_text(o.continuum.output_path), "frames");
  EXPECT_EQ(o.continuum.output_every, 20);
  EXPECT_DOUBLE_EQ(o.inertia, 0.25);
  EXPECT_EQ(o.rezone_log, coupler::RezoneLog::kQuiet);
  EXPECT_EQ(o.continuum.points_per_axis, 3);
  EXPECT_DOUBLE_EQ(o.idle_timeout, 0.0);
  EXPECT_EQ(o.mpm_state_path, "s.h5");
  EXPECT_EQ(o.grain_type, 2);
  EXPECT_DOUBLE_EQ(o.relax_time, 0.0);
  EXPECT_DOUBLE_EQ(o.continuum.fill_share, 0.0);    // the fill pressure is off unless asked for
  EXPECT_DOUBLE_EQ(o.continuum.packing_fraction, 0.82);    // 2D without a material: grid_packing's
  EXPECT_DOUBLE_EQ(parse("cell 0.01", 3).continuum.packing_fraction, 0.60);
  EXPECT_DOUBLE_EQ(parse("cell 0.01 fill 0.1").continuum.fill_share, 0.1);
}

TEST(FixOptions, FillPressureNeedsAShareOfTheModulusAndAStableStep) {
  EXPECT_EQ(error_of("cell 0.01 fill 1.5"),
            "keyword 'fill' (auto: the fill pressure's modulus from the calibration, or a share of the continuum's bulk "
            "modulus; 0 = none) must be auto or in [0, 1], not 1.5");
  EXPECT_EQ(error_of("cell 0.01 fill auto").rfind("keyword 'fill auto' needs 'material'", 0), 0u);
  const auto o = parse("cell 0.01 fill 0.2 fill auto material disks_2d");
  EXPECT_TRUE(o.fill_auto);
  EXPECT_EQ(o.continuum.fill_share, 0.0);    // the last fill keyword is the one
  EXPECT_DOUBLE_EQ(o.continuum.packing_fraction, o.material->packing_fraction);
  EXPECT_EQ(error_of("cell 0.01 fill -0.1").rfind("keyword 'fill' ", 0), 0u);
  EXPECT_EQ(error_of("cell 0.01 fill 1 cfl 0.7"), "(no error)");
  EXPECT_EQ(error_of("cell 0.01 fill 1 cfl 0.8"),
            "keywords 'cfl' 0.8 and 'fill' 1: the fill pressure raises the continuum's wave speed by up to "
            "sqrt(1 + fill), so cfl must be at most 0.7071067811865475 with it; lower cfl or fill");
  EXPECT_EQ(error_of("cell 0.01 cfl 1"), "(no error)");    // without it, the cfl may be 1
}

TEST(FixOptions, AdaptiveZonesSetTheOracleAndPicDefaults) {
  auto o = parse("cell 0.01 adaptive 100 every 10 touch xlo touch ylo");
  EXPECT_TRUE(o.adaptive() && o.splits());
  EXPECT_DOUBLE_EQ(o.oracle.band, 0.01);
  EXPECT_DOUBLE_EQ(o.oracle.continuum_depth, 0.03);
  EXPECT_DOUBLE_EQ(o.oracle.free_surface_depth(), 0.03);    // no surface_depth: the depth
  EXPECT_DOUBLE_EQ(parse("cell 0.01 adaptive 100 surface_depth 0.02").oracle.free_surface_depth(), 0.02);
  EXPECT_DOUBLE_EQ(parse("cell 0.01 adaptive 100 surface_depth 0.02").oracle.continuum_depth, 0.03);
  EXPECT_EQ(o.continuum.pic, coupler::kPicRegime);    // each node's rule from the flow there
  EXPECT_EQ(o.continuum.touched_faces, coupler::face_bit(0, 0) | coupler::face_bit(1, 0));
  EXPECT_DOUBLE_EQ(parse("cell 0.01 adaptive 100 every 10 pic 0.5").continuum.pic, 0.5);
  EXPECT_EQ(parse("cell 0.01 adaptive 100 pic regime").continuum.pic, coupler::kPicRegime);
  EXPECT_THROW(parse("cell 0.01 pic regimes"), coupler::OptionError);
  EXPECT_EQ(parse("cell 0.01 adaptive 100 rest_hold no").oracle.rest_hold, 0.0);
  EXPECT_THROW(parse("cell 0.01 adaptive 100 rest_hold off"), coupler::OptionError);
  EXPECT_EQ(parse("cell 0.01 adaptive 10 touch all", 3).continuum.touched_faces, 63u);
  // fix_modify's oracle keywords: false for others, the same checks
  EXPECT_TRUE(coupler::set_oracle_option(o.oracle, "depth", "0.05"));
  EXPECT_DOUBLE_EQ(o.oracle.continuum_depth, 0.05);
  EXPECT_TRUE(coupler::set_oracle_option(o.oracle, "surface_depth", "0.025"));
  EXPECT_DOUBLE_EQ(o.oracle.free_surface_depth(), 0.025);
  EXPECT_FALSE(coupler::set_oracle_option(o.oracle, "every", "5"));
  EXPECT_EQ(o.oracle.rest_hold, 1.0);    // on by default
  EXPECT_TRUE(coupler::set_oracle_option(o.oracle, "rest_hold", "no"));
  EXPECT_EQ(o.oracle.rest_hold, 0.0);
  EXPECT_TRUE(coupler::set_oracle_option(o.oracle, "rest_hold", "yes"));
  EXPECT_EQ(o.oracle.rest_hold, 1.0);
  EXPECT_THROW(coupler::set_oracle_option(o.oracle, "rest_hold", "1"), coupler::OptionError);
  EXPECT_THROW(coupler::set_oracle_option(o.oracle, "surface_packing", "1"), coupler::OptionError);
  o.oracle.band = 0.001;
  EXPECT_THROW(coupler::check_oracle_options(o, 2), coupler::OptionError);
  // fix_modify's pic (the DEM side's grain update), with the fix line's check
  auto m = parse("cell 0.01 adaptive 100 every 10");
  EXPECT_TRUE(coupler::modify_option(m, "pic", "1", 2));
  EXPECT_DOUBLE_EQ(m.continuum.pic, 1.0);
  EXPECT_THROW(coupler::modify_option(m, "pic", "1.5", 2), coupler::OptionError);
  EXPECT_DOUBLE_EQ(m.continuum.pic, 1.0);
  EXPECT_TRUE(coupler::modify_option(m, "pic", "regime", 2));
  EXPECT_EQ(m.continuum.pic, coupler::kPicRegime);
  EXPECT_FALSE(coupler::modify_option(m, "every", "5", 2));
}

TEST(FixOptions, BadLinesNameTheKeyword) {
  // the messages tests/test_coupled_launch.py expects from LAMMPS, and others
  EXPECT_EQ(error_of("cell 0.01 bogus 3").rfind("unknown keyword 'bogus' (known keywords: cell, continuum, ", 0), 0u);
  EXPECT_EQ(error_of("cell -0.01"), "keyword 'cell' must be > 0 (the MPM grid cell size), not -0.01");
  EXPECT_EQ(error_of("model drucker_prager"), "(no error)");    // the cell then comes from the grains
  EXPECT_EQ(error_of("cell 0.01 model granite"), "keyword 'model' must be drucker_prager or mu_i, not 'granite'");
  EXPECT_EQ(error_of("cell 0.01 timeout"), "keyword 'timeout' needs a value");
  EXPECT_EQ(error_of("cell 0.01 every 0"), "keyword 'every' needs a positive integer, not '0'");
  EXPECT_EQ(error_of("cell 0.01 every 2.5"), "keyword 'every' needs a positive integer, not '2.5'");
  EXPECT_EQ(error_of("cell 0.01 every automatic"), "keyword 'every' needs a positive integer, not 'automatic'");
  EXPECT_EQ(error_of("cell 0.01 adaptive 100 every 30"),
            "keyword 'adaptive' (100 steps) must be a multiple of 'every' (30): zones change right after an exchange");
  EXPECT_EQ(error_of("cell 0.01 adaptive 100 every auto"), "(no error)");    // rounded when every is known
  EXPECT_EQ(error_of("cell abc"), "keyword 'cell' needs a number, not 'abc'");
  EXPECT_EQ(error_of("cell 0.01 continuum nowhere"),
            "continuum region 'nowhere' does not exist (define it with the region command first)");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 discrete nowhere"),
            "discrete region 'nowhere' does not exist (define it with the region command first)");
  EXPECT_EQ(error_of("cell 0.01 discrete core").rfind("keyword 'discrete' needs adaptive zones (keyword 'adaptive')", 0),
            0u);
  EXPECT_EQ(error_of("cell 0.01 weight 1.5"),
            "keyword 'weight' (the share of a hybrid cell's mass its grains keep) must be between 0 and 1, not 1.5");
  EXPECT_EQ(error_of("cell 0.01 wall friction"), "keyword 'wall friction' needs the friction coefficient");
  EXPECT_EQ(error_of("cell 0.01 wall friction -1"), "keyword 'wall friction' needs a coefficient >= 0");
  EXPECT_EQ(error_of("cell 0.01 container 0 INF"), "keyword 'container' needs 4 values (xlo xhi ylo yhi; INF = the box face)");
  EXPECT_EQ(error_of("cell 0.01 container 0 INF", 3),
            "keyword 'container' needs 6 values (xlo xhi ylo yhi zlo zhi; INF = the box face)");
  EXPECT_EQ(error_of("cell 0.01 steps_per_contact 1.5"),
            "keyword 'steps_per_contact' (warn below this many DEM steps per contact) must exceed pi/2, where "
            "velocity Verlet goes unstable, not 1.5");
  EXPECT_EQ(error_of("cell 0.01 material no_such_material.toml").rfind(
                "keyword 'material': material file no_such_material.toml not found", 0),
            0u);
  EXPECT_EQ(error_of("cell 0.01 material disks_2d", 3), "keyword 'material': disks_2d was calibrated in 2D, this run is 3D");
  EXPECT_EQ(error_of("cell 0.01 material disks_2d friction 30"),
            "keyword 'friction' conflicts with 'material', which sets the continuum's constants from the "
            "calibration; leave one out");
  EXPECT_EQ(error_of("cell 0.01 energy_guard -0.1"),
            "keyword 'energy_guard' (the energy the coupling may make, as a share of the scene's energy scale; 0 = "
            "unguarded) must be >= 0, not -0.1");
  EXPECT_DOUBLE_EQ(parse("cell 0.01").energy_guard, coupler::kEnergyGuard);
  EXPECT_DOUBLE_EQ(parse("cell 0.01 energy_guard 0").energy_guard, 0.0);
  EXPECT_EQ(error_of("cell 0.01 relax -1"), "keyword 'relax' (relaxation time of the velocity agreement, s; 0 = close "
                                            "the gap at every exchange) must be >= 0, not -1");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 touch floor"),
            "keyword 'touch' needs a container face (xlo, xhi, ylo, yhi or all), not 'floor'");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 touch floor", 3),
            "keyword 'touch' needs a container face (xlo, xhi, ylo, yhi, zlo, zhi or all), not 'floor'");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 touch ylo touch zlo"),
            "keyword 'touch' face 'zlo' needs a 3D box (a 2D box has no z faces)");
  EXPECT_EQ(error_of("cell 0.01 touch ylo").rfind("keyword 'touch' needs adaptive zones (keyword 'adaptive')", 0), 0u);
  EXPECT_EQ(error_of("cell 0.01 rezone_log verbose"), "keyword 'rezone_log' must be full, summary or quiet, not 'verbose'");
  EXPECT_EQ(error_of("cell 0.01 adaptive 15 every 10"),
            "keyword 'adaptive' (15 steps) must be a multiple of 'every' (10): zones change right after an exchange");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 band 0.005"),
            "keyword 'band' (0.005) must exceed 0.007071 (sqrt(2)/2 cells), or continuum cells may border discrete ones");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 depth 0.01 band 0.01"),
            "keyword 'depth' (0.01) must exceed 'band' (0.01): the cells at the free surface must stay discrete");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 surface_depth 0.01"),
            "keyword 'surface_depth' (0.01) must exceed 'band' (0.01): the cells at the free surface must stay discrete");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 surface_depth -1"),
            "keyword 'surface_depth' (continuum deeper than surface_depth + band below a free surface, m) must be in "
            "(0, inf), not -1");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 dilute 1.5"),
            "keyword 'dilute' (a packing fraction) must be in (0, 1), not 1.5");
  EXPECT_EQ(error_of("cell 0.01 adaptive 10 shear_rate 0"),
            "keyword 'shear_rate' (cells shearing faster are discrete, 1/s) must be in (0, inf), not 0");
  EXPECT_EQ(error_of("cell 0.01 grain_type 3"), "keyword 'grain_type' 3 is not an atom type (1 to 2)");
  EXPECT_EQ(error_of("cell 0.01 idle -1"), "keyword 'idle' must be >= 0 seconds (0 = wait forever), not -1");
  EXPECT_EQ(error_of("cell 0.01 points_per_cell 5"), "keyword 'points_per_cell' (points per cell and axis) must be 1 to 4");
  // the first problem on the line wins
  EXPECT_EQ(error_of("bogus 1"), error_of("cell 0.01 bogus 1"));
}

}    // namespace

namespace {

std::string resolve_error(coupler::FixOptions o, int dimension, double diameter) {
  try {
    coupler::resolve_grid(o, dimension, diameter);
  } catch (const coupler::OptionError &e) {
    return e.what();
  }
  return "(no error)";
}

}    // namespace

TEST(FixOptions, GrainsChooseCellsOfAtLeastEightGrainsPerPoint) {
  // 2D: disks at 0.82, 4 points per cell: cell^2 >= 8 * 4 * (pi/4) / 0.82 = 30.6 d^2, 6 d in half diameters
  auto g = coupler::grid_from_grains(2, 0.002, 0.82, 2);
  EXPECT_DOUBLE_EQ(g.cell, 0.012);
  EXPECT_EQ(g.points_per_axis, 2);
  EXPECT_NEAR(g.grains_per_point, 0.82 * 36.0 / (3.14159265358979 / 4.0 * 4.0), 1e-12);
  EXPECT_GE(g.grains_per_point, 8.0);
  // 3D: spheres at 0.60, 8 points per cell: cell^3 >= 55.9 d^3, 4 d
  g = coupler::grid_from_grains(3, 0.001, 0.60, 2);
  EXPECT_DOUBLE_EQ(g.cell, 0.004);
  EXPECT_NEAR(g.grains_per_point, 0.60 * 64.0 / (3.14159265358979 / 6.0 * 8.0), 1e-12);
  // one point per cell and axis: 3 d in 2D; in 3D the 2 d floor of adaptive zones (9.2 grains)
  EXPECT_DOUBLE_EQ(coupler::grid_from_grains(2, 1.0, 0.82, 1).cell, 3.0);
  EXPECT_DOUBLE_EQ(coupler::grid_from_grains(3, 1.0, 0.60, 1).cell, 2.0);
  // every choice carries at least the target, and half a diameter less would not
  for (int dim : {2, 3})
    for (int ppa : {1, 2, 3, 4})
      for (double packing : {0.55, 0.64, 0.82, 0.9}) {
        const auto c = coupler::grid_from_grains(dim, 1.0, packing, ppa);
        EXPECT_GE(c.grains_per_point, 8.0 - 1e-9);
        if (c.cell > 2.0)
          EXPECT_LT(coupler::grid_from_grains(dim, 1.0, packing, ppa).grains_per_point *
                        std::pow((c.cell - 0.5) / c.cell, dim), 8.0);
      }
}

TEST(FixOptions, ResolveGridFillsTheCellAndTheOracleDefaults) {
  auto o = parse("adaptive 100 every 10");
  EXPECT_LE(o.cell, 0.0);
  EXPECT_LE(o.oracle.band, 0.0);    // waits for the cell
  const std::string line = coupler::resolve_grid(o, 2, 0.002);
  EXPECT_DOUBLE_EQ(o.cell, 0.012);
  EXPECT_EQ(o.continuum.points_per_axis, 2);
  EXPECT_DOUBLE_EQ(o.oracle.band, 0.012);
  EXPECT_DOUBLE_EQ(o.oracle.continuum_depth, 0.036);
  EXPECT_NE(line.find("cell 0.012 = 6 mean grain diameters (chosen from the grains), 2^2 points per cell: "
                      "a point made from grains carries 9.4 grains at packing 0.82"), std::string::npos) << line;
  // points per cell given: the cell follows them
  o = parse("adaptive 100 every 10 points_per_cell 1");
  coupler::resolve_grid(o, 2, 0.002);
  EXPECT_DOUBLE_EQ(o.cell, 0.006);
  EXPECT_EQ(o.continuum.points_per_axis, 1);
  // a cell on the line (or restored from a restart file) is kept, and so are the 2 points
  o = parse("cell 0.005 adaptive 100 every 10");
  EXPECT_NE(coupler::resolve_grid(o, 2, 0.002).find("cell 0.005 = 2.5 mean grain diameters, 2^2 points per cell: "
                                                     "a point made from grains carries 1.63 grains"),
            std::string::npos);
  EXPECT_DOUBLE_EQ(o.cell, 0.005);
  // a band given on the line is checked against the chosen cell
  EXPECT_EQ(resolve_error(parse("adaptive 100 every 10 band 0.004"), 2, 0.002),
            "keyword 'band' (0.004) must exceed 0.008485 (sqrt(2)/2 cells), or continuum cells may border discrete "
            "ones");
  // no grains and no cell: nothing to choose from
  EXPECT_EQ(resolve_error(parse("adaptive 100 every 10"), 2, 0.0),
            "keyword 'cell' is needed: the group has no grains to choose the MPM grid cell from");
  EXPECT_EQ(resolve_error(parse("cell 0.01"), 3, 0.0), "(no error)");
}

// `every auto`: the exchange interval is the continuum's stable substep in DEM steps, so the MPM
// process takes one full substep per exchange (the 80k-disk silo: 46 steps; every 10 made it take
// four short ones and ran 8.9x faster than pure LAMMPS instead of 11.6x every 40). Figures of that
// silo: kn = 1.1772e7 N/m, E = 0.2848 kn, nu = 0.3283, cells of 0.01186 m, dt = 2.632e-6 s.
TEST(FixOptions, EveryAutoIsTheContinuumsStableSubstepInDemSteps) {
  auto o = parse("cell 0.01186 adaptive 100 every auto youngs 3.3527e6 poisson 0.3283 grain_density 2500 "
                 "critical_packing 0.7118");
  ASSERT_TRUE(o.every_auto);
  const double dt = 2.632e-6;
  const double modulus = 3.3527e6 * (1 - 0.3283) / ((1 + 0.3283) * (1 - 2 * 0.3283));    // lambda + 2G
  const double substep = 0.5 * 0.01186 / std::sqrt(modulus / (0.7118 * 2500));
  const std::string line = coupler::resolve_exchange_interval(o, dt);
  EXPECT_EQ(o.every, static_cast<int>(std::floor(substep / dt)));
  EXPECT_GT(o.every, 30);
  EXPECT_LT(o.every, 50);
  // the oracle's 100 steps become the next multiple of the interval: it runs right after an exchange
  EXPECT_EQ(o.adapt_every % o.every, 0);
  EXPECT_GE(o.adapt_every, 100);
  EXPECT_LT(o.adapt_every, 100 + o.every);
  EXPECT_NE(line.find("exchange every " + std::to_string(o.every) + " step(s) (every auto"), std::string::npos) << line;
  EXPECT_NE(line.find("rounded up"), std::string::npos) << line;
  // a DEM step longer than the continuum's substep: every step
  o = parse("cell 0.01186 every auto youngs 3.3527e6 poisson 0.3283");
  coupler::resolve_exchange_interval(o, 10 * substep);
  EXPECT_EQ(o.every, 1);
  // stiffer continuum, shorter substep, fewer DEM steps per exchange
  auto stiff = parse("cell 0.01186 every auto youngs 3.3527e8 poisson 0.3283 grain_density 2500 critical_packing 0.7118");
  coupler::resolve_exchange_interval(stiff, dt);
  EXPECT_EQ(stiff.every, static_cast<int>(std::floor(substep / 10 / dt)));
}

// Moving zones exchange once per continuum substep unless the fix line says otherwise; fixed zones
// keep every step (their rows were measured so), and an explicit interval is kept and checked.
TEST(FixOptions, AdaptiveZonesExchangeEveryContinuumSubstepByDefault) {
  auto o = parse("cell 0.01186 adaptive 100");
  EXPECT_TRUE(o.every_auto);
  o = parse("cell 0.01186 adaptive 100 every 10");
  EXPECT_FALSE(o.every_auto);
  EXPECT_EQ(o.every, 10);
  o = parse("cell 0.01186 continuum core");
  EXPECT_FALSE(o.every_auto);
  EXPECT_EQ(o.every, 1);
  // the default interval is resolved at the first run and rounds the oracle's steps up to a multiple
  o = parse("cell 0.01186 adaptive 100 youngs 3.3527e6 poisson 0.3283 grain_density 2500 critical_packing 0.7118");
  coupler::resolve_exchange_interval(o, 2.632e-6);
  EXPECT_GT(o.every, 30);
  EXPECT_EQ(o.adapt_every % o.every, 0);
}

// The zone oracle runs after the exchanges of its steps once grains became points, never after the
// run's last step (both hosts ask FixOptions::oracle_after)
TEST(FixOptions, OracleRunsAfterItsExchangesButNotAtTheEndOfARun) {
  const coupler::FixOptions adaptive = parse("cell 0.01 adaptive 100 every 10");
  EXPECT_TRUE(adaptive.oracle_after(200, 1000, true));
  EXPECT_FALSE(adaptive.oracle_after(210, 1000, true));     // not an oracle step
  EXPECT_FALSE(adaptive.oracle_after(200, 1000, false));    // before the conversion
  EXPECT_FALSE(adaptive.oracle_after(1000, 1000, true));    // the run's last step
  EXPECT_FALSE(parse("cell 0.01 every 10").oracle_after(200, 1000, true));    // fixed zones
}
