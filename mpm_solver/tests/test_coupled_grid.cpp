// The grid both sides of a coupled run build: the DEM side from its options and box
// (coupler::run_grid), the MPM process from the handshake (coupled_scene). Their nodes must be
// the same, and the container faces the continuum touches must be node planes.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "coupler/dem_coupling.hpp"
#include "coupler/fix_options.hpp"
#include "mpm/coupled_continuum.hpp"
#include "mpm/solver.hpp"

namespace {

coupler::FixOptions silo_options(const std::vector<std::string>& touch) {
  std::vector<std::string> words = {"adaptive", "10", "container", "0", "0.32", "0", "INF"};
  for (const auto& face : touch) words.insert(words.end(), {"touch", face});
  auto opt = coupler::parse_fix_options(words, 2, 1, [](const std::string&) { return false; });
  opt.continuum.grain_diameter = 0.002;
  opt.continuum.gravity[1] = -9.81;
  opt.continuum.agreement_time = 1e-5;
  return opt;
}

template <int D>
void expect_same_nodes(const coupler::GridGeometry<D>& dem, const coupler::GridGeometry<D>& mpm) {
  EXPECT_EQ(dem.dx, mpm.dx);
  for (int a = 0; a < D; ++a) {
    EXPECT_EQ(dem.origin[a], mpm.origin[a]) << "axis " << a;
    EXPECT_EQ(dem.dims[a], mpm.dims[a]) << "axis " << a;
  }
}

TEST(CoupledGrid, BothSidesLayTheSameNodesWithTouchedFacesOnNodePlanes) {
  const double lo[3] = {-0.004, -0.1, -0.5}, hi[3] = {0.324, 2.0, 0.5};
  for (const auto& touch : std::vector<std::vector<std::string>>{{}, {"xlo", "xhi"}, {"xhi"}, {"ylo"}}) {
    coupler::FixOptions opt = silo_options(touch);
    std::string problem;
    coupler::grid_of_run(opt, 2, 1000, lo, hi, problem);
    ASSERT_EQ(problem, "");
    const coupler::Hello hello = coupler::make_hello(opt, "test", "si", 2, 1e-6, lo, hi, 0, 0.0, problem);
    ASSERT_EQ(problem, "");
    const mpm::Solver<2> solver(mpm::coupled_scene(hello));
    const auto dem = coupler::run_grid<2>(opt, lo, hi);
    expect_same_nodes<2>(dem, solver.grid());
    // every touched face is a node plane
    for (const auto& face : touch) {
      const int axis = face[0] - 'x';
      const double plane = face.substr(1) == "lo" ? opt.container_edge(axis, 0, lo, hi)
                                                  : opt.container_edge(axis, 1, lo, hi);
      const double nodes = (plane - dem.origin[axis]) / dem.dx;
      EXPECT_NEAR(nodes, std::round(nodes), 1e-9) << face;
    }
  }
}

}  // namespace
