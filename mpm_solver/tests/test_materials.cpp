// Constitutive updates checked against their defining properties.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "mpm/materials.hpp"

namespace {

mpm::Material sand(double phi_deg) {
  mpm::Material m;
  m.name = "sand";
  m.model = mpm::ModelKind::DruckerPrager;
  m.drucker_prager.friction_angle_deg = phi_deg;
  return m;
}

template <int D>
void expect_inside_cone(const mpm::MaterialModel& model, const mpm::Mat<D>& stress) {
  const double p = -stress.trace() / D;
  const mpm::Mat<D> dev = stress + p * mpm::Mat<D>::Identity();
  EXPECT_GE(p, -1e-9 * (1 + stress.norm()));
  EXPECT_LE(dev.norm(), model.cone_slope<D>() * p + 1e-9 * (1 + stress.norm()));
}

template <int D>
void random_return_map_stays_in_cone() {
  const mpm::MaterialModel model(sand(30));
  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  int yielded = 0, dilated = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    mpm::Mat<D> be = mpm::Mat<D>::Identity(), stress = mpm::Mat<D>::Zero();
    double plastic = 0;
    // A few random deformation increments, biased to compression.
    for (int k = 0; k < 3; ++k) {
      mpm::Mat<D> L;
      for (int i = 0; i < D; ++i)
        for (int j = 0; j < D; ++j) L(i, j) = 0.02 * n01(rng);
      L -= 0.01 * mpm::Mat<D>::Identity();
      const mpm::Mat<D> f = mpm::Mat<D>::Identity() + L;
      const double before = plastic;
      mpm::update_drucker_prager<D>(model, f, be, stress, plastic);
      expect_inside_cone<D>(model, stress);
      EXPECT_TRUE((stress - stress.transpose()).norm() <= 1e-9 * (1 + stress.norm()));
      if (plastic > before) ++yielded;
      if (stress.isZero(0)) ++dilated;
    }
  }
  // The sample exercised all three branches.
  EXPECT_GT(yielded, 100);
  EXPECT_GT(dilated, 10);
}

}  // namespace

TEST(DruckerPrager, ReturnMapStaysInsideFrictionCone2D) { random_return_map_stays_in_cone<2>(); }
TEST(DruckerPrager, ReturnMapStaysInsideFrictionCone3D) { random_return_map_stays_in_cone<3>(); }

TEST(DruckerPrager, DilatedStateReturnsToZeroStress) {
  const mpm::MaterialModel model(sand(30));
  mpm::Mat<3> be = mpm::Mat<3>::Identity(), stress = mpm::Mat<3>::Zero();
  double plastic = 0;
  // First load it in compression so the stress is non-zero, then dilate.
  mpm::update_drucker_prager<3>(model, 0.999 * mpm::Mat<3>::Identity(), be, stress, plastic);
  ASSERT_GT(stress.norm(), 0);
  mpm::Mat<3> f = 1.01 * mpm::Mat<3>::Identity();
  f(0, 1) = 0.003;
  mpm::update_drucker_prager<3>(model, f, be, stress, plastic);
  EXPECT_TRUE(stress.isZero(0));
  EXPECT_TRUE(be.isIdentity(0));
}

TEST(DruckerPrager, SmallIsotropicCompressionIsElasticWithBulkModulus) {
  const mpm::MaterialModel model(sand(30));
  mpm::Mat<2> be = mpm::Mat<2>::Identity(), stress = mpm::Mat<2>::Zero();
  double plastic = 0;
  const double s = 1.0 - 1e-5;
  mpm::update_drucker_prager<2>(model, s * mpm::Mat<2>::Identity(), be, stress, plastic);
  EXPECT_EQ(plastic, 0.0);
  const double eps = std::log(s);
  const double expected = (2 * model.shear_modulus + 2 * model.lame_lambda) * eps / (s * s);  // Kirchhoff / J
  EXPECT_NEAR(stress(0, 0), expected, 1e-9 * std::abs(expected));
  EXPECT_NEAR(stress(0, 1), 0.0, 1e-9 * std::abs(expected));
}

namespace {
mpm::Material beads() {
  mpm::Material m;
  m.name = "beads";
  m.model = mpm::ModelKind::MuI;
  m.density = m.mu_i.critical_density * 1.001;
  return m;
}
}  // namespace

