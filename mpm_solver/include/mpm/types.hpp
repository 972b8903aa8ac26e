#pragma once
#include <Eigen/Dense>
#include <stdexcept>
#include <string>

namespace mpm {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;
template <int D>
using Mat = Eigen::Matrix<double, D, D>;
template <int D>
using IVec = Eigen::Matrix<int, D, 1>;

/// An error in the user's scene or run that the user can fix; the message says how.
struct UserError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace mpm
