#pragma once
// Quadratic B-spline transfer kernel shared by the MPM grid and the grain <-> grid
// transfers of the coupling, so that both sides weight nodes identically.
#include <Eigen/Core>
#include <array>
#include <cmath>

namespace coupler {

/// Weights of the 3^D nodes around one point, in grid units.
/// Node (base + k) for k in {0,1,2}^D has weight prod_a w[a][k_a] and offset
/// (k - frac) * dx from the point.
template <int D>
struct QuadraticStencil {
  Eigen::Matrix<int, D, 1> base;      ///< lowest node index of the stencil
  Eigen::Matrix<double, D, 1> frac;   ///< point position relative to base, in cells
  std::array<std::array<double, 3>, D> w;

  /// `xi` is the point position in cell units measured from the grid origin.
  explicit QuadraticStencil(const Eigen::Matrix<double, D, 1>& xi) {
    for (int a = 0; a < D; ++a) {
      const int b = static_cast<int>(std::floor(xi[a] - 0.5));
      const double f = xi[a] - b;  // in [0.5, 1.5)
      base[a] = b;
      frac[a] = f;
      w[a][0] = 0.5 * (1.5 - f) * (1.5 - f);
      w[a][1] = 0.75 - (f - 1.0) * (f - 1.0);
      w[a][2] = 0.5 * (f - 0.5) * (f - 0.5);
    }
  }
};

/// APIC/MLS inertia-like factor: for quadratic B-splines D_p = dx^2/4 I, so the
/// affine velocity estimate is C = (4/dx^2) sum_i w_i v_i (x_i - x_p)^T.
inline constexpr double kQuadraticInverseInertia = 4.0;

}  // namespace coupler
