// The hybrid-zone velocity agreement conserves the weighted momentum of both
// sides exactly and makes them agree at every shared node.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "coupler/flow_regime.hpp"
#include "coupler/protocol.hpp"
#include "coupler/transfer.hpp"

namespace {

template <int D>
struct Scene {
  coupler::GridGeometry<D> grid;
  std::vector<double> x, v, mass, weight;  // grains, stride 3 like LAMMPS
  coupler::GrainView view() const {
    coupler::GrainView g;
    g.count = mass.size();
    g.x = x.data();
    g.v = v.data();
    g.mass = mass.data();
    g.weight = weight.data();
    return g;
  }
};

template <int D>
Scene<D> random_scene(unsigned seed, std::size_t n) {
  Scene<D> s;
  s.grid.dx = 0.01;
  s.grid.origin.setConstant(-0.03);
  s.grid.dims.setConstant(20);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (std::size_t g = 0; g < n; ++g) {
    for (int a = 0; a < 3; ++a) {
      s.x.push_back(a < D ? 0.02 + 0.08 * u(rng) : 0.0);
      s.v.push_back(a < D ? 2 * u(rng) - 1 : 0.0);
    }
    s.mass.push_back(1e-3 * (0.5 + u(rng)));
    s.weight.push_back(u(rng));
  }
  return s;
}

template <int D>
void agreement_conserves_and_agrees() {
  using V = Eigen::Matrix<double, D, 1>;
  const Scene<D> s = random_scene<D>(5, 300);
  const auto view = s.view();
  coupler::GrainTransfer<D> transfer(s.grid);
  const auto dem = transfer.to_nodes(view);
  ASSERT_FALSE(dem.empty());

  // Weighted grain totals are what the nodes hold.
  double m_total = 0;
  V p_grains = V::Zero();
  for (std::size_t g = 0; g < view.count; ++g) {
    m_total += s.weight[g] * s.mass[g];
    p_grains += s.weight[g] * s.mass[g] * Eigen::Map<const V>(&s.v[g * 3]);
  }
  double m_nodes = 0;
  V p_nodes = V::Zero();
  for (const auto& n : dem) m_nodes += n.mass, p_nodes += n.momentum;
  EXPECT_NEAR(m_nodes, m_total, 1e-14 * m_total);
  EXPECT_LE((p_nodes - p_grains).norm(), 1e-14 * (1 + p_grains.norm()));

  // An MPM field on the same nodes, and the agreement.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> m_mpm(dem.size());
  std::vector<V> p_mpm(dem.size()), lambda(dem.size());
  V p_before = p_grains;
  for (std::size_t i = 0; i < dem.size(); ++i) {
    m_mpm[i] = 1e-3 * (1.5 + u(rng));
    for (int a = 0; a < D; ++a) p_mpm[i][a] = m_mpm[i] * u(rng);
    p_before += p_mpm[i];
    lambda[i] = coupler::agreement_impulse<D>(m_mpm[i], p_mpm[i], dem[i].mass, dem[i].momentum);
    const V mpm_after = p_mpm[i] - lambda[i], dem_after = dem[i].momentum + lambda[i];
    // Both sides hold the common node velocity, and the node's total is unchanged
    // (round-off measured against the node's momentum scale).
    const V common = (p_mpm[i] + dem[i].momentum) / (m_mpm[i] + dem[i].mass);
    const double scale = p_mpm[i].norm() + dem[i].momentum.norm() + m_mpm[i] * common.norm();
    EXPECT_LE((mpm_after - m_mpm[i] * common).norm(), 1e-14 * scale);
    EXPECT_LE((dem_after - dem[i].mass * common).norm(), 1e-14 * scale);
    EXPECT_LE((mpm_after + dem_after - p_mpm[i] - dem[i].momentum).norm(), 1e-15 * scale);
  }

  // Both grain updates (impulse, field), their blend and a blend that differs from node to node
  // (pic regime) carry exactly sum(lambda) into the weighted grain momentum; the field update
  // leaves each grain at the interpolated field.
  std::vector<coupler::AgreedNode<D>> agreed(dem.size());
  for (std::size_t i = 0; i < dem.size(); ++i) {
    agreed[i].velocity = (p_mpm[i] + dem[i].momentum) / (m_mpm[i] + dem[i].mass);
    agreed[i].impulse_per_mass = lambda[i] / dem[i].mass;
  }
  for (double pic : {0.0, 0.3, 1.0, coupler::kPicRegime}) {
    for (std::size_t i = 0; i < dem.size(); ++i)  // per node: shares spread over [0, 1]
      agreed[i].field_share = pic == coupler::kPicRegime ? std::fmod(0.618 * static_cast<double>(i), 1.0) : pic;
    std::vector<double> dv(view.count * D);
    transfer.velocity_updates(view, agreed, dv.data());
    V p_after = V::Zero();
    for (std::size_t g = 0; g < view.count; ++g)
      p_after += s.weight[g] * s.mass[g] * (Eigen::Map<const V>(&s.v[g * 3]) + Eigen::Map<const V>(&dv[g * D]));
    for (std::size_t i = 0; i < dem.size(); ++i) p_after += p_mpm[i] - lambda[i];
    EXPECT_LE((p_after - p_before).norm(), 1e-13 * p_before.norm()) << "pic " << pic;
    if (pic == 1.0) {
      for (std::size_t g = 0; g < view.count; ++g) {
        V field = V::Zero();
        const V x = Eigen::Map<const V>(&s.x[g * 3]);
        coupler::for_each_stencil_node<D>(coupler::QuadraticStencil<D>(s.grid.to_cell_units(x)), s.grid,
                                          [&](std::size_t node, double w, const auto&) {
                                            for (std::size_t i = 0; i < dem.size(); ++i)
                                              if (dem[i].node == node) field += w * agreed[i].velocity;
                                          });
        const V v_after = Eigen::Map<const V>(&s.v[g * 3]) + Eigen::Map<const V>(&dv[g * D]);
        EXPECT_LE((v_after - field).norm(), 1e-14 * (1 + field.norm())) << "grain " << g;
      }
    }
  }
}

}  // namespace

