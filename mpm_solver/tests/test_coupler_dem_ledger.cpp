// The grains' side of the energy ledger and the fix's global vector (coupler/dem_ledger.hpp):
// every change of the grains' energy is charged to one bracket, so the residual (entry 29) is
// zero when the two sides' figures are those of one state, and not when they are not.
#include <gtest/gtest.h>

#include "coupler/dem_ledger.hpp"

#include <initializer_list>
#include <string>
#include <vector>

namespace {

TEST(DemLedger, BracketsChargeEveryChangeOnce) {
  coupler::EnergyLedger l;
  l.start = l.energy = 10.0;
  l.support_open += 0.5;         // the support force's kicks during the host's steps
  l.close_dem_bracket(9.0);      // the grains' energy at the exchange
  EXPECT_DOUBLE_EQ(l.dem, -1.5);
  EXPECT_DOUBLE_EQ(l.support, 0.5);
  EXPECT_DOUBLE_EQ(l.support_open, 0.0);
  l.add_agreement(-0.25);
  EXPECT_DOUBLE_EQ(l.energy, 8.75);
  l.close_rezone(9.75);
  EXPECT_DOUBLE_EQ(l.rezone, 1.0);
  EXPECT_DOUBLE_EQ(l.energy, 9.75);
  // the grains' energy is their start plus what each bracket changed
  EXPECT_DOUBLE_EQ(l.energy, l.start + l.dem + l.support + l.agreement + l.rezone);
}

TEST(DemLedger, VectorAddsBothSidesAndItsResidualClosesTheLedger) {
  coupler::EnergyLedger l;
  l.start = l.energy = 10.0;
  l.close_dem_bracket(9.0);
  l.add_agreement(-0.5);
  coupler::StepAck a;
  a.points = 40, a.shared_nodes = 12, a.mismatch = 0.01, a.substeps = 3, a.mpm_dt = 1e-5, a.overlap = 0.0625;
  a.energy_fill = 0.375;  // a part of energy_physics, not a term of the sum
  a.mass = 2.0, a.momentum[1] = -1.0, a.angular[2] = 0.25, a.kinetic_energy = 0.125;
  a.zone_cells[coupler::kContinuum] = 5, a.zone_cells[coupler::kHybrid] = 6, a.zone_cells[coupler::kDiscrete] = 7;
  const double continuum_start = 4.0;
  a.energy_physics = -0.75, a.energy_agreement = 0.25, a.energy_rezone = 0.0;
  a.energy = continuum_start + a.energy_physics + a.energy_agreement;
  const double totals[7] = {1.0, 0.5, 0.5, 0, 0, 0, 0.5};
  double sums[coupler::EnergyLedger::kSums], v[coupler::kVecSize];
  l.sums(sums);
  coupler::thermo_vector(a, 9, 33, totals, sums, continuum_start, v);
  EXPECT_DOUBLE_EQ(v[coupler::kVecExchanges], 9);
  EXPECT_DOUBLE_EQ(v[coupler::kVecCoupledGrains], 33);
  EXPECT_DOUBLE_EQ(v[coupler::kVecPoints], 40);
  EXPECT_DOUBLE_EQ(v[coupler::kVecMass], 3.0);
  EXPECT_DOUBLE_EQ(v[coupler::kVecPy], -0.5);
  EXPECT_DOUBLE_EQ(v[coupler::kVecLz], 0.75);
  EXPECT_DOUBLE_EQ(v[coupler::kVecContinuumCells], 5);
  EXPECT_DOUBLE_EQ(v[coupler::kVecDiscreteCells], 7);
  EXPECT_DOUBLE_EQ(v[coupler::kVecEnergyGrains], 8.5);
  EXPECT_DOUBLE_EQ(v[coupler::kVecEnergy], 8.5 + 3.5);
  EXPECT_DOUBLE_EQ(v[coupler::kVecEnergyResidual], 0.0);
  // a change no bracket saw shows up in the residual
  a.energy += 0.125;
  coupler::thermo_vector(a, 9, 33, totals, sums, continuum_start, v);
  EXPECT_DOUBLE_EQ(v[coupler::kVecEnergyResidual], 0.125);
  // f_ID[1..36] in docs/fix_hybrid_mpm.md: the timing entries come after the ledger's, which
  // keep their numbers; they are the host's wall clock, left at zero here; then the overlap,
  // the fill pressure's work and the energy guard's share (the guard's, zero here)
  EXPECT_EQ(coupler::kVecEnergyResidual, 28);
  EXPECT_EQ(coupler::kVecTimeCoupling, 29);
  EXPECT_EQ(coupler::kVecOverlap, 33);
  EXPECT_EQ(coupler::kVecEnergyFill, 34);
  EXPECT_EQ(coupler::kVecGuardShare, 35);
  EXPECT_EQ(coupler::kVecSize, 36);
  EXPECT_EQ(v[coupler::kVecGuardShare], 0.0);
  for (int k = coupler::kVecTimeCoupling; k <= coupler::kVecTimeShare; k++) EXPECT_EQ(v[k], 0.0) << k;
  EXPECT_DOUBLE_EQ(v[coupler::kVecOverlap], 0.0625);
  EXPECT_DOUBLE_EQ(v[coupler::kVecEnergyFill], 0.375);
}

/// A thermo vector with mass `mass` whose non-host ledger terms are `terms` (entries 23-28).
std::vector<double> vector_with(double mass, std::initializer_list<double> terms, double energy = 40.0) {
  std::vector<double> v(coupler::kVecSize, 0.0);
  v[coupler::kVecMass] = mass;
  v[coupler::kVecEnergy] = energy;
  v[coupler::kVecEnergyDem] = -100.0;    // the host's own steps never count
  int k = coupler::kVecEnergyContinuumSteps;
  for (double t : terms) v[k++] = t;
  return v;
}

TEST(EnergyGuard, StopsOnlyWhenTheCouplingMakesMoreThanItsShareOfMgh) {
  // 2D silo: 40 kg/m under g = 9.81 in a box 0.25 m high, 5 %: 4.905 J/m allowed
  const double g[3] = {0, -9.81, 0}, lo[3] = {0, 0, -0.5}, hi[3] = {0.1, 0.25, 0.5};
  auto guard = coupler::EnergyGuard::over_box(0.05, g, lo, hi, 2);
  EXPECT_EQ(guard.check(vector_with(40, {0, 0, 0, 0, 0, 0}).data(), 0.0), "");
  EXPECT_NEAR(guard.scale(), 40 * 9.81 * 0.25, 1e-12);    // z of a 2D box does not count
  // dissipation: the sum falls, whatever the host's steps do
  EXPECT_EQ(guard.check(vector_with(39, {-3, -1, -0.5, 2, -28, 28.5}).data(), 0.1), "");    // sum -2
  // a rise of 4.9 above the lowest sum (-2) is within 5 %, from the largest mass seen (40)
  EXPECT_EQ(guard.check(vector_with(30, {-1, -1, -0.5, 4.9, -28, 28.5}).data(), 0.2), "");
  // the rezones count: the continuum's steps and a rezone measure on the grid and on the points,
  // so each alone shifts energy to the other (their sum is what the material holds)
  EXPECT_EQ(guard.check(vector_with(30, {1.5, -1, -0.5, 4.9, -28, 26}).data(), 0.22), "");
  const std::string made = guard.check(vector_with(30, {-1, -1, -0.5, 5.0, -28, 28.5}).data(), 0.25);
  EXPECT_NE(made.find("the coupling made 5 J (J/m in 2D) of energy between t = 0.1 s and t = 0.25 s"),
            std::string::npos) << made;
  EXPECT_NE(made.find("the support force's kicks +3"), std::string::npos) << made;    // since the lowest
  EXPECT_NE(made.find("the continuum's own steps +2"), std::string::npos) << made;
  EXPECT_NE(made.find("energy_guard 0 lets the run go on"), std::string::npos) << made;
  // its margin: the largest rise so far over the scale, 5.0 / 98.1 (the benches report it)
  EXPECT_NEAR(guard.largest_share(), 5.0 / (40 * 9.81 * 0.25), 1e-12);
  EXPECT_EQ(guard.check(vector_with(30, {-1, -1, -0.5, 3.0, -28, 28.5}).data(), 0.3), "");    // a smaller rise
  EXPECT_NEAR(guard.largest_share(), 5.0 / (40 * 9.81 * 0.25), 1e-12);
  // unguarded, the same rise passes, and the margin is still tracked
  auto off = coupler::EnergyGuard::over_box(0.0, g, lo, hi, 2);
  off.check(vector_with(40, {0, 0, 0, 0, 0, 0}).data(), 0.0);
  EXPECT_EQ(off.check(vector_with(30, {10, 0, 0, 10, 0, 0}).data(), 0.25), "");
  EXPECT_NEAR(off.largest_share(), 20.0 / (40 * 9.81 * 0.25), 1e-12);
}

TEST(EnergyGuard, WithoutGravityTheScaleIsTheLargestEnergySeen) {
  const double g[3] = {0, 0, 0}, lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
  auto guard = coupler::EnergyGuard::over_box(0.1, g, lo, hi, 3);
  EXPECT_EQ(guard.check(vector_with(1, {0, 0, 0, 0, 0, 0}, 2.0).data(), 0.0), "");
  EXPECT_DOUBLE_EQ(guard.scale(), 2.0);
  EXPECT_EQ(guard.check(vector_with(1, {-0.5, 0, 0, 0, 0, 0}, 1.5).data(), 1.0), "");
  EXPECT_EQ(guard.check(vector_with(1, {-0.5, 0, 0, 0.2, 0, 0}, 1.7).data(), 2.0), "");    // 0.2 = 10 % of 2
  EXPECT_NE(guard.check(vector_with(1, {-0.5, 0, 0, 0.25, 0, 0}, 1.75).data(), 3.0), "");
}

}    // namespace
