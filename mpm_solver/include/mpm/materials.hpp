#pragma once
// Constitutive updates. Each acts on one point, given its velocity gradient
// over the step, and leaves its Cauchy stress for the next P2G.
#include <cmath>

#include "mpm/scene.hpp"
#include "mpm/types.hpp"

namespace mpm {

/// A material with its derived constants, ready for the per-point updates.
struct MaterialModel {
  ModelKind kind = ModelKind::DruckerPrager;
  double density = 0;  ///< bulk density of the continuum
  double shear_modulus = 0, lame_lambda = 0;
  double friction_angle_rad = 0;  ///< Drucker-Prager
  /// The cone in Hencky-strain terms, for 2D and 3D: yield where
  /// |dev eps| + cone_strain_slope * tr eps > 0 (precomputed: it is per point-step work).
  double cone_strain_slope[2] = {0, 0};
  MuIParams mu_i;

  /// Throws UserError naming the material if a parameter is out of range.
  explicit MaterialModel(const Material& m);

  /// P-wave speed sqrt((lambda + 2G)/rho), which bounds the stable time step.
  double wave_speed() const { return std::sqrt((lame_lambda + 2.0 * shear_modulus) / density); }
  /// Fourth power of the P-wave speed of a point in its current state (reference density
  /// rho0, volume ratio J, squared elastic volume ratio Je2 = det b_e): its force is V0 J/Je
  /// times the Kirchhoff stress, so a point whose elastic state restarted dilute (J/Je > 1:
  /// Drucker-Prager after tension, mu(I) reconnecting) is stiffer per unit mass; Hencky's
  /// pressure stiffens by 1 - ln Je <= 1/Je under compression. Bounds the stable step through
  /// high-speed impacts and splashes. (Fourth powers: no square root per point and step.)
  double wave_speed4(double rho0, double J, double Je2) const {
    const double c2 = (lame_lambda + 2.0 * shear_modulus) / rho0;
    return c2 * c2 * std::max(1.0, J * J / Je2) * std::max(1.0, 1.0 / Je2);
  }
  /// Bulk modulus in D dimensions.
  template <int D>
  double bulk_modulus() const { return lame_lambda + 2.0 * shear_modulus / D; }
  /// Elastic energy per unit volume stored in a stress (small-strain, isotropic):
  /// |dev sigma|^2 / (4G) + tr(sigma)^2 / (2 D^2 K) (the energy ledger, docs/fix_hybrid_mpm.md).
  template <int D>
  double elastic_energy_density(const Mat<D>& stress) const {
    const double tr = stress.trace();
    const double dev2 = stress.squaredNorm() - tr * tr / D;
    return dev2 / (4.0 * shear_modulus) + tr * tr / (2.0 * D * D * bulk_modulus<D>());
  }
  /// Friction-cone slope alpha in ||dev sigma|| <= alpha p, p = -tr(sigma)/D.
  /// 2D: exact Mohr-Coulomb. 3D: Mohr-Coulomb fitted on the compression meridian.
  template <int D>
  double cone_slope() const {
    const double s = std::sin(friction_angle_rad);
    return D == 2 ? std::sqrt(2.0) * s : std::sqrt(2.0 / 3.0) * 6.0 * s / (3.0 - s);
  }
};

/// Matrix logarithm of a symmetric positive definite tensor.
template <int D>
Mat<D> tensor_log(const Mat<D>& b);
/// Matrix exponential of a symmetric tensor.
template <int D>
Mat<D> tensor_exp(const Mat<D>& y);

/// Hyperelastic Drucker-Prager with Hencky strain (Klar et al. 2016), on the
/// elastic left Cauchy-Green tensor: be <- f be f^T with f = I + dt L, then a
/// return map of the principal log strains onto the friction cone; dilated
/// states (tr eps >= 0) return to the stress-free state.
/// Updates be, the Cauchy stress and the equivalent plastic shear strain.
template <int D>
void update_drucker_prager(const MaterialModel& m, const Mat<D>& f, Mat<D>& be, Mat<D>& stress,
                           double& plastic_strain);

/// Hypoelastic mu(I) (Dunatunga & Kamrin 2015): Jaumann-rate elastic trial,
/// then isochoric spin-free plastic flow along the stress deviator at the
/// rate that satisfies mu(I) = tau/p; no stress below the critical density or
/// in tension. `density` is the point's current bulk density.
template <int D>
void update_mu_i(const MaterialModel& m, const Mat<D>& L, double dt, double density, Mat<D>& stress,
                 double& plastic_strain);

/// Stress-free-elastic initial state of a point that carries `stress`
/// (geostatic start): the elastic left Cauchy-Green tensor for Drucker-Prager.
template <int D>
Mat<D> elastic_state_for_stress(const MaterialModel& m, const Mat<D>& stress);

}  // namespace mpm
