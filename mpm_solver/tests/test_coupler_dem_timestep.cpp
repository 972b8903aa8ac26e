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

// LIGGGHTS's Hertz time is the duration of a Hertzian collision, F = 4/3 Y sqrt(r/2) delta^1.5
// between two grains of radius r (Y = E / (2 (1 - nu^2)), r/2 their effective radius), for the
// effective mass it is given: integrated here with velocity Verlet at a fine step
TEST(ElasticStepCheck, HertzTimeIsTheDurationOfAHertzianCollision) {
  const double r = 0.001, m_eff = 0.5 * 2500 * 4.0 / 3.0 * M_PI * r * r * r, E = 5e6, nu = 0.3, v0 = 0.5;
  const double y = E / (2 * (1 - nu * nu)), k = 4.0 / 3.0 * y * std::sqrt(0.5 * r);
  const double estimate = coupler::hertz_time(r, m_eff, E, nu, v0);
  const double dt = estimate / 200000;
  double x = 0, v = v0, t = 0;
  auto accel = [&](double x_) { return x_ > 0 ? -k / m_eff * std::pow(x_, 1.5) : 0.0; };
  double a = accel(x);
  do {
    v += 0.5 * dt * a;
    x += dt * v;
    a = accel(x);
    v += 0.5 * dt * a;
    t += dt;
  } while (x > 0);
  EXPECT_NEAR(estimate, t, 0.002 * t);    // 2.87 is 2.868 rounded
  EXPECT_TRUE(std::isinf(coupler::hertz_time(r, m_eff, E, nu, 0.0)));
  // slower collisions last longer: t ~ v^(-1/5)
  EXPECT_NEAR(coupler::hertz_time(r, m_eff, E, nu, v0 / 32) / estimate, 2.0, 1e-12);
}

TEST(ElasticStepCheck, RayleighTimeAndTheShorterOfTheTwo) {
  const double r = 0.001, m = 2500 * 4.0 / 3.0 * M_PI * r * r * r, E = 5e6, nu = 0.3;
  // pi r sqrt(rho / G) / (0.1631 nu + 0.8766), G = E / 2.6
  EXPECT_NEAR(coupler::rayleigh_time(r, m, E, nu), M_PI * r * std::sqrt(2500 * 2.6 / E) / 0.92553, 1e-15);
  // a rigid-ish material at low speed: the Rayleigh bound decides
  const auto slow = coupler::check_elastic_step("hertz", r, m, 5e9, nu, 0.01, false, 1e-6);
  EXPECT_DOUBLE_EQ(slow.tc, coupler::kRayleighContactFactor * coupler::rayleigh_time(r, m, 5e9, nu));
  EXPECT_DOUBLE_EQ(slow.steps, slow.tc / 1e-6);
  // a soft one at high speed: the Hertz time
  const auto fast = coupler::check_elastic_step("hooke", r, m, 1e5, nu, 5.0, true, 1e-5);
  EXPECT_DOUBLE_EQ(fast.tc, coupler::hertz_time(r, m, 1e5, nu, 5.0));
  EXPECT_NE(fast.what.find("pair style gran model hooke"), std::string::npos) << fast.what;
  EXPECT_NE(fast.what.find("at their share in hybrid cells"), std::string::npos) << fast.what;
  // grains at rest: the Rayleigh time only
  const auto rest = coupler::check_elastic_step("hertz", r, m, E, nu, 0.0, false, 1e-5);
  EXPECT_TRUE(std::isfinite(rest.tc));
  EXPECT_NE(rest.what.find("of grains at rest (none)"), std::string::npos) << rest.what;
}

TEST(DemTimestep, AgreementTimeIsHalfTheContactOrTheKeyword) {
  // 20 steps per contact of 1e-5 s: half of it; keyword relax wins, 0 included; unknown: 10 steps
  EXPECT_DOUBLE_EQ(coupler::agreement_time(-1.0, 20.0, 1e-5), 1e-4);
  EXPECT_DOUBLE_EQ(coupler::agreement_time(3e-4, 20.0, 1e-5), 3e-4);
  EXPECT_DOUBLE_EQ(coupler::agreement_time(0.0, 20.0, 1e-5), 0.0);
  EXPECT_DOUBLE_EQ(coupler::agreement_time(-1.0, 1.0e20, 1e-5), 1e-4);
}
