// The DEM time-step check: its contact time is the duration of a real two-grain collision, and
// the steps it allows integrate the contact with velocity Verlet (LAMMPS's fix nve/sphere).
#include <gtest/gtest.h>

#include <cmath>

#include "coupler/dem_timestep.hpp"

namespace {

// head-on collision of two grains (relative coordinate, effective mass) under
// F = -kn delta - m_eff gamman v, integrated with velocity Verlet at step dt; returns the
// time in contact and the rebound speed over the impact speed
struct Collision {
  double duration, restitution, max_energy_ratio;
};

Collision collide(const coupler::HookeanContact &c, double dt, double v0 = 1.0) {
  double x = 0, v = v0;    // x = overlap
  auto accel = [&](double x_, double v_) { return x_ > 0 ? -c.kn / c.m_eff * x_ - c.gamman * v_ : 0.0; };
  double a = accel(x, v), t = 0, max_ratio = 0;
  const double e0 = 0.5 * c.m_eff * v0 * v0;
  for (int n = 0; n < 10000000; ++n) {
    v += 0.5 * dt * a;
    x += dt * v;
    a = accel(x, v);    // LAMMPS's damping uses the half-step velocity too
    v += 0.5 * dt * a;
    t += dt;
    const double e = 0.5 * c.m_eff * v * v + (x > 0 ? 0.5 * c.kn * x * x : 0.0);
    max_ratio = std::max(max_ratio, e / e0);
    if (x <= 0 && v < 0) return {t, -v / v0, max_ratio};
    if (!std::isfinite(x) || std::fabs(x) > 1e6) return {t, INFINITY, INFINITY};
  }
  return {t, NAN, NAN};
}

TEST(DemTimestep, ContactTimeIsTheDurationOfADampedCollision) {
  coupler::HookeanContact c;
  c.kn = 2.0e5, c.kt = 2.0 / 7.0 * c.kn, c.m_eff = 0.5 * 3.3e-3, c.inertia = 0.5;
  const double e = 0.5, zeta = -std::log(e) / std::sqrt(M_PI * M_PI + std::log(e) * std::log(e));
  c.gamman = 2 * zeta * std::sqrt(c.kn / c.m_eff);
  const double tc = coupler::contact_time(c);
  const Collision fine = collide(c, tc / 20000);
  EXPECT_NEAR(fine.duration, tc, 1e-3 * tc);
  EXPECT_NEAR(fine.restitution, e, 2e-3);
}

TEST(DemTimestep, TangentialStiffnessRaisedByRotationCanSetTheContactTime) {
  coupler::HookeanContact c;
  c.kn = 1.0e4, c.m_eff = 1.0e-3, c.inertia = 0.4;
  c.kt = 2.0 / 7.0 * c.kn;    // the classic choice: tangential and normal frequencies equal
  EXPECT_NEAR(coupler::contact_time(c), M_PI / std::sqrt(c.kn / c.m_eff), 1e-12);
  c.kt = c.kn;                // 3.5 times stiffer in rotation-coupled sliding
  EXPECT_NEAR(coupler::contact_time(c), M_PI / std::sqrt(3.5 * c.kn / c.m_eff), 1e-12);
  c.kt = 0, c.gamman = 4 * std::sqrt(c.kn / c.m_eff);    // overdamped: the undamped frequency
  EXPECT_NEAR(coupler::contact_time(c), M_PI / std::sqrt(c.kn / c.m_eff), 1e-12);
}

TEST(DemTimestep, AllowedStepsResolveTheContactAndTooLongOnesDoNot) {
  coupler::HookeanContact c;
  c.kn = 1.0e5, c.kt = 2.0 / 7.0 * c.kn, c.m_eff = 1.0e-3;    // elastic: energy must come back
  const double tc = coupler::contact_time(c);
  for (double steps : {coupler::kSafeStepsPerContact, coupler::kWarnStepsPerContact}) {
    const Collision r = collide(c, tc / steps);
    EXPECT_NEAR(r.restitution, 1.0, 0.02) << steps << " steps per contact";
    EXPECT_LT(r.max_energy_ratio, 1.03) << steps << " steps per contact";
  }
  // beyond Verlet's limit dt = 2/omega = (2/pi) tc the contact blows up
  const Collision unstable = collide(c, 0.7 * tc);
  EXPECT_FALSE(unstable.max_energy_ratio < 2.0);
}

}    // namespace

// The check's words, as the fix logs them and tests/test_coupled_launch.py reads them
TEST(DemStepCheck, NamesTheContactTheStepsAndTheSafeStep) {
  coupler::HookeanContact c;
  c.kn = 1000, c.kt = 0, c.gamman = 500, c.inertia = 0.4;
  const double m = 2500 * 4.0 / 3.0 * M_PI * 1e-9;    // 2 mm grains of 2500 kg/m^3
  c.m_eff = 0.5 * m;
  const auto fine = coupler::check_dem_step("gran/hooke/history", c, m, false, 1e-5);
  EXPECT_NEAR(fine.steps, fine.tc / 1e-5, 1e-9);
  EXPECT_FALSE(fine.unstable());
  EXPECT_EQ(fine.what.rfind("the stiffest contact (pair style gran/hooke/history: kn = 1000 N/m, kt = 0 N/m, "
                            "gamma_n = 500 1/s; lightest grains 1.0472e-05 kg) lasts tc = ",
                            0),
            0u)
      << fine.what;
  EXPECT_EQ(fine.log_line(1e-5).rfind("fix hybrid/mpm: DEM time step 1e-05 s: the stiffest contact", 0), 0u);
  const auto coarse = coupler::check_dem_step("gran/hooke", c, m, true, 2e-4);
  EXPECT_TRUE(coarse.unstable());
  EXPECT_NE(coarse.what.find("kg, at their share in hybrid cells) lasts"), std::string::npos);
  const std::string why = coarse.why(10);
  EXPECT_NE(why.find("steps per contact (fewer than pi/2) make velocity Verlet unstable. Use timestep "),
            std::string::npos)
      << why;
  EXPECT_NE(why.find(" (tc/20) or less"), std::string::npos) << why;
  const auto poor = coupler::check_dem_step("gran/hooke", c, m, false, 5e-5);
  EXPECT_NE(poor.why(12.5).find("(fewer than 12.5) resolve it poorly (a collision's energy balance drifts; keyword "
                                "steps_per_contact sets this threshold)"),
            std::string::npos);
  EXPECT_EQ(coupler::unchecked_pair_style("gran/hertz/history"),
            "Fix hybrid/mpm checks the DEM time step for pair styles gran/hooke and gran/hooke/history only; check it "
            "yourself for pair style gran/hertz/history (at least 20 steps per contact)");
}
