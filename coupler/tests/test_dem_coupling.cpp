// The pieces of the DEM side's coupled steps that the LAMMPS and LIGGGHTS fixes share
// (coupler/dem_coupling.hpp, coupler/dem_grains.hpp): per-atom arrays, deletions, the
// group's defaults over the ranks, zone counts, the handshake's container check, the
// rezone's totals and atom-count limits. Runs in coupler_mpi_tests on 2 ranks.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "coupler/dem_coupling.hpp"
#include "coupler/fix_options.hpp"
#include "coupler/tuning.hpp"

namespace {

int ranks() {
  int n = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

// n atoms' arrays, as a host keeps them (double**)
struct Atoms {
  std::vector<double> weight, support_data, stress_data, x_data, v_data, omega_data, radius, rmass;
  std::vector<double *> support, stress, x, v, omega;
  std::vector<int> mask, type;
  explicit Atoms(int n)
      : weight(n, 1.0), support_data(3 * n, 0.0), stress_data(6 * n, 0.0), x_data(3 * n, 0.0), v_data(3 * n, 0.0),
        omega_data(3 * n, 0.0), radius(n, 0.001), rmass(n, 1.0), mask(n, 1 | 2), type(n, 1) {
    for (int i = 0; i < n; i++) {
      support.push_back(&support_data[3 * i]), stress.push_back(&stress_data[6 * i]);
      x.push_back(&x_data[3 * i]), v.push_back(&v_data[3 * i]), omega.push_back(&omega_data[3 * i]);
    }
  }
  coupler::GrainArrays arrays() {
    coupler::GrainArrays a;
    a.weight = weight.data(), a.support = support.data(), a.stress = stress.data();
    return a;
  }
  coupler::DemGrains grains(int n) {
    return coupler::grain_view(n, x.data(), v.data(), omega.data(), radius.data(), rmass.data(), mask.data(), 2,
                               arrays());
  }
};

TEST(DemCoupling, GrainArraysTravelWhole) {
  Atoms a(2);
  a.weight[0] = 0.25;
  for (int k = 0; k < 3; k++) a.support[0][k] = k + 1.0;
  for (int k = 0; k < 6; k++) a.stress[0][k] = 10.0 + k;
  double buf[coupler::GrainArrays::kValues];
  ASSERT_EQ(a.arrays().pack(0, buf), coupler::GrainArrays::kValues);
  ASSERT_EQ(a.arrays().unpack(1, buf), coupler::GrainArrays::kValues);
  EXPECT_EQ(a.weight[1], 0.25);
  EXPECT_EQ(a.support[1][2], 3.0);
  EXPECT_EQ(a.stress[1][5], 15.0);
  a.arrays().reset(0);
  EXPECT_EQ(a.weight[0], 1.0);
  EXPECT_EQ(a.support[0][0], 0.0);
  EXPECT_EQ(a.stress[0][3], 0.0);
  EXPECT_EQ(coupler::supported_grains(a.support.data(), 2), std::vector<int>{1});
}

TEST(DemCoupling, DeletionMovesTheLastAtomsIntoTheGaps) {
  // atoms 0..5 hold their own index; delete 1 and 4
  std::vector<int> id = {0, 1, 2, 3, 4, 5};
  const std::vector<char> flags = {0, 1, 0, 0, 1, 0};
  const int n = coupler::delete_flagged(flags, 6, [&](int from, int to) { id[to] = id[from]; });
  ASSERT_EQ(n, 4);
  EXPECT_EQ(std::vector<int>(id.begin(), id.begin() + n), (std::vector<int>{0, 5, 2, 3}));
}

TEST(DemCoupling, GroupDefaultsOverTheRanks) {
  // every rank: two grains of the group (diameters 2 and 4 mm), one atom outside it
  Atoms a(3);
  a.radius = {0.001, 0.002, 0.005};
  a.type = {3, 2, 1};
  a.mask = {1 | 2 | 8, 1 | 2, 1};
  a.weight = {1.0, 0.5, 1.0};
  const double pi = 3.14159265358979323846, rho = 2500.0;
  for (int i = 0; i < 3; i++) a.rmass[i] = a.weight[i] * rho * 4.0 / 3.0 * pi * a.radius[i] * a.radius[i] * a.radius[i];
  const coupler::GroupGrains gg = coupler::group_grains(a.grains(3), a.type.data(), 3, 3, MPI_COMM_WORLD);
  EXPECT_EQ(gg.count, 2 * ranks());
  EXPECT_DOUBLE_EQ(gg.dmin, 0.002);
  EXPECT_DOUBLE_EQ(gg.dmax, 0.004);
  EXPECT_EQ(gg.smallest_type, 2);
  coupler::FixOptions opt;
  double polydispersity = 0.0;
  const int mask = coupler::apply_group_defaults(opt, gg, 2, polydispersity);
  EXPECT_EQ(mask, 1 | 2);    // bit 8 is not on every grain
  EXPECT_DOUBLE_EQ(opt.continuum.grain_diameter, 0.003);
  EXPECT_NEAR(opt.continuum.grain_density, rho, 1e-9 * rho);    // solid mass: rmass / weight
  EXPECT_EQ(opt.grain_type, 2);
  EXPECT_DOUBLE_EQ(polydispersity, 1.0 / 3.0);
}

TEST(DemCoupling, GrainsAndPointsConvertAtOneSolidDensity) {
  // 2D disks of radii 1 and 1.5 mm on every rank; rank 1 (if any) holds the heavier one
  const double pi = 3.14159265358979323846, rho = 2500.0;
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  Atoms a(2);
  a.radius = {0.001, 0.0015};
  auto disks = [&](double per_area) {
    for (int i = 0; i < 2; i++) a.rmass[i] = a.weight[i] * per_area * pi * a.radius[i] * a.radius[i];
  };
  auto problem = [&](const coupler::FixOptions &given) {
    coupler::FixOptions opt = given;
    double polydispersity = 0.0;
    const coupler::GroupGrains gg = coupler::group_grains(a.grains(2), a.type.data(), 1, 2, MPI_COMM_WORLD);
    coupler::apply_group_defaults(opt, gg, 2, polydispersity);
    return coupler::density_problem(opt, gg, 2);
  };
  coupler::FixOptions defaults, given;
  given.density_given = true;
  disks(rho);
  EXPECT_EQ(problem(defaults), "");
  given.continuum.grain_density = 1.005 * rho;    // within the light-grain rule's 1 %
  EXPECT_EQ(problem(given), "");
  given.continuum.grain_density = 1.02 * rho;
  EXPECT_NE(problem(given).find("grain_density 2550 is not the group's grains' own solid density 2500"),
            std::string::npos) << problem(given);
  // a 2D deck's `set density`: disks get a sphere's mass, so their density per area grows with r
  for (int i = 0; i < 2; i++) a.rmass[i] = rho * 4.0 / 3.0 * pi * std::pow(a.radius[i], 3);
  EXPECT_NE(problem(defaults).find("set density/disc"), std::string::npos) << problem(defaults);
  // two densities on two ranks: the spread is over all ranks
  disks(rank == 1 ? 1.1 * rho : rho);
  EXPECT_EQ(problem(defaults).empty(), ranks() == 1) << problem(defaults);
  // once grains carry shares (a coupled state, e.g. after a restart), masses are the coupling's
  a.weight[0] = 0.5;
  for (int i = 0; i < 2; i++) a.rmass[i] = rho * 4.0 / 3.0 * pi * std::pow(a.radius[i], 3);
  EXPECT_EQ(problem(given), "");
}

TEST(DemCoupling, ZoneCountsAndEmptyRegions) {
  const double lo[3] = {0, 0, 0}, hi[3] = {0.1, 0.1, 0.1};
  const auto grid = coupler::padded_grid<3>(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.1, 0.1, 0.1), 0.01);
  std::vector<signed char> zones(coupler::num_cells<3>(grid), coupler::kDiscrete);
  std::int64_t n[3];
  coupler::zone_counts<3>(grid, zones, lo, hi, n);
  EXPECT_EQ(n[coupler::kDiscrete], 11 * 11 * 11);    // the padded grid's cells overlapping the box
  EXPECT_EQ(n[coupler::kContinuum] + n[coupler::kHybrid], 0);
  // region 0: a cube around the box centre (holds cell centres); region 1: smaller than a cell
  // and between cell centres (holds none)
  auto match = [](int k, const double *x) {
    const double h = k == 0 ? 0.02 : 0.002, c = k == 0 ? 0.05 : 0.05;
    return std::abs(x[0] - c) < h && std::abs(x[1] - c) < h && std::abs(x[2] - c) < h;
  };
  EXPECT_EQ(coupler::first_empty_region<3>(grid, lo, hi, 1, match), -1);
  EXPECT_EQ(coupler::first_empty_region<3>(grid, lo, hi, 2, match), 1);
}

TEST(DemCoupling, DiscreteRegionsKeepEveryCellTheyTouch) {
  // A 3D silo's outlet: a vertical cylinder of radius 0.3 cells about an axis on a node line
  // (x = z = 0.05), up to 0.02 above the floor. It holds no cell centre (they lie 0.71 cells from
  // the axis); the four columns of cells around the axis touch it, up to the cell holding y = 0.02.
  const double lo[3] = {0, 0, 0}, hi[3] = {0.1, 0.1, 0.1}, dx = 0.01;
  const auto grid = coupler::padded_grid<3>(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.1, 0.1, 0.1), dx);
  auto cylinder = [](double radius) {
    coupler::RegionShape r;
    r.inside = [radius](const double *x) {
      return std::hypot(x[0] - 0.05, x[2] - 0.05) < radius && x[1] > -0.005 && x[1] < 0.02;
    };
    return r;
  };
  const coupler::RegionShape outlet = cylinder(0.3 * dx);
  std::vector<std::uint64_t> expected;
  for (std::size_t c = 0; c < coupler::num_cells<3>(grid); ++c) {
    const auto x = coupler::cell_center<3>(grid, coupler::cell_coords<3>(grid, c));
    EXPECT_FALSE(outlet.inside(x.data())) << "no cell centre lies in the outlet";
    if (std::abs(x[0] - 0.05) < dx && std::abs(x[2] - 0.05) < dx && x[1] > -dx && x[1] < 0.02 + 0.5 * dx)
      expected.push_back(c);
  }
  EXPECT_EQ(expected.size(), 4u * 3u);    // the columns' cells from the floor's down to y = 0.02
  EXPECT_EQ(coupler::cells_touched<3>(grid, {outlet}), expected);
  coupler::RegionShape bounded = outlet;    // a fixed region's bounding box only saves work
  bounded.bounded = true;
  const double blo[3] = {0.05 - 0.3 * dx, -0.005, 0.05 - 0.3 * dx}, bhi[3] = {0.05 + 0.3 * dx, 0.02, 0.05 + 0.3 * dx};
  std::copy(blo, blo + 3, bounded.lo), std::copy(bhi, bhi + 3, bounded.hi);
  EXPECT_EQ(coupler::cells_touched<3>(grid, {bounded}), expected);
  // a region between the samples of every cell touches none: refused at the start
  EXPECT_EQ(coupler::first_untouching_region<3>(grid, lo, hi, {outlet}), -1);
  EXPECT_EQ(coupler::first_untouching_region<3>(grid, lo, hi, {outlet, cylinder(0.1 * dx)}), 1);
  EXPECT_TRUE(coupler::cells_touched<3>(grid, {cylinder(0.1 * dx)}).empty());
}

