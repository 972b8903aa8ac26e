// dem_timestep.hpp - the stable time step of a Hookean DEM contact (docs/design.md section 3), for the
// check fix hybrid/mpm makes before and during a run.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace coupler {

/// A linear spring-dashpot contact between two grains as LAMMPS's gran/hooke(/history) pair
/// styles apply it: Fn = kn delta - m_eff gamman v_n, Ft = -kt s - m_eff gammat v_t.
struct HookeanContact {
  double kn = 0;          // normal stiffness, N/m
  double kt = 0;          // tangential stiffness, N/m
  double gamman = 0;      // normal damping rate, 1/s (multiplied by the effective mass)
  double m_eff = 0;       // effective mass of the pair, kg
  double inertia = 0.4;   // I = inertia m r^2 of each grain (0.4 spheres, 0.5 disks)
};

/// Steps per contact the DEM practice asks for (dt <= tc/20); the default below which the fix
/// warns (fix keyword steps_per_contact): with fewer than 10 the contact force is no longer well
/// resolved and a collision's energy balance drifts (LIGGGHTS's check/timestep/gran warns alike);
/// and the fewest at all: velocity Verlet integrates an undamped oscillator of frequency omega
/// stably only for omega dt < 2, i.e. tc/dt > pi/2. Below that the fix refuses the run.
inline constexpr double kSafeStepsPerContact = 20;
inline constexpr double kWarnStepsPerContact = 10;
inline constexpr double kUnstableStepsPerContact = M_PI / 2;
/// The DEM side's "unknown" and "none yet" (LAMMPS's BIG): the steps per contact where the check
/// does not know the contact time (a pair style or contact model it cannot check, no grains), and
/// the start of the hosts' minima over their grains. Every host uses this one constant.
inline constexpr double kBig = 1.0e20;

/// Contact time of the stiffest mode of the pair: the damped normal oscillation,
/// tc = pi / sqrt(kn/m_eff - gamman^2/4), or the tangential one, whose stiffness the rotation
/// of both grains raises by the factor 1 + 1/inertia (undamped: the shorter, safe side). An
/// overdamped normal mode falls back to its undamped frequency sqrt(kn/m_eff).
inline double contact_time(const HookeanContact &c)
{
  const double normal2 = c.kn / c.m_eff;
  double omega2 = normal2 - 0.25 * c.gamman * c.gamman;
  if (omega2 <= 0) omega2 = normal2;
  omega2 = std::max(omega2, c.kt * (1 + 1 / c.inertia) / c.m_eff);
  if (!(omega2 > 0)) return std::numeric_limits<double>::infinity();
  return M_PI / std::sqrt(omega2);
}

/// The DEM step checked against the stiffest contact of a run: the contact time of the two
/// lightest grains (at their share `weight` of their mass where the coupling splits grains),
/// the steps per contact, and the words of the fix's log line, warning and error.
struct DemStepCheck {
  double tc = 0;        ///< contact time of the stiffest pair, s
  double steps = 0;     ///< DEM steps per contact, tc / dt
  std::string what;     ///< "the stiffest contact (pair style ...) lasts tc = ... s"
  bool unstable() const { return steps < kUnstableStepsPerContact; }
  /// "fix hybrid/mpm: DEM time step <dt> s: <what>, <steps> steps per contact" (the first check's log line)
  std::string log_line(double dt) const;
  /// Why the step is unstable or poor, and the step to use ("<what>, and N steps per contact
  /// (fewer than ...) ... Use timestep ... (tc/20) or less"); warn_below: keyword steps_per_contact.
  std::string why(double warn_below) const;
};

/// The check of a Hookean pair style `pair_style` whose constants `contact` has (its m_eff and
/// inertia set from the lightest grains, `lightest` kg), at DEM step dt; `split`: the lightest
/// grains count at their share in hybrid cells.
DemStepCheck check_dem_step(const std::string &pair_style, const HookeanContact &contact, double lightest, bool split,
                            double dt);

/// LIGGGHTS's Young's-modulus contact models (model hooke, model hertz) as its fix
/// check/timestep/gran estimates them, for a grain of radius r and mass m (density m over its
/// volume) of a material E, nu: the Rayleigh time pi r sqrt(rho / G) / (0.1631 nu + 0.8766),
/// G = E / (2 (1 + nu)), and the Hertz time of its collision with its like at relative speed v,
/// 2.87 (m^2 / (r/2 Y^2 v))^(1/5), Y = E / (2 (1 - nu^2)) (infinite for v = 0).
double rayleigh_time(double radius, double mass, double youngs, double poisson);
double hertz_time(double radius, double mass, double youngs, double poisson, double speed);
/// DEM practice asks for dt <= 0.2 of the Rayleigh time; the check counts twice the Rayleigh time
/// as a contact time, so that its kWarnStepsPerContact steps are that bound.
inline constexpr double kRayleighContactFactor = 2.0;
/// The check of such a model `model` ("hertz", "hooke") for the lightest grains (radius, mass
/// at their share where the coupling splits grains) at relative speed v, at DEM step dt: the
/// contact time is the shorter of the Hertz time and twice the Rayleigh time; the same steps per
/// contact as for Hookean pairs.
DemStepCheck check_elastic_step(const std::string &model, double radius, double mass, double youngs, double poisson,
                                double speed, bool split, double dt);

/// Whether a check's steps per contact call for a warning: fewer than warn_below (keyword
/// steps_per_contact), and 10 % fewer than at the last warning (`fewest_warned`, updated).
bool warn_poor_step(double steps, double warn_below, double &fewest_warned);
/// "Fix hybrid/mpm: the time step <dt> s resolves the contacts poorly <when>: <why>"
std::string poor_step_warning(double dt, const std::string &when, const std::string &why);

/// The velocity agreement's relaxation time (docs/design.md section 5.2): keyword relax's
/// `relax_time` if given (>= 0), else half the stiffest contact's duration, the time over which
/// grains in contact equalise their velocities: `steps_per_contact` DEM steps of `dt` (10 steps
/// where the contact time is unknown, steps_per_contact >= kBig).
double agreement_time(double relax_time, double steps_per_contact, double dt);

/// The warning for a pair style the check does not know.
std::string unchecked_pair_style(const std::string &pair_style);

}    // namespace coupler
