#pragma once
// The fill pressure of a node shared by points and coupled grains (docs/design.md section 5.4):
// where the two together hold more than the packing's mass, the points are pushed apart until
// they do not. Header-only and free of MPI and LAMMPS types: the MPM process applies it, the
// unit tests drive it directly.

namespace coupler {

/// The pressure at a node of `node_mass` (its points' and coupled grains' mass) where a node at
/// the packing holds `full_mass` (packing fraction x grain density x cell volume): `modulus`
/// times the overfill `node_mass / full_mass - 1` read as a volumetric strain, none at or below
/// the packing's (a loose mixture is the continuum's own stress to answer).
inline double fill_pressure(double node_mass, double full_mass, double modulus) {
  return full_mass > 0 && node_mass > full_mass ? modulus * (node_mass / full_mass - 1.0) : 0.0;
}

}  // namespace coupler