TEST(DemCoupling, HelloRefusesAContainerOutsideTheBox) {
  coupler::FixOptions opt;
  opt.cell = 0.01;
  const double lo[3] = {0, 0, 0}, hi[3] = {0.1, 0.1, 0.1};
  std::string problem;
  coupler::Hello h = coupler::make_hello(opt, "LIGGGHTS 3.8.0", "si", 3, 1e-5, lo, hi, 7, 7e-5, problem);
  EXPECT_EQ(problem, "");
  EXPECT_EQ(h.continuum.container_hi[2], 0.1);
  EXPECT_EQ(h.step, 7);
  EXPECT_STREQ(h.host, "LIGGGHTS 3.8.0");
  opt.container_given[3] = true, opt.container_value[3] = 0.2;    // yhi
  coupler::make_hello(opt, "LIGGGHTS 3.8.0", "si", 3, 1e-5, lo, hi, 7, 7e-5, problem);
  EXPECT_EQ(problem, "container y hi = 0.2 lies outside the box (0 to 0.1)");
}

TEST(DemCoupling, RezoneTotalsAndAtomLimits) {
  coupler::StepAck ack;
  ack.mass = 2.0, ack.momentum[1] = 3.0, ack.angular[2] = 4.0;
  for (int k = 0; k < 7; k++) ack.before[k] = 0.5;
  const double gb[7] = {1, 1, 1, 1, 1, 1, 1}, ga[7] = {0, 0, 0, 0, 0, 0, 0};
  double before[7], after[7];
  coupler::rezone_totals(gb, ga, ack, before, after);
  EXPECT_EQ(before[0], 1.5);
  EXPECT_EQ(after[0], 2.0);
  EXPECT_EQ(after[2], 3.0);
  EXPECT_EQ(after[6], 4.0);
  EXPECT_EQ(coupler::new_atoms_problem(10, 0, 100, 1000, 50, 1000, 3, "LIGGGHTS", "hint"), "");
  EXPECT_NE(coupler::new_atoms_problem(10, 0, 995, 1000, 50, 1000, 3, "LIGGGHTS", "hint").find("too many total atoms"),
            std::string::npos);
  EXPECT_NE(coupler::new_atoms_problem(10, 0, 100, 1000, 995, 1000, 3, "LIGGGHTS", "hint").find("IDs"),
            std::string::npos);
  EXPECT_TRUE(coupler::output_frame_due(5, 10, false));
  EXPECT_FALSE(coupler::output_frame_due(5, 11, false));
  EXPECT_TRUE(coupler::output_frame_due(5, 11, true));
  EXPECT_FALSE(coupler::output_frame_due(0, 0, true));
  // a run of steps 0-67 exchanging every 10: its last exchange is at step 60
  EXPECT_FALSE(coupler::last_exchange_of_run(50, 10, 67));
  EXPECT_TRUE(coupler::last_exchange_of_run(60, 10, 67));
  EXPECT_FALSE(coupler::last_exchange_of_run(60, 10, 70));
  EXPECT_TRUE(coupler::last_exchange_of_run(70, 10, 70));
  // a run with no exchange writes no frame, and says so
  EXPECT_EQ(coupler::frameless_run_warning(5, 1, 10, 10), "");
  EXPECT_EQ(coupler::frameless_run_warning(0, 0, 3, 10), "");
  const std::string frameless = coupler::frameless_run_warning(5, 0, 3, 10);
  EXPECT_NE(frameless.find("3 step(s) had no exchange (every 10)"), std::string::npos) << frameless;
}

