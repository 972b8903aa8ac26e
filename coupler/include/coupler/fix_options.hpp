#pragma once
// The options of the DEM side's fix (LAMMPS's fix hybrid/mpm; docs/fix_hybrid_mpm.md,
// "Syntax"): its keyword table, their defaults and every check of their values. Host-neutral:
// a host's fix hands its keyword/value words to parse_fix_options and turns an OptionError
// into its own input error ("Illegal fix hybrid/mpm command: " + what()).

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "coupler/dem_timestep.hpp"
#include "coupler/grid_geometry.hpp"
#include "coupler/material_file.hpp"
#include "coupler/protocol.hpp"
#include "coupler/rezone_log.hpp"
#include "coupler/tuning.hpp"

namespace coupler {

/// A bad fix line: what() names the keyword and the value it needs.
struct OptionError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// Every keyword's value, at its default unless the fix line gave it.
struct FixOptions {
  double cell = -1.0;             ///< MPM grid cell size, m (<= 0 until chosen from the grains)
  double reply_timeout = 30.0;    ///< s the DEM side waits for each reply of the MPM process
  double idle_timeout = 600.0;    ///< s the MPM process waits for the next message (0 = forever)
  int model = kModelDruckerPrager;
  int every = 1;                  ///< exchange every this many steps
  bool every_auto = false;        ///< keyword `every auto`: `every` from the continuum's stable step at the first run
                                  ///< (the default with adaptive zones)
  int hybrid_width = 2;           ///< cells of hybrid zone inside the continuum regions' border
  int adapt_every = 0;            ///< the zone oracle every this many steps (0 = fixed zones)
  int grain_type = 0;             ///< atom type of grains made from points (0 = the group's smallest)
  int template_seed = 12345;      ///< seed of the packing template new grains are cut from
  double inertia = -1.0;          ///< I = inertia m r^2 (after parsing: 0.5 in 2D, 0.4 in 3D unless given)
  std::vector<std::string> continuum_regions;    ///< keyword continuum (repeatable)
  std::vector<std::string> discrete_regions;     ///< keyword discrete (repeatable, adaptive only)
  std::string output_path;                       ///< HDF5 file of grains and points ("" = none)
  std::string mpm_state_path;                    ///< MPM state to continue from (keyword mpm_state)
  ContinuumSettings continuum;                   ///< what the handshake sends (gravity etc. set later)
  OracleSettings oracle;                         ///< the zone oracle of adaptive runs
  std::optional<CalibratedMaterial> material;    ///< keyword material (none: constants from the line)
  bool diameter_given = false, density_given = false;    ///< mu(I) grain size and density given
  bool pic_given = false;
  bool fill_auto = false;         ///< keyword `fill auto`: the fill pressure's modulus from the calibration
  bool points_given = false;      ///< keyword points_per_cell given
  bool container_given[6] = {false, false, false, false, false, false};    ///< xlo xhi ylo yhi zlo zhi
  double container_value[6] = {0, 0, 0, 0, 0, 0};
  double warn_steps_per_contact = kWarnStepsPerContact;    ///< keyword steps_per_contact
  double relax_time = -1.0;       ///< keyword relax, s (< 0: half the stiffest contact's duration)
  /// keyword energy_guard: the energy the coupling may make, as a share of the scene's energy scale
  /// (coupler::EnergyGuard; 0: unguarded)
  double energy_guard = kEnergyGuard;
  RezoneLog rezone_log = RezoneLog::kSummary;

