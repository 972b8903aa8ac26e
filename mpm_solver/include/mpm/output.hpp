#pragma once
// HDF5 snapshots of the material points (and optionally grid fields), with an
// XDMF sidecar so that ParaView opens a whole run in one step.
#include <memory>
#include <string>

#include "mpm/grid.hpp"
#include "mpm/particles.hpp"
#include "mpm/scene.hpp"

namespace mpm {

template <int D>
class SnapshotWriter {
 public:
  /// Creates `directory` if needed and the file `directory`/points.h5 (truncating it).
  SnapshotWriter(const std::string& directory, const Scene& scene);
  ~SnapshotWriter();
  SnapshotWriter(const SnapshotWriter&) = delete;
  SnapshotWriter& operator=(const SnapshotWriter&) = delete;

  /// Appends one frame; rewrites the XDMF sidecar so it is valid after every frame.
  void write(const Particles<D>& points, const Grid<D>& grid, double time, long step);
  int frames_written() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mpm