TEST(DemCoupling, RestartRecordKeepsTheCellTheRunStartedWith) {
  coupler::RestartRecord r;
  r.cell = 0.012;
  double chosen = -1.0;    // no cell on the input: the grains chose the file's
  EXPECT_EQ(r.take_cell(chosen), "");
  EXPECT_EQ(chosen, 0.012);
  double given = 0.01;     // a given cell wins, with a warning
  EXPECT_EQ(r.take_cell(given), "Fix hybrid/mpm: restart file has cell 0.012, the input says 0.01; using 0.01");
  EXPECT_EQ(given, 0.01);
}

TEST(DemCoupling, GridOfRunRefusesAdaptiveCellsOfFewGrains) {
  auto opt = coupler::parse_fix_options({"cell", "0.0035", "adaptive", "10"}, 2, 1,
                                        [](const std::string &) { return false; });
  opt.continuum.grain_diameter = 0.002;
  std::string problem;
  const double lo[3] = {0, 0, 0}, hi[3] = {0.1, 0.1, 0.1};
  coupler::grid_of_run(opt, 2, 100, lo, hi, problem);
  EXPECT_EQ(problem, "cell 0.0035 is under 2 grain diameters (mean diameter 0.002): adaptive zones need cells that "
                     "hold several grains. Use cell 0.004 or more");
  // chosen from the grains, never too small; with no grains (and no diameter) a cell must be given
  opt = coupler::parse_fix_options({"adaptive", "10"}, 3, 1, [](const std::string &) { return false; });
  opt.continuum.grain_diameter = 0.001;
  EXPECT_NE(coupler::grid_of_run(opt, 3, 100, lo, hi, problem).find("cell 0.004 = 4 mean grain diameters"), std::string::npos);
  EXPECT_EQ(problem, "");
  opt = coupler::parse_fix_options({"adaptive", "10"}, 3, 1, [](const std::string &) { return false; });
  EXPECT_THROW(coupler::grid_of_run(opt, 3, 0, lo, hi, problem), coupler::OptionError);
}