  bool adaptive() const { return adapt_every > 0; }
  /// Whether the zone oracle runs right after the exchange at `step` (adaptive zones, after the
  /// conversion, an oracle step, and not the run's last step `last_step`: the next run's setup
  /// reorders the atoms).
  bool oracle_after(std::int64_t step, std::int64_t last_step, bool converted) const {
    return adaptive() && converted && step % adapt_every == 0 && step < last_step;
  }
  /// Whether the coupling splits grains (continuum regions or adaptive zones).
  bool splits() const { return !continuum_regions.empty() || adaptive(); }
  /// The continuum's container face (side 0 lo, 1 hi) on an axis: the keyword's, else the box's.
  double container_edge(int axis, int side, const double box_lo[3], const double box_hi[3]) const {
    const int k = 2 * axis + side;
    return container_given[k] ? container_value[k] : side ? box_hi[axis] : box_lo[axis];
  }
};

/// The planes of the container faces the continuum touches (coupler::touched_walls of the
/// container_edge faces: what make_hello sends, so the MPM's grid gets the same).
std::array<double, 3> touched_walls(const FixOptions &options, const double box_lo[3], const double box_hi[3]);

/// The MPM grid of a coupled run over the DEM box: the DEM side's transfers and zone map use it,
/// the MPM process builds the same from the handshake (mpm::coupled_scene), so node numbers agree.
template <int D>
GridGeometry<D> run_grid(const FixOptions &options, const double box_lo[3], const double box_hi[3]) {
  return padded_grid<D>(Eigen::Map<const Eigen::Matrix<double, D, 1>>(box_lo),
                        Eigen::Map<const Eigen::Matrix<double, D, 1>>(box_hi), options.cell,
                        touched_walls(options, box_lo, box_hi));
}

/// Names of the container faces in the order of face_bit (the values of `touch`).
inline constexpr const char *kFaceNames[6] = {"xlo", "xhi", "ylo", "yhi", "zlo", "zhi"};

/// The fix line's keyword/value words (after "fix ID group hybrid/mpm") in a run of
/// `dimension` with `ntypes` atom types; region_exists(id) says whether the host has a region.
/// Throws OptionError for the first problem, in the order the fix line is read.
FixOptions parse_fix_options(const std::vector<std::string> &words, int dimension, int ntypes,
                             const std::function<bool(const std::string &)> &region_exists);

/// The zone oracle's keywords (depth, band, surface_packing, dilute, shear_rate), also
/// changeable between runs: false if key is none of them, OptionError for a bad value.
bool set_oracle_option(OracleSettings &oracle, const std::string &key, const std::string &value);

/// The oracle's defaults from the cell (depth 3 cells, band 1) and the checks between its
/// values; nothing without adaptive zones. Throws OptionError.
void check_oracle_options(FixOptions &options, int dimension);

/// The grid the grains choose when the fix line gives no `cell` (docs/design.md section 5.1):
/// `points_per_axis` points per cell and axis (kPointsPerAxis unless given) and the cell, in
/// whole and half grain diameters, the smallest that gives each point at least kGrainsPerPoint
/// grains of diameter `grain_diameter` at the packing fraction `packing`, and at least
/// kSmallestCellInGrains diameters.
struct GrainGrid {
  double cell = 0.0;
  int points_per_axis = 0;
  double grains_per_point = 0.0;    ///< at `packing`
  double smallest_cell = 0.0;       ///< the finest cell whose points carry kGrainsPerPoint grains
};
GrainGrid grid_from_grains(int dimension, double grain_diameter, double packing, int points_per_axis);

/// The packing fraction a material point is made at: the calibrated material's, else a dense
/// random packing of disks (0.82) or spheres (0.60).
double grid_packing(const FixOptions &options, int dimension);

/// A width of the container the continuum touches on both sides (`touch` of both faces of
/// `axis`): for both faces to lie on node planes, the cell must divide it.
struct TouchedSpan {
  int axis = 0;
  double width = 0;
};
std::vector<TouchedSpan> touched_spans(const FixOptions &options, int dimension, const double box_lo[3],
                                       const double box_hi[3]);

/// The cell nearest `nominal` (within a quarter of it, no finer than `smallest`; the coarser of
/// two as near) that divides every span, else the one nearest it that divides the first span;
/// `nominal` if there are no spans.
double cell_dividing(double nominal, const std::vector<TouchedSpan> &spans, double smallest = 0.0);

/// Completes the options once the grains are known: without `cell` on the fix line the cell and
/// the points per cell come from the grains' mean diameter (grid_from_grains, then
/// cell_dividing the spans; a cell restored from a restart file is kept), then the oracle's
/// defaults that follow from the cell. Returns the line that says what was chosen and how many
/// grains a point carries, with a warning if the cell does not divide a span. Throws OptionError.
std::string resolve_grid(FixOptions &options, int dimension, double grain_diameter,
                         const std::vector<TouchedSpan> &spans = {});

/// The grid of a host's first run over a group of `grains` grains, whose mean diameter the options
/// then hold (the keyword diameter's or the grains'): resolve_grid, then the check that adaptive
/// zones' cells hold several grains (kSmallestCellInGrains). Returns resolve_grid's line; throws
/// OptionError for a bad option (an "Illegal fix" error) and sets `problem` for too small a cell.
std::string grid_of_run(FixOptions &options, int dimension, std::int64_t grains, const double box_lo[3],
                        const double box_hi[3], std::string &problem);

/// Keyword `every auto` at the first run, once the cell and the continuum's constants are known:
/// the exchange interval is the continuum's stable substep cfl dx / c (c its P-wave speed at its
/// nominal density) in whole DEM steps of `dem_dt`, at least 1, since the MPM process never steps
/// past an exchange; the zone oracle's interval is rounded up to a multiple of it. Returns the
/// line that says what was chosen.
std::string resolve_exchange_interval(FixOptions &options, double dem_dt);

/// rezone_log's value (OptionError for another).
RezoneLog rezone_log_option(const std::string &value);

/// A keyword a host's fix_modify may change between runs: rezone_log, pic (the grain update, the
/// DEM side's alone) and the zone oracle's (set_oracle_option, then check_oracle_options). False
/// if `key` is none of them; OptionError for a bad value.
bool modify_option(FixOptions &options, const std::string &key, const std::string &value, int dimension);

}    // namespace coupler
