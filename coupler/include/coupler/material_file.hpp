// material_file.hpp - a granular material calibrated from its own grains (docs/design.md
// section 4.6, "Calibration from the grains"): the contact law it was measured with and
// the continuum's constants, all dimensionless so that one file serves every grain size and
// stiffness of that law. fix hybrid/mpm reads it with the keyword `material FILE`.
#pragma once

#include <string>

namespace coupler {

struct ContinuumSettings;

struct CalibratedMaterial {
  std::string path, name;
  int dimension = 0;
  // [contact]: the law of the calibration runs
  std::string pair;
  double friction = 0, restitution = 0, kt_over_kn = 0, gammat_over_gamman = 0, polydispersity = 0,
         stiffness_number = 0;
  // [continuum]
  double packing_fraction = 0, critical_packing = 0;
  double youngs_over_kn = 0;   ///< E / kn in 2D (kn per unit depth), E d / kn in 3D
  double poisson = 0, mu_s = 0, mu_2 = 0, I0 = 0;
  double friction_angle = 0;   ///< degrees: the Drucker-Prager cone that matches mu_s
};

/// The material file a fix line names: a path that exists, else a name (no '/') looked up as
/// NAME or NAME.toml in each directory of $HYBRID_MATERIALS (':'-separated) and then in the
/// project's input_decks/materials (the calibrated materials the decks use). Throws
/// std::runtime_error listing where it looked and how to calibrate a material.
std::string find_material_file(const std::string& name_or_path);

/// Reads a material file. Throws std::runtime_error naming the file, the key and what is wrong
/// (missing, not a number, out of range).
CalibratedMaterial read_material_file(const std::string& path);

/// A deck's Hookean contact law as its pair style holds it (LAMMPS's damping is per unit
/// effective mass), with the mean grain's mass for the restitution.
struct DeckContact {
  int dimension = 0;
  double friction = 0, kn = 0, kt = 0, gamman = 0, gammat = 0;
  double mean_mass = 0;   ///< of a grain of the mean diameter
};

/// Normal restitution of a Hookean pair of effective mass m_eff: zeta = gamman / (2 sqrt(kn/m_eff)),
/// e = exp(-pi zeta / sqrt(1 - zeta^2)) (0 when overdamped).
double restitution(double kn, double gamman, double m_eff);

/// What differs between the deck's contact law and the calibrated one beyond round-off of the
/// decks' own arithmetic, each difference with both values; "" when they match.
std::string contact_mismatch(const CalibratedMaterial& m, const DeckContact& deck);

/// The continuum's constants from the material: Young's modulus from the deck's kn (and the
/// mean grain diameter d in 3D), Poisson's ratio, the Drucker-Prager angle, mu(I) and the
/// critical packing.
void apply_material(const CalibratedMaterial& m, double kn, double diameter, ContinuumSettings& settings);

/// The packing's compaction modulus from the calibration (the fill pressure's, `fill auto`;
/// docs/design.md section 5.4): the pressure p0 the grains were compressed to (kn / kappa in 2D,
/// kn / (kappa d) in 3D, kappa the stiffness number) over the relative densification from the
/// critical packing it took, p0 phi / (phi - phi_c), Pa.
double compaction_modulus(const CalibratedMaterial& m, double kn, double diameter);

}  // namespace coupler
