#pragma once
// HDF5 snapshots of the material points (and optionally grid fields), with an
// XDMF sidecar so that ParaView opens a whole run in one step.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mpm/grid.hpp"
#include "mpm/particles.hpp"
#include "mpm/scene.hpp"

namespace mpm {

/// Grains of a coupled run's frame (the DEM side), written next to the points.
struct GrainFrame {
  std::vector<std::int64_t> id;
  std::vector<double> x, v;            ///< 3 values per grain (also in 2D, z = 0)
  std::vector<double> radius, mass, weight;  ///< mass: the mass the grain carries (weight * its full mass)
  std::vector<std::int8_t> zone;       ///< 0 discrete, 1 hybrid, 2 continuum (coupler::Zone)
  std::size_t size() const { return id.size(); }
};

/// Coupling fields of the points of a frame (coupled runs).
struct PointCoupling {
  std::vector<std::int8_t> zone;   ///< zone of the point's cell
  std::vector<double> weight;      ///< share of its cell's material the point carries
};

template <int D>
class SnapshotWriter {
 public:
  /// Creates `directory` if needed and the file `directory`/points.h5 (truncating it).
  SnapshotWriter(const std::string& directory, const Scene& scene);
  ~SnapshotWriter();
  SnapshotWriter(const SnapshotWriter&) = delete;
  SnapshotWriter& operator=(const SnapshotWriter&) = delete;

  /// Appends one frame; rewrites the XDMF sidecars so they are valid after every frame.
  /// Coupled runs also pass the frame's grains (-> /frames/NNNNNN/grains and grains.xdmf)
  /// and the points' zone and weight. Arrays of inconsistent lengths throw
  /// std::invalid_argument and write nothing.
  void write(const Particles<D>& points, const Grid<D>& grid, double time, long step,
             const GrainFrame* grains = nullptr, const PointCoupling* coupling = nullptr);
  int frames_written() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mpm