// A silo whose walls x = 0 and 0.32 the continuum touches, in a box 2 mm wider on each side: the
// cell chosen from 2 mm grains (6 d = 0.012) becomes 0.32 / 27, and both walls are node planes.
TEST(DemCoupling, TouchedWallsLieOnNodePlanes) {
  auto opt = coupler::parse_fix_options({"adaptive", "10", "container", "0", "0.32", "0", "INF", "touch", "xlo",
                                         "touch", "xhi"},
                                        2, 1, [](const std::string &) { return false; });
  opt.continuum.grain_diameter = 0.002;
  const double lo[3] = {-0.004, -0.1, -0.5}, hi[3] = {0.324, 2.0, 0.5};
  std::string problem;
  const std::string line = coupler::grid_of_run(opt, 2, 1000, lo, hi, problem);
  EXPECT_NEAR(opt.cell, 0.32 / 27, 1e-15);
  EXPECT_NE(line.find("fitted to the x width 0.32 the continuum touches: 27 cells"), std::string::npos) << line;
  EXPECT_EQ(line.find("warning"), std::string::npos) << line;
  const auto grid = coupler::run_grid<2>(opt, lo, hi);
  for (const double wall : {0.0, 0.32}) {
    const double nodes = (wall - grid.origin[0]) / grid.dx;
    EXPECT_NEAR(nodes, std::round(nodes), 1e-9) << "wall " << wall;
  }
  EXPECT_LE(grid.origin[0], lo[0] - coupler::kGridPad * grid.dx + 1e-15);    // still pads the box
  EXPECT_GT(grid.origin[0], lo[0] - (coupler::kGridPad + 1) * grid.dx);
  EXPECT_NEAR(grid.origin[1], lo[1] - coupler::kGridPad * grid.dx, 1e-15);  // y: no touched face, from the box
  EXPECT_GE(grid.origin[0] + (grid.dims[0] - 1) * grid.dx, hi[0] + coupler::kGridPad * grid.dx - 1e-12);

  // a cell given on the line is kept, with a warning that names the fix
  opt = coupler::parse_fix_options({"cell", "0.012", "adaptive", "10", "container", "0", "0.32", "0", "INF", "touch",
                                    "xlo", "touch", "xhi"},
                                   2, 1, [](const std::string &) { return false; });
  opt.continuum.grain_diameter = 0.002;
  const std::string given = coupler::grid_of_run(opt, 2, 1000, lo, hi, problem);
  EXPECT_EQ(opt.cell, 0.012);
  EXPECT_NE(given.find("warning: the container's x faces the continuum touches are 26.67 cells apart"),
            std::string::npos)
      << given;
  EXPECT_NE(given.find("(e.g. 0.0118519)"), std::string::npos) << given;
}