TEST(MuI, SteadySimpleShearFollowsMuOfI) {
  // Constant simple shear under a held pressure: the stress ratio must settle
  // on mu(I) with I = gammadot d / sqrt(p / rho_s).
  const mpm::Material mat = beads();
  const mpm::MaterialModel model(mat);
  const double p = 2000.0;
  for (double gammadot : {1.0, 20.0, 200.0}) {
    mpm::Mat<2> stress = -p * mpm::Mat<2>::Identity();
    mpm::Mat<2> L = mpm::Mat<2>::Zero();
    L(0, 1) = gammadot;  // v_x = gammadot * y
    double plastic = 0;
    const double dt = 1e-6;
    for (int k = 0; k < 20000; ++k) mpm::update_mu_i<2>(model, L, dt, mat.density, stress, plastic);
    const double pressure = -stress.trace() / 2;
    const mpm::Mat<2> dev = stress + pressure * mpm::Mat<2>::Identity();
    const double tau = dev.norm() / std::sqrt(2.0);
    const double I = gammadot * mat.mu_i.grain_diameter / std::sqrt(pressure / mat.mu_i.grain_density);
    const double mu = mat.mu_i.mu_s + (mat.mu_i.mu_2 - mat.mu_i.mu_s) / (mat.mu_i.I0 / I + 1);
    EXPECT_NEAR(pressure, p, 1e-6 * p) << "simple shear is isochoric";
    EXPECT_NEAR(tau / pressure, mu, 2e-3 * mu) << "gammadot = " << gammadot;
    EXPECT_GT(plastic, 0);
  }
}

TEST(MuI, DisconnectedBelowCriticalDensity) {
  const mpm::Material mat = beads();
  const mpm::MaterialModel model(mat);
  mpm::Mat<3> stress = -1000.0 * mpm::Mat<3>::Identity();
  double plastic = 0;
  mpm::update_mu_i<3>(model, mpm::Mat<3>::Zero(), 1e-5, 0.99 * mat.mu_i.critical_density, stress, plastic);
  EXPECT_TRUE(stress.isZero(0));
}

TEST(MuI, TensionIsStressFree) {
  const mpm::Material mat = beads();
  const mpm::MaterialModel model(mat);
  mpm::Mat<2> stress = mpm::Mat<2>::Zero();
  double plastic = 0;
  mpm::update_mu_i<2>(model, 0.5 * mpm::Mat<2>::Identity(), 1e-4, mat.density, stress, plastic);  // expansion
  EXPECT_TRUE(stress.isZero(0));
}

TEST(Materials, BadParametersNameTheMaterial) {
  mpm::Material m = sand(30);
  m.drucker_prager.poisson_ratio = 0.5;
  try {
    mpm::MaterialModel model(m);
    FAIL() << "expected a UserError";
  } catch (const mpm::UserError& e) {
    EXPECT_NE(std::string(e.what()).find("sand"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("poisson_ratio"), std::string::npos);
  }
}

namespace {
template <int D>
mpm::Mat<D> exact_function(const mpm::Mat<D>& a, double (*fn)(double)) {
  Eigen::SelfAdjointEigenSolver<mpm::Mat<D>> eig(a);
  mpm::Vec<D> values;
  for (int i = 0; i < D; ++i) values[i] = fn(eig.eigenvalues()[i]);
  return eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
}

template <int D>
void tensor_log_exp_match_spectral_definition() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  // Magnitudes on both sides of the series radius (0.01), up to large strains.
  for (double scale : {1e-6, 1e-3, 0.005, 0.0099, 0.0101, 0.05, 0.5}) {
    for (int trial = 0; trial < 50; ++trial) {
      mpm::Mat<D> X;
      for (int i = 0; i < D; ++i)
        for (int j = 0; j < D; ++j) X(i, j) = u(rng);
      X = (0.5 * (X + X.transpose())).eval();  // eval: X + X^T aliases in place
      X *= scale / X.norm();
      const mpm::Mat<D> b = mpm::Mat<D>::Identity() + X;
      const mpm::Mat<D> log_b = mpm::tensor_log<D>(b);
      const mpm::Mat<D> exact = exact_function<D>(b, [](double x) { return std::log(x); });
      // 2e-11: series truncation at the radius; 1e-14: round-off of the reference.
      EXPECT_LE((log_b - exact).norm(), 2e-11 * exact.norm() + 1e-14) << "scale " << scale;
      const mpm::Mat<D> back = mpm::tensor_exp<D>(log_b);
      EXPECT_LE((back - b).norm(), 1e-12 * b.norm()) << "exp(log b) = b, scale " << scale;
    }
  }
}
}  // namespace

TEST(TensorFunctions, NearlyIsotropicLargeStrainIsExact) {
  // Far outside the series radius with (nearly) equal eigenvalues: the 2D
  // closed form's divided-difference branch.
  for (double shear : {0.0, 1e-9, 1e-6}) {
    mpm::Mat<2> b = 0.8 * mpm::Mat<2>::Identity();
    b(0, 1) = b(1, 0) = shear;
    const mpm::Mat<2> exact = exact_function<2>(b, [](double x) { return std::log(x); });
    EXPECT_LE((mpm::tensor_log<2>(b) - exact).norm(), 1e-14) << shear;
    EXPECT_LE((mpm::tensor_exp<2>(exact) - b).norm(), 1e-14) << shear;
  }
}

TEST(TensorFunctions, LogAndExpMatchSpectralDefinition2D) { tensor_log_exp_match_spectral_definition<2>(); }
TEST(TensorFunctions, LogAndExpMatchSpectralDefinition3D) { tensor_log_exp_match_spectral_definition<3>(); }
