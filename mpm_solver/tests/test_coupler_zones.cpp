// Zones from continuum regions (coupler/zones.hpp): the box faces make no hybrid layers, also
// where a face lies off the cell lattice (a thin slab between side walls).
#include <gtest/gtest.h>

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