TEST(DemCoupling, CellDividingIsNearestTheNominalCell) {
  EXPECT_EQ(coupler::cell_dividing(0.012, {}), 0.012);
  EXPECT_NEAR(coupler::cell_dividing(0.012, {{0, 0.32}}), 0.32 / 27, 1e-15);
  EXPECT_NEAR(coupler::cell_dividing(0.012, {{0, 0.18}}), 0.012, 1e-15);
  // a square section: one cell for both
  EXPECT_NEAR(coupler::cell_dividing(0.01, {{0, 0.2}, {1, 0.2}}), 0.01, 1e-15);
  // 0.3 and 0.2 wide: 0.1 / n cells divide both; 0.0125 = 0.1 / 8 is nearest 0.012
  EXPECT_NEAR(coupler::cell_dividing(0.012, {{0, 0.3}, {1, 0.2}}), 0.0125, 1e-15);
  // 8.5 nominal cells across: 9 cells are nearer the nominal one, but finer than the smallest
  // that gives a point its grains, so 8 (the 3D silo of W = 34 d: 4 d nominal, 3.81 d smallest);
  // without a smallest cell the nearest
  EXPECT_NEAR(coupler::cell_dividing(0.008, {{0, 0.068}, {2, 0.068}}, 0.00762), 0.068 / 8, 1e-15);
  EXPECT_NEAR(coupler::cell_dividing(0.008, {{0, 0.068}, {2, 0.068}}), 0.068 / 9, 1e-15);
  // a width of exactly n smallest cells takes n; two counts as near: the coarser
  EXPECT_NEAR(coupler::cell_dividing(0.008, {{0, 0.064}}, 0.0064 / 0.8), 0.008, 1e-15);
  const double tie = 2.0 * 0.008 * 8 * 9 / 17;    // 8 and 9 cells lie as far from 0.008 either side
  EXPECT_NEAR(coupler::cell_dividing(0.008, {{0, tie}}), tie / 8, 1e-15);
}

