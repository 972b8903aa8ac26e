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

std::string unchecked_pair_style(const std::string &pair_style) {
  return "Fix hybrid/mpm checks the DEM time step for pair styles gran/hooke and gran/hooke/history only; check it "
         "yourself for pair style " + pair_style + " (at least " + general(kSafeStepsPerContact, 6) +
         " steps per contact)";
}

}    // namespace coupler
