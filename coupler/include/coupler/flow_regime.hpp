#pragma once
// The local flow regime and the grain update it asks for (docs/design.md section 5.3).
//
// The impulse rule keeps each hybrid grain's velocity fluctuation about the field; the field
// rule replaces it with the field. Where the material flows, the fluctuations carry its
// fluidity and must be kept (a collapse run on the field rule alone ran out 41 % short); where
// it is quasi-static, contacts remove them within a few collisions in the DEM, but a hybrid
// grain of half mass between a continuum and grains kept wandering (a collapse deposit took
// 1.7-2.2x the DEM's steps to rest). The regime is read from the inertial number
// I = gammadot d / sqrt(p / rho_s) (GDR MiDi 2004; da Cruz et al. 2005): quasi-static below
// about 1e-3, dense flow above it; and from the material's speed against the oracle's rest speed,
// since slow shear under a deep silo's pressure is quasi-static by I but still a flow whose grains
// must pass each other (still_share). A point's share is the product of the two.
#include <algorithm>
#include <cmath>

#include <Eigen/Core>

namespace coupler {

/// Inertial number at or below which the material is quasi-static: the field rule throughout.
inline constexpr double kQuasiStaticInertialNumber = 1e-3;
/// Inertial number at or above which the material flows: the impulse rule throughout. Between
/// the two the share falls linearly in log I, so that neighbouring nodes change rule smoothly.
inline constexpr double kFlowingInertialNumber = 1e-2;

/// Inertial number of a material point from its velocity gradient L, its Cauchy stress
/// (tension positive), the grain diameter and the grains' solid density. The shear rate is
/// sqrt(2) |dev sym L| (the mu(I) convention of mpm_solver's update_mu_i; unlike the oracle's
/// coupler::shear_rate, which counts a compaction as shear, the deviatoric part only). A point without
/// pressure is free (infinite I); one without shear under pressure is at rest (I = 0).
template <int D>
double inertial_number(const Eigen::Matrix<double, D, D>& L, const Eigen::Matrix<double, D, D>& stress,
                       double grain_diameter, double grain_density) {
  using M = Eigen::Matrix<double, D, D>;
  const M rate = 0.5 * (L + L.transpose());
  const double shear_rate = std::sqrt(2.0) * (rate - rate.trace() / D * M::Identity()).norm();
  const double pressure = -stress.trace() / D;
  if (!(pressure > 0.0)) return shear_rate > 0.0 ? HUGE_VAL : 0.0;
  return shear_rate * grain_diameter * std::sqrt(grain_density / pressure);
}

/// 1 at or below `full`, 0 at or above `none`, linear in log x between: the field rule's share
/// along a measure of the flow, so that neighbouring nodes change rule smoothly.
inline double log_linear_share(double x, double full, double none) {
  if (!(x > full)) return 1.0;
  if (x >= none) return 0.0;
  return std::log(none / x) / std::log(none / full);
}

/// Share of the field rule in a hybrid grain's update where the material has inertial number I:
/// 1 when quasi-static, 0 when flowing, log-linear between.
inline double field_share(double inertial_number) {
  return log_linear_share(inertial_number, kQuasiStaticInertialNumber, kFlowingInertialNumber);
}

/// Share of the field rule by how still the material is: 1 at or below rest_speed, 0 at or above
/// kStillSpeeds times it, log-linear in the speed between. The inertial number alone reads a
/// deep silo's slow flow as quasi-static (its pressure makes I small at any shear the flow has),
/// and the field rule there erased the fluctuations that let the grains pass each other: the
/// 80k disk silo discharged 6.7 % slow exchanging every 10 steps (1.3 % with the impulse rule).
/// What the field rule is for, a deposit's hybrid grains that keep wandering as it comes to rest,
/// happens where the material is nearly still; a flow moves at 0.1-1 sqrt(g d).
inline constexpr double kStillSpeeds = 10.0;
inline double still_share(double speed, double rest_speed) {
  return log_linear_share(speed, rest_speed, kStillSpeeds * rest_speed);
}

}  // namespace coupler