TEST(DemCoupling, GridFromTheGrainsGivesEveryPointItsGrains) {
  // the 3D silo decks' widths (spheres of 2 mm at packing 0.606, both side spans touched): the
  // fitted cell never leaves a point with fewer than kGrainsPerPoint grains
  const coupler::GrainGrid g = coupler::grid_from_grains(3, 0.002, 0.606, 2);
  for (const int width_d : {12, 18, 26, 34, 40, 52}) {
    const double width = width_d * 0.002;
    const double cell = coupler::cell_dividing(g.cell, {{0, width}, {2, width}}, g.smallest_cell);
    const double grains = 0.606 * std::pow(cell / 0.002, 3) / (3.14159265358979 / 6.0 * 8.0);
    EXPECT_GE(grains, coupler::kGrainsPerPoint * (1.0 - 1e-12)) << width_d << " d: cell " << cell;
    EXPECT_LE(std::abs(cell / g.cell - 1.0), 0.25) << width_d;
  }
}

}    // namespace

TEST(DemCoupling, ClockKeepsItsTimeAcrossRunsAndStepChanges) {
  coupler::CouplingClock clock;
  // before the first run: the host's own time (0.5 s at step 100, dt 1e-3)
  EXPECT_DOUBLE_EQ(clock.time_of(110, 0.5, 100, 1e-3), 0.51);
  clock.start_run(120, 0.5, 100, 1e-3);
  EXPECT_EQ(clock.step, 120);
  EXPECT_DOUBLE_EQ(clock.time_of(130, 99.0, 0, 1.0), 0.52 + 0.01);    // the host's figures no longer count
  // a later run with the same step keeps the anchor; one with another step re-anchors at its start
  clock.start_run(200, 0.0, 0, 1e-3);
  EXPECT_EQ(clock.step, 120);
  clock.start_run(200, 0.0, 0, 5e-4);
  EXPECT_EQ(clock.step, 200);
  EXPECT_DOUBLE_EQ(clock.time, 0.6);
  EXPECT_DOUBLE_EQ(clock.time_of(210, 0.0, 0, 5e-4), 0.6 + 10 * 5e-4);
  // a restart file's record replaces it
  coupler::RestartRecord r;
  r.time = 2.0, r.step = 1000;
  clock.restore(r, 1e-4);
  EXPECT_DOUBLE_EQ(clock.time_of(1010, 0.0, 0, 1.0), 2.001);
  clock.start_run(1010, 0.0, 0, 1e-4);    // the restarted run's setup: the same step, the same anchor
  EXPECT_EQ(clock.step, 1000);
}

