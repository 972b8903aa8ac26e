#include "coupler/dem_timestep.hpp"

#include "coupler/text.hpp"

namespace coupler {

DemStepCheck check_dem_step(const std::string &pair_style, const HookeanContact &contact, double lightest, bool split,
                            double dt) {
  DemStepCheck c;
  c.tc = contact_time(contact);
  c.steps = c.tc / dt;
  c.what = "the stiffest contact (pair style " + pair_style + ": kn = " + general(contact.kn, 6) +
           " N/m, kt = " + general(contact.kt, 6) + " N/m, gamma_n = " + general(contact.gamman, 6) +
           " 1/s; lightest grains " + general(lightest, 6) + " kg" +
           (split ? ", at their share in hybrid cells" : "") + ") lasts tc = " + general(c.tc, 6) + " s";
  return c;
}

std::string DemStepCheck::log_line(double dt) const {
  return "fix hybrid/mpm: DEM time step " + general(dt, 6) + " s: " + what + ", " + general(steps, 3) +
         " steps per contact";
}

std::string DemStepCheck::why(double warn_below) const {
  return what + ", and " + general(steps, 3) + " steps per contact (" +
         (unstable() ? std::string("fewer than pi/2") : "fewer than " + general(warn_below, 6)) + ") " +
         (unstable() ? "make velocity Verlet unstable"
                     : "resolve it poorly (a collision's energy balance drifts; keyword steps_per_contact sets this "
                       "threshold)") +
         ". Use timestep " + general(tc / kSafeStepsPerContact, 6) + " (tc/" + general(kSafeStepsPerContact, 6) +
         ") or less";
}

double rayleigh_time(double radius, double mass, double youngs, double poisson) {
  const double density = mass / (4.0 / 3.0 * M_PI * radius * radius * radius);
  const double shear_modulus = youngs / (2.0 * (1.0 + poisson));
  return M_PI * radius * std::sqrt(density / shear_modulus) / (0.1631 * poisson + 0.8766);
}

double hertz_time(double radius, double mass, double youngs, double poisson, double speed) {
  if (!(speed > 0)) return std::numeric_limits<double>::infinity();
  const double y_eff = youngs / (2.0 * (1.0 - poisson * poisson));
  return 2.87 * std::pow(mass * mass / (0.5 * radius * y_eff * y_eff * speed), 0.2);
}

DemStepCheck check_elastic_step(const std::string &model, double radius, double mass, double youngs, double poisson,
                                double speed, bool split, double dt) {
  const double rayleigh = rayleigh_time(radius, mass, youngs, poisson), hertz = hertz_time(radius, mass, youngs, poisson, speed);
  DemStepCheck c;
  c.tc = std::min(hertz, kRayleighContactFactor * rayleigh);
  c.steps = c.tc / dt;
  c.what = "the lightest grains (pair style gran model " + model + ", " + general(mass, 4) + " kg" +
           (split ? " at their share in hybrid cells" : "") + ", E " + general(youngs, 4) + " Pa, nu " +
           general(poisson, 3) + ") have the Hertz time " +
           (std::isfinite(hertz) ? general(hertz, 4) + " s at relative speed " + general(speed, 3) + " m/s"
                                 : std::string("of grains at rest (none)")) +
           " and the Rayleigh time " + general(rayleigh, 4) + " s (LIGGGHTS's estimates; the check takes the shorter "
           "of the Hertz time and twice the Rayleigh time, tc = " + general(c.tc, 4) + " s)";
  return c;
}

double agreement_time(double relax_time, double steps_per_contact, double dt) {
  if (relax_time >= 0.0) return relax_time;
  return 0.5 * (steps_per_contact < kBig ? steps_per_contact : 20.0) * dt;
}

bool warn_poor_step(double steps, double warn_below, double &fewest_warned) {
  if (steps >= warn_below || steps >= 0.9 * fewest_warned) return false;
  fewest_warned = steps;
  return true;
}

std::string poor_step_warning(double dt, const std::string &when, const std::string &why) {
  return "Fix hybrid/mpm: the time step " + general(dt, 6) + " s resolves the contacts poorly " + when + ": " + why;
}

std::string unchecked_pair_style(const std::string &pair_style) {
  return "Fix hybrid/mpm checks the DEM time step for pair styles gran/hooke and gran/hooke/history only; check it "
         "yourself for pair style " + pair_style + " (at least " + general(kSafeStepsPerContact, 6) +
         " steps per contact)";
}

}    // namespace coupler
