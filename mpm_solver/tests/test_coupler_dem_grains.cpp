// The DEM side's grains as the coupling sees them (coupler/dem_grains.hpp, dem_rezone.hpp): a
// view of a host's per-atom arrays, the sums over them, and a rezone's corrections applied to
// them; only the group's grains count, frozen grains outside it never do.
#include <gtest/gtest.h>

#include <cmath>

#include "coupler/dem_grains.hpp"
#include "coupler/dem_rezone.hpp"
#include "coupler/zones.hpp"

namespace {

// three atoms in 2D: two grains of the group (bit 1), a frozen wall grain (bit 2)
struct Atoms {
  double xs[3][3] = {{0.012, 0.013, 0}, {0.017, 0.012, 0}, {0.031, 0.004, 0}};
  double vs[3][3] = {{1.0, -0.5, 0}, {0.0, 2.0, 0}, {5.0, 5.0, 0}};
  double ws[3][3] = {{0, 0, 3.0}, {0, 0, -1.0}, {0, 0, 7.0}};
  double st[3][6] = {{1, 2, 0, 3, 0, 0}, {4, 5, 0, 6, 0, 0}, {0, 0, 0, 0, 0, 0}};
  double *x[3] = {xs[0], xs[1], xs[2]}, *v[3] = {vs[0], vs[1], vs[2]}, *omega[3] = {ws[0], ws[1], ws[2]};
  double *stress[3] = {st[0], st[1], st[2]};
  double radius[3] = {0.001, 0.0012, 0.001};
  double rmass[3] = {0.5, 0.9, 1.0};
  double weight[3] = {0.5, 1.0, 1.0};
  int mask[3] = {1 | 4, 1, 2};
  coupler::DemGrains view() {
    coupler::DemGrains g;
    g.n = 3;
    g.x = x, g.v = v, g.omega = omega, g.radius = radius, g.rmass = rmass, g.mask = mask, g.groupbit = 1;
    g.weight = weight, g.stress = stress;
    return g;
  }
};

coupler::GrainRules rules() {
  coupler::GrainRules r;
  r.dimension = 2;
  r.density = 1.0 / (M_PI * 1e-6);    // a grain of radius 1 mm has solid mass 1
  r.inertia = 0.5;
  return r;
}

coupler::GridGeometry<2> grid() {
  return coupler::padded_grid<2>(Eigen::Vector2d(0, 0), Eigen::Vector2d(0.04, 0.04), 0.01);
}

TEST(DemGrains, TotalsAndEnergyCountTheGroupOnly) {
  Atoms a;
  double t[7];
  coupler::grain_totals(a.view(), 0.5, t);
  EXPECT_DOUBLE_EQ(t[0], 1.4);
  EXPECT_DOUBLE_EQ(t[1], 0.5 * 1.0);
  EXPECT_DOUBLE_EQ(t[2], 0.5 * -0.5 + 0.9 * 2.0);
  const double Lz = 0.5 * (0.012 * -0.5 - 0.013 * 1.0) + 0.5 * 0.5 * 1e-6 * 3.0 + 0.9 * (0.017 * 2.0 - 0.012 * 0.0) +
                    0.5 * 0.9 * 1.44e-6 * -1.0;
  EXPECT_NEAR(t[6], Lz, 1e-15);
  const double g[3] = {0, -9.81, 0};
  const double e = 0.5 * 0.5 * 1.25 + 0.5 * 0.5 * 0.5 * 1e-6 * 9 + 0.5 * 9.81 * 0.013 + 0.5 * 0.9 * 4 +
                   0.5 * 0.5 * 0.9 * 1.44e-6 + 0.9 * 9.81 * 0.012;
  EXPECT_NEAR(coupler::grain_energy(a.view(), 0.5, g), e, 1e-14);
}

TEST(DemGrains, VolumesPerCellAndTheCoupledGrains) {
  Atoms a;
  a.xs[1][0] = 0.014;    // both grains in one cell
  const auto cells = coupler::cell_grains<2>(grid(), a.view());
  ASSERT_EQ(cells.size(), 1u);
  EXPECT_DOUBLE_EQ(cells[0].mass, 1.4);
  EXPECT_NEAR(cells[0].volume, M_PI * (1e-6 + 1.44e-6), 1e-18);
  // translational kinetic energy (the oracle's rest measure): 1/2 0.5 1.25 + 1/2 0.9 4
  EXPECT_DOUBLE_EQ(cells[0].kinetic, 0.5 * 0.5 * 1.25 + 0.5 * 0.9 * 4.0);
  // hybrid grains always; whole grains where the zone is not discrete; never the frozen one
  EXPECT_EQ(coupler::coupled_grains(a.view(), [](const double *) { return coupler::kDiscrete; }),
            std::vector<int>{0});
  EXPECT_EQ(coupler::coupled_grains(a.view(), [](const double *) { return coupler::kHybrid; }),
            (std::vector<int>{0, 1}));
}

TEST(DemGrains, MassDriftIsCarriedOverWeightTimesSolidMass) {
  Atoms a;
  double d[2], s[2];
  coupler::mass_drift(a.view(), rules(), d, s);
  // grain 0: 0.5 / (0.5 * 1) = 1; grain 1: 0.9 / (1 * 1.44) = 0.625
  EXPECT_DOUBLE_EQ(-d[0], 0.625);
  EXPECT_DOUBLE_EQ(d[1], 1.0);
}

TEST(DemGrains, MassDriftSumsAreCarriedMassAndWeightTimesSolidMass) {
  Atoms a;
  double d[2], s[2];
  coupler::mass_drift(a.view(), rules(), d, s);
  // grain 0: carried 0.5, share 0.5 * 1; grain 1: carried 0.9, share 1 * 1.44 (mass_drift's grains)
  EXPECT_DOUBLE_EQ(s[0], 0.5 + 0.9);
  EXPECT_DOUBLE_EQ(s[1], 0.5 + 1.44);
}

TEST(DemGrains, HybridGrainsAreTheGroupsGrainsOfWeightBelowOne) {
  Atoms a;
  EXPECT_EQ(coupler::hybrid_grain_count(a.view()), 1);
  a.weight[2] = 0.5;    // the frozen grain is not of the group
  EXPECT_EQ(coupler::hybrid_grain_count(a.view()), 1);
  a.weight[1] = 0.5;
  EXPECT_EQ(coupler::hybrid_grain_count(a.view()), 2);
}

TEST(DemRezone, SumsOfTheMovingCellsAndTheirCorrections) {
  Atoms a;
  a.xs[1][0] = 0.022;    // the grains in two cells
  const auto gr = grid();
  const auto c0 = coupler::cell_index<2>(gr, coupler::cell_of<2>(gr, Eigen::Vector2d(0.012, 0.013)));
  const auto c1 = coupler::cell_index<2>(gr, coupler::cell_of<2>(gr, Eigen::Vector2d(0.022, 0.012)));
  ASSERT_NE(c0, c1);
  std::vector<coupler::RezoneCell<2>> cells(2);
  cells[0].cell = c1, cells[1].cell = c0;
  const auto slots = coupler::cell_slots<2>(cells);
  EXPECT_EQ(coupler::slot_of_cell_at<2>(gr, a.x[0], slots), 1);
  EXPECT_EQ(coupler::slot_of_cell_at<2>(gr, a.x[2], slots), -1);    // its cell is not listed
  auto sums = coupler::moving_grain_sums<2>(gr, cells, slots, a.view(), rules());
  ASSERT_EQ(sums.size(), 2u);
  EXPECT_DOUBLE_EQ(sums[1].carried.moments.mass, 0.5);
  EXPECT_DOUBLE_EQ(sums[1].solid.moments.mass, 1.0);
  EXPECT_DOUBLE_EQ(sums[0].solid.moments.mass, 1.44);
  EXPECT_EQ(sums[0].carried.moments.cell, c1);

  // a made grain joins its cell's solid sums only
  coupler::PlannedGrain<2> p;
  p.slot = 0;
  p.grain.x = Eigen::Vector2d(0.024, 0.016), p.grain.v = Eigen::Vector2d(0, 0), p.grain.radius = 0.001;
  p.grain.mass = 1.0, p.grain.omega.setZero();
  p.centre = coupler::cell_center<2>(gr, coupler::cell_coords<2>(gr, c1));
  coupler::add_new_grain<2>(sums, cells, p, rules());
  EXPECT_DOUBLE_EQ(sums[0].solid.moments.mass, 2.44);
  EXPECT_DOUBLE_EQ(sums[0].carried.moments.mass, 0.9);

  // cell c0 becomes points; cell c1's grains take half their solid mass and a rigid increment
  std::vector<coupler::GrainCorrection<2>> corrections(2);
  corrections[0].cell = c0, corrections[0].remove = 1, corrections[0].mechanism = coupler::kHomogenisation;
  corrections[1].cell = c1, corrections[1].weight = 0.5, corrections[1].mass_factor = 0.5;
  corrections[1].mechanism = coupler::kRepair;
  corrections[1].velocity[0] = 1.0, corrections[1].omega[0] = 2.0;
  corrections[1].centre[0] = 0.025, corrections[1].centre[1] = 0.015;
  auto view = a.view();
  std::vector<signed char> mechanisms;
  const auto remove = coupler::apply_corrections<2>(gr, cells, slots, corrections, view, rules(), &mechanisms);
  EXPECT_EQ(remove, (std::vector<char>{1, 0, 0}));
  // each grain's cell's mechanism as its correction names it; none for the frozen grain
  EXPECT_EQ(mechanisms, (std::vector<signed char>{coupler::kHomogenisation, coupler::kRepair, -1}));
  EXPECT_DOUBLE_EQ(a.rmass[1], 0.5 * 1.44);
  EXPECT_DOUBLE_EQ(a.weight[1], 0.5);
  // dv = velocity + omega x (x - centre) = (1, 0) + 2 (-(0.012 - 0.015), 0.022 - 0.025)
  EXPECT_DOUBLE_EQ(a.vs[1][0], 0.0 + 1.0 + 2.0 * 0.003);
  EXPECT_DOUBLE_EQ(a.vs[1][1], 2.0 - 2.0 * 0.003);
  EXPECT_DOUBLE_EQ(a.ws[1][2], -1.0 + 2.0);
  EXPECT_DOUBLE_EQ(a.rmass[2], 1.0);    // the frozen grain is untouched
}

}    // namespace
