// Zones from continuum regions (coupler/zones.hpp): the box faces make no hybrid layers, also
// where a face lies off the cell lattice (a thin slab between side walls).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "coupler/grid_geometry.hpp"
#include "coupler/zones.hpp"

namespace {

using Vec3 = Eigen::Vector3d;

// A slab 0.012 thick in z on cells of 0.005: the last cell layer (z 0.010 to 0.015) straddles
// the face z = 0.012; the region is the block x < 0.03, y < 0.03 through the whole slab.
TEST(coupler_zones, FaceOffTheCellLatticeMakesNoLayer) {
  const Vec3 lower(0.0, 0.0, 0.0), upper(0.06, 0.06, 0.012);
  const auto grid = coupler::padded_grid<3>(lower, upper, 0.005);
  auto inside = [](const auto& x) { return x[0] < 0.03 && x[1] < 0.03; };
  const auto zones = coupler::zones_from_regions<3>(grid, lower, upper, 1, inside);
  int straddling_continuum = 0, beyond_region_continuum = 0;
  for (std::size_t c = 0; c < zones.size(); ++c) {
    const Vec3 x = coupler::cell_center(grid, coupler::cell_coords(grid, c));
    const bool in_xy = x[0] > 0 && x[0] < 0.06 && x[1] > 0 && x[1] < 0.06;
    if (!in_xy) continue;
    const bool straddles = x[2] > 0.010 && x[2] < 0.015;
    // deep in the region (two cells from its x and y borders): continuum in every z layer,
    // the straddling one included: the side walls make no hybrid layer
    if (x[0] < 0.02 && x[1] < 0.02 && x[2] > 0 && x[2] < 0.015) {
      EXPECT_EQ(zones[c], coupler::kContinuum) << "cell at " << x.transpose();
      straddling_continuum += straddles;
    }
    // outside the region: discrete, straddling layer included (its grains stay grains)
    if ((x[0] > 0.035 || x[1] > 0.035) && x[2] > 0 && x[2] < 0.015) {
      EXPECT_EQ(zones[c], coupler::kDiscrete) << "cell at " << x.transpose();
      beyond_region_continuum += straddles && zones[c] != coupler::kDiscrete;
    }
  }
  EXPECT_GT(straddling_continuum, 0);
  EXPECT_EQ(beyond_region_continuum, 0);
}

}  // namespace

// A mesh wall's triangles mark the cells they pass through: a square plate of two triangles
// across a 0.16 m box at z = 0.085 lies in one layer of 16 x 16 cells of 0.01 m; a triangle
// sticking out of the grid marks only the cells on it; a tilted one marks cells in several layers.
TEST(coupler_zones, MeshWallTrianglesMarkTheCellsTheyPassThrough) {
  const auto grid = coupler::padded_grid<3>(Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(0.16), 0.01);
  const double lo = 0.001, hi = 0.159, z = 0.085;
  const std::vector<double> plate = {lo, lo, z, hi, lo, z, hi, hi, z, lo, lo, z, hi, hi, z, lo, hi, z};
  const auto cells = coupler::cells_of_triangles(grid, plate);
  ASSERT_EQ(cells.size(), 256u);
  for (auto c : cells) {
    const Eigen::Vector3i ijk = coupler::cell_coords<3>(grid, c);
    EXPECT_EQ(ijk[2], coupler::kGridPad + 8);    // the layer 0.08 < z < 0.09
    EXPECT_GE(ijk[0], coupler::kGridPad);
    EXPECT_LT(ijk[0], coupler::kGridPad + 16);
  }
  EXPECT_TRUE(std::is_sorted(cells.begin(), cells.end()));
  // far outside the grid: nothing; partly outside: the cells on the grid only
  EXPECT_TRUE(coupler::cells_of_triangles(grid, {5, 5, 5, 6, 5, 5, 5, 6, 5}).empty());
  const auto edge = coupler::cells_of_triangles(grid, {-1.0, 0.005, 0.005, 1.0, 0.005, 0.005, 0.0, 0.0051, 0.005});
  EXPECT_EQ(edge.size(), static_cast<std::size_t>(grid.dims[0] - 1));    // the whole row along x
  // a triangle rising through the layers
  const auto tilted = coupler::cells_of_triangles(grid, {0.02, 0.02, 0.021, 0.05, 0.02, 0.049, 0.02, 0.025, 0.021});
  std::set<int> layers;
  for (auto c : tilted) layers.insert(coupler::cell_coords<3>(grid, c)[2]);
  EXPECT_EQ(layers, (std::set<int>{coupler::kGridPad + 2, coupler::kGridPad + 3, coupler::kGridPad + 4}));    // z 0.021 to 0.049
  // NaN vertices are skipped, not mapped
  EXPECT_TRUE(coupler::cells_of_triangles(grid, {std::nan(""), 0, 0, 0.1, 0.1, 0.1, 0.05, 0.05, 0.05}).empty());
}
