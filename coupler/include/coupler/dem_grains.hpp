#pragma once
// The DEM side's grains as the coupling sees them: a view of a host's per-atom arrays (LAMMPS
// and LIGGGHTS keep them as double**), and what the coupling computes from them on one rank
// (the caller sums over the ranks): totals, energy, volumes per cell, the grains an exchange
// couples, the drift of their carried mass. Host-neutral.

#include <cstdint>
#include <vector>

#include "coupler/grid_geometry.hpp"
#include "coupler/protocol.hpp"

namespace coupler {

/// This rank's atoms (grains of the coupled group, and others: frozen walls, driven bodies).
struct DemGrains {
  int n = 0;                         ///< local atoms
  double **x = nullptr, **v = nullptr, **omega = nullptr;    ///< [n][3]
  double *radius = nullptr, *rmass = nullptr;
  const int *mask = nullptr;
  int groupbit = 0;                  ///< the coupled group's bit in mask
  double *weight = nullptr;          ///< share of its material a grain carries (the fix's per-atom array)
  double **stress = nullptr;         ///< stress * volume xx yy zz xy xz yz kept for a rezone ([n][6])
  bool coupled(int i) const { return (mask[i] & groupbit) != 0; }
};

/// What a grain is made of: its solid mass (at weight 1) from its size, its moment of inertia.
struct GrainRules {
  int dimension = 3;
  double density = 0;    ///< solid density of the grains (kg/m^3, kg/m^2 in 2D)
  double inertia = 0.4;  ///< I = inertia m r^2
  double solid_mass(double radius) const;
};

/// Mass, linear momentum and angular momentum about the origin (orbital and spin) of this
/// rank's grains of the group.
void grain_totals(const DemGrains &g, double inertia, double out[7]);

/// Kinetic (translation and rotation) plus potential energy in gravity g of this rank's grains
/// of the group (the energy ledger).
double grain_energy(const DemGrains &g, double inertia, const double gravity[3]);

/// Volume and carried mass per grid cell of this rank's grains of the group (the oracle's
/// packing fraction), sparse: cells holding grains, by cell index.
template <int D>
std::vector<CellGrains> cell_grains(const GridGeometry<D> &grid, const DemGrains &g);

/// The grains an exchange couples: of the group, hybrid (weight below 1) or in a cell whose
/// zone is not discrete. zone_of(x) gives the zone of a position.
template <class ZoneOf>
std::vector<int> coupled_grains(const DemGrains &g, ZoneOf &&zone_of) {
  std::vector<int> index;
  for (int i = 0; i < g.n; i++)
    if (g.coupled(i) && !(g.weight[i] >= 1.0 && zone_of(g.x[i]) == kDiscrete)) index.push_back(i);
  return index;
}

/// Carried mass over weight times solid mass of this rank's grains of the group: out[0] the
/// lightest's, negated, out[1] the heaviest's (for a max-reduction over the ranks).
void mass_drift(const DemGrains &g, const GrainRules &rules, double out[2]);

}    // namespace coupler
