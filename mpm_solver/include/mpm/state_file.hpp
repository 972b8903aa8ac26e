#pragma once
// The exact state of the MPM side of a coupled run, saved next to the DEM host's
// restart file (<restart>.mpm.h5) and read back so that the run continues bit
// for bit. The layout of the HDF5 file is described in state_file.cpp.
#include <cstdint>
#include <string>
#include <vector>

#include "mpm/particles.hpp"
#include "mpm/types.hpp"

namespace mpm {

template <int D>
struct ContinuumState {
  Particles<D> points;                       ///< every field, exactly
  std::vector<std::int8_t> zones;            ///< one per grid cell
  std::vector<std::uint64_t> support_nodes;  ///< nodes with a support force
  std::vector<Vec<D>> support_forces;        ///< same length as support_nodes
  std::vector<double> support_masses;        ///< reduced mass each support force was set with, same length
  std::vector<double> support_budgets;       ///< energy each may still give the relative motion, same length
  std::vector<Vec<D>> support_gaps;          ///< v_dem - v_mpm the last agreement left, same length
  double time = 0;                           ///< DEM time of the continuum's state, s
  double solver_time = 0;                    ///< the MPM solver's own clock, s
  long solver_steps = 0;                     ///< MPM steps taken so far
  std::int64_t dem_step = 0;                 ///< DEM step at which it was saved
  std::int64_t exchanges = 0;
  double cell = 0;                           ///< grid cell size, m
  double box_lo[3] = {0, 0, 0}, box_hi[3] = {0, 0, 0};
  int model = 0;                             ///< coupler::ModelId
};

/// Writes `state` to `path` (truncating it). Throws UserError naming the path on failure,
/// std::invalid_argument if the state's arrays have inconsistent lengths.
template <int D>
void save_state(const std::string& path, const ContinuumState<D>& state);

/// Reads a state written by save_state. Throws UserError if the file is missing, is not an
/// MPM state file, is for another dimension or format version, or its arrays are inconsistent.
template <int D>
ContinuumState<D> load_state(const std::string& path);

}  // namespace mpm