TEST(CouplerTransfer, AgreementConservesWeightedMomentum2D) { agreement_conserves_and_agrees<2>(); }
TEST(CouplerTransfer, AgreementConservesWeightedMomentum3D) { agreement_conserves_and_agrees<3>(); }

TEST(CouplerFlowRegime, InertialNumberAndFieldShare) {
  // simple shear at rate 2 /s under pressure 100 Pa: I = gammadot d sqrt(rho / p)
  Eigen::Matrix2d L;
  L << 0, 2.0, 0, 0;
  const Eigen::Matrix2d stress = -100.0 * Eigen::Matrix2d::Identity();
  const double I = coupler::inertial_number<2>(L, stress, 1e-3, 2500.0);
  EXPECT_NEAR(I, 2.0 * 1e-3 * std::sqrt(25.0), 1e-15);
  // a uniform expansion has no shear; a spin neither
  Eigen::Matrix3d dilation = Eigen::Matrix3d::Identity(), spin = Eigen::Matrix3d::Zero();
  spin(0, 1) = 1.0, spin(1, 0) = -1.0;
  EXPECT_EQ(coupler::inertial_number<3>(dilation, -Eigen::Matrix3d::Identity(), 1e-3, 2500.0), 0.0);
  EXPECT_EQ(coupler::inertial_number<3>(spin, -Eigen::Matrix3d::Identity(), 1e-3, 2500.0), 0.0);
  // no pressure: free when shearing, at rest when not
  EXPECT_EQ(coupler::inertial_number<2>(L, Eigen::Matrix2d::Zero(), 1e-3, 2500.0), HUGE_VAL);
  EXPECT_EQ(coupler::inertial_number<2>(Eigen::Matrix2d::Zero(), Eigen::Matrix2d::Zero(), 1e-3, 2500.0), 0.0);
  // the field rule where quasi-static, the impulse rule where flowing, log-linear between
  EXPECT_EQ(coupler::field_share(0.0), 1.0);
  EXPECT_EQ(coupler::field_share(coupler::kQuasiStaticInertialNumber), 1.0);
  EXPECT_NEAR(coupler::field_share(std::sqrt(coupler::kQuasiStaticInertialNumber * coupler::kFlowingInertialNumber)),
              0.5, 1e-12);
  EXPECT_EQ(coupler::field_share(coupler::kFlowingInertialNumber), 0.0);
  EXPECT_EQ(coupler::field_share(HUGE_VAL), 0.0);
  EXPECT_LT(coupler::field_share(4e-3), coupler::field_share(2e-3));
  // the still share: 1 up to the rest speed, 0 from kStillSpeeds times it, log-linear between
  EXPECT_EQ(coupler::still_share(0.0, 1e-3), 1.0);
  EXPECT_EQ(coupler::still_share(1e-3, 1e-3), 1.0);
  EXPECT_NEAR(coupler::still_share(std::sqrt(coupler::kStillSpeeds) * 1e-3, 1e-3), 0.5, 1e-12);
  EXPECT_EQ(coupler::still_share(coupler::kStillSpeeds * 1e-3, 1e-3), 0.0);
  EXPECT_LT(coupler::still_share(4e-3, 1e-3), coupler::still_share(2e-3, 1e-3));
  // without a rest speed (no gravity) only material at rest is still
  EXPECT_EQ(coupler::still_share(0.0, 0.0), 1.0);
  EXPECT_EQ(coupler::still_share(1e-9, 0.0), 0.0);
}
