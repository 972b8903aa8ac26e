#pragma once
// The DEM side's grains as the coupling sees them: a view of a host's per-atom arrays (LAMMPS
// and LIGGGHTS keep them as double**), and what the coupling computes from them on one rank
// (the caller sums over the ranks): totals, energy, volumes per cell, the grains an exchange
// couples, the drift of their carried mass. Host-neutral.

#include <cstdint>
#include <functional>
#include <vector>

#include "coupler/dem_ledger.hpp"
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

/// Kinetic (translation and rotation) and potential energy in gravity g of grain i.
GrainEnergy grain_energy_of(const DemGrains &g, int i, double inertia, const double gravity[3]);

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

/// Carried mass over weight times solid mass of this rank's grains of the group, in one pass:
/// extremes[0] the lightest's, negated, extremes[1] the heaviest's (for a max-reduction over the
/// ranks); sums[0] their carried mass, sums[1] their weights times their solid masses (for a
/// sum-reduction). The sums' ratio is the carried mass over the solid share on the mean: above 1
/// the grains are fewer than their material fills (the conversions lost grain volume, and the
/// grains are heavier than their size); 1 for grains that never met a continuum.
void mass_drift(const DemGrains &g, const GrainRules &rules, double extremes[2], double sums[2]);

/// How many of this rank's grains of the group carry a weight below 1 (the hybrid grains).
std::int64_t hybrid_grain_count(const DemGrains &g);


/// The fix's per-atom arrays that travel with a grain (a host's fix allocates them and hands
/// them to its exchange and copy callbacks): weight, support acceleration, stored stress.
struct GrainArrays {
  static constexpr int kValues = 1 + 3 + 6;    ///< doubles per atom in an exchange buffer
  double *weight = nullptr;
  double **support = nullptr;    ///< [n][3]
  double **stress = nullptr;     ///< [n][6]
  void copy(int from, int to) const;
  void reset(int i) const;       ///< a new atom: weight 1, no support, no stored stress
  int pack(int i, double *buf) const;
  int unpack(int i, const double *buf) const;
  /// Restart files hold weight and support (a rezone left pending at the end of a run is
  /// dropped): kRestartValues doubles, the count first (LAMMPS's convention).
  static constexpr int kRestartValues = 1 + 1 + 3;
  int pack_restart(int i, double *buf) const;
  void unpack_restart(int i, const double *values) const;    ///< values: this fix's, count first
};

/// Local atoms with a non-zero support acceleration (after atoms were reordered).
std::vector<int> supported_grains(double *const *support, int n);

/// Deletes the flagged ones of n local atoms as LAMMPS's fix evaporate does: from the end,
/// the last atom moves into the gap (move(from, to) copies every per-atom array); returns the
/// new n.
int delete_flagged(const std::vector<char> &flags, int n, const std::function<void(int, int)> &move);

/// The view of a host's atoms: its per-atom arrays (n local atoms) and the fix's.
inline DemGrains grain_view(int n, double **x, double **v, double **omega, double *radius, double *rmass,
                            const int *mask, int groupbit, const GrainArrays &arrays) {
  DemGrains g;
  g.n = n, g.x = x, g.v = v, g.omega = omega, g.radius = radius, g.rmass = rmass;
  g.mask = mask, g.groupbit = groupbit, g.weight = arrays.weight, g.stress = arrays.stress;
  return g;
}

/// This rank's atoms for an output frame of the MPM process's file (tag: the host's atom IDs;
/// zone_of(x): the zone of a position).
template <class Tag, class ZoneOf>
std::vector<GrainRecord> frame_records(const DemGrains &g, const Tag *tag, ZoneOf &&zone_of) {
  std::vector<GrainRecord> records(static_cast<std::size_t>(g.n));
  for (int i = 0; i < g.n; i++) {
    GrainRecord &r = records[static_cast<std::size_t>(i)];
    r.id = static_cast<std::int64_t>(tag[i]);
    for (int a = 0; a < 3; a++) r.x[a] = g.x[i][a], r.v[a] = g.v[i][a];
    r.radius = g.radius[i], r.mass = g.rmass[i], r.weight = g.weight[i];
    r.zone = zone_of(g.x[i]);
  }
  return records;
}

}    // namespace coupler
