#pragma once
// Geometry of the background grid that both sides of a coupled run share:
// where node i sits and how nodes are numbered. The MPM grid stores fields on
// it; the DEM side uses it to transfer grains to the same nodes.
#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace coupler {

template <int D>
struct GridGeometry {
  using Vec = Eigen::Matrix<double, D, 1>;
  using IVec = Eigen::Matrix<int, D, 1>;

  double dx = 0;
  Vec origin = Vec::Zero();  ///< position of node 0
  IVec dims = IVec::Zero();  ///< nodes per axis

  std::size_t num_nodes() const {
    std::size_t n = 1;
    for (int a = 0; a < D; ++a) n *= static_cast<std::size_t>(dims[a]);
    return n;
  }
  /// Row-major flat index, last axis fastest.
  std::size_t index(const IVec& i) const {
    std::size_t k = static_cast<std::size_t>(i[0]);
    for (int a = 1; a < D; ++a) k = k * static_cast<std::size_t>(dims[a]) + static_cast<std::size_t>(i[a]);
    return k;
  }
  /// Stride of one step along axis a in the flat index.
  std::size_t stride(int a) const {
    std::size_t s = 1;
    for (int b = D - 1; b > a; --b) s *= static_cast<std::size_t>(dims[b]);
    return s;
  }
  IVec node_of(std::size_t k) const {
    IVec i;
    for (int a = D - 1; a >= 0; --a) {
      i[a] = static_cast<int>(k % static_cast<std::size_t>(dims[a]));
      k /= static_cast<std::size_t>(dims[a]);
    }
    return i;
  }
  Vec node_position(const IVec& i) const { return origin + dx * i.template cast<double>(); }
  /// Position in cell units from the origin: the input of the transfer stencil.
  Vec to_cell_units(const Vec& x) const { return (x - origin) / dx; }
  /// True if the quadratic stencil of a point at x lies on the grid.
  bool stencil_on_grid(const Vec& x) const {
    const Vec xi = to_cell_units(x);
    return (xi.array() >= 0.5).all() && (xi.array() < dims.template cast<double>().array() - 1.5).all();
  }
};

/// Cells of padding past the domain on every side: the quadratic stencil of any point
/// within 1.5 cells outside the domain stays on the grid.
inline constexpr int kGridPad = 3;

/// The grid over the box [lower, upper] with cell size `cell`: node 0 sits kGridPad cells
/// below `lower`. Both sides of a coupled run build it from the DEM box, so their node
/// numbers agree.
template <int D>
GridGeometry<D> padded_grid(const Eigen::Matrix<double, D, 1>& lower, const Eigen::Matrix<double, D, 1>& upper,
                            double cell) {
  GridGeometry<D> g;
  g.dx = cell;
  g.origin = lower.array() - kGridPad * cell;
  for (int a = 0; a < D; ++a)
    g.dims[a] = static_cast<int>(std::ceil((upper[a] - lower[a]) / cell)) + 2 * kGridPad + 1;
  return g;
}

/// A face of the box, as a bit of a face mask (ContinuumSettings::touched_faces, the fix's
/// `touch`): side 0 is the lower face of the axis, 1 the upper.
inline constexpr std::uint32_t face_bit(int axis, int side) { return 1u << (2 * axis + side); }

/// No wall plane on an axis (touched_walls, padded_grid with walls).
inline constexpr double kNoWall = std::numeric_limits<double>::quiet_NaN();
inline constexpr std::array<double, 3> kNoWalls = {kNoWall, kNoWall, kNoWall};

/// Per axis, the plane of the container's faces the continuum may touch (`touched`, face_bit):
/// the lower face's if it is touched, else the upper face's, else NaN (none). The grid lays its
/// nodes on these planes (padded_grid with walls).
inline std::array<double, 3> touched_walls(const double container_lo[3], const double container_hi[3],
                                           std::uint32_t touched) {
  std::array<double, 3> wall = kNoWalls;
  for (int a = 0; a < 3; ++a) {
    if (touched & face_bit(a, 0)) wall[a] = container_lo[a];
    else if (touched & face_bit(a, 1)) wall[a] = container_hi[a];
    if (!std::isfinite(wall[a])) wall[a] = kNoWall;
  }
  return wall;
}

/// padded_grid whose nodes are laid so that on each axis with a finite `wall[a]` (touched_walls)
/// that plane is a plane of nodes: node 0 moves down by less than a cell. The MPM applies a wall
/// at the nodes on or beyond it, so a face inside a cell would stand up to a cell past the
/// grains' wall, and the cell across it (discrete, its centre beyond the face) would turn the
/// points that drift into it into rests every rezone (docs/design.md 5.1, "The grid and the
/// walls the continuum touches").
template <int D>
GridGeometry<D> padded_grid(const Eigen::Matrix<double, D, 1>& lower, const Eigen::Matrix<double, D, 1>& upper,
                            double cell, const std::array<double, 3>& wall) {
  Eigen::Matrix<double, D, 1> start = lower;
  for (int a = 0; a < D; ++a)
    if (std::isfinite(wall[a])) start[a] = wall[a] - std::ceil((wall[a] - lower[a]) / cell - 1e-9) * cell;
  return padded_grid<D>(start, upper, cell);
}

}  // namespace coupler