TEST(DemCoupling, NextExchangeIsAnnouncedOnlyWhenCertain) {
  coupler::ExchangeOutlook o;
  o.now = 100, o.last_step = 200, o.every = 10;
  EXPECT_EQ(coupler::next_exchange_step(o), 110);
  for (bool coupler::ExchangeOutlook::*flag : {&coupler::ExchangeOutlook::rezone_next,
                                               &coupler::ExchangeOutlook::restart_file}) {
    coupler::ExchangeOutlook held = o;
    held.*flag = true;
    EXPECT_EQ(coupler::next_exchange_step(held), -1);
  }
  o.now = 190;    // the run's last step is the next exchange's
  EXPECT_EQ(coupler::next_exchange_step(o), 200);
  o.now = 195;    // the run ends before the next exchange step
  EXPECT_EQ(coupler::next_exchange_step(o), -1);
}

TEST(DemCoupling, RestartRecordFileIsItsSizeThenItsValues) {
  coupler::RestartRecord r;
  r.cell = 0.01, r.exchanges = 7, r.every = 5, r.converted = true, r.time = 0.25, r.step = 35;
  std::FILE *fp = std::tmpfile();
  ASSERT_NE(fp, nullptr);
  r.write_file(fp);
  std::rewind(fp);
  int size = 0;
  ASSERT_EQ(std::fread(&size, sizeof(int), 1, fp), 1u);
  EXPECT_EQ(size, static_cast<int>(coupler::RestartRecord::kValues * sizeof(double)));
  double values[coupler::RestartRecord::kValues];
  ASSERT_EQ(std::fread(values, sizeof(double), coupler::RestartRecord::kValues, fp),
            static_cast<std::size_t>(coupler::RestartRecord::kValues));
  std::fclose(fp);
  const coupler::RestartRecord back = coupler::RestartRecord::read(values);
  EXPECT_EQ(back.exchanges, 7);
  EXPECT_TRUE(back.converted);
  EXPECT_DOUBLE_EQ(back.time, 0.25);
  EXPECT_EQ(back.step, 35);
}

TEST(DemCoupling, MpmProcessNamesItsHostFromTheHandshake) {
  EXPECT_EQ(coupler::dem_host_name("LAMMPS 29 Sep 2021"), "LAMMPS");
  EXPECT_EQ(coupler::dem_host_name("LIGGGHTS 3.8.0"), "LIGGGHTS");
  EXPECT_EQ(coupler::dem_host_name("LIGGGHTS"), "LIGGGHTS");
  // a peer that names no known host (the fault campaign's stand-in), or nothing
  EXPECT_EQ(coupler::dem_host_name("hostile_peer.py (mpi4py)"), coupler::kUnknownDemHost);
  EXPECT_EQ(coupler::dem_host_name("LAMMPSX 1"), coupler::kUnknownDemHost);
  EXPECT_EQ(coupler::dem_host_name(""), "the DEM host");
}
