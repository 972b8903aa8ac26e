#pragma once
// The DEM side's log of rezones (docs/fix_hybrid_mpm.md, keyword rezone_log): what one rezone
// did, its lines in the full log, and the summary of several rezones that replaces them in
// the default log (one line per thermo output, one per run). Host-neutral: the fix fills a
// RezoneReport from its sums over the ranks and prints the lines these functions make.

#include <cstdint>
#include <optional>
#include <string>

#include "coupler/dem_ledger.hpp"

namespace coupler {

/// How much of the rezones the log shows (keyword rezone_log).
enum class RezoneLog {
  kFull,       ///< every rezone's two lines (counts, totals before/after), and the summaries
  kSummary,    ///< the first rezone's lines (the conversion), a summary at thermo output and per run
  kQuiet,      ///< only the summary of each run
};

/// rezone_log's value ("full", "summary", "quiet"); nullopt for anything else.
std::optional<RezoneLog> parse_rezone_log(const std::string &value);
const char *rezone_log_name(RezoneLog level);
/// The values rezone_log accepts, for error messages.
inline constexpr const char *kRezoneLogValues = "full, summary or quiet";

/// What one rezone did, summed over the DEM ranks (the MPM process's figures from its
/// acknowledgement).
struct RezoneReport {
  std::int64_t step = 0;
  std::int64_t grains_deleted = 0;    ///< grains that became material points
  std::int64_t points_made = 0;       ///< material points made from grains
  std::int64_t hybrid_grains = 0;     ///< grains left with a weight below 1 (after the rezone)
  double weight = 0.5;                ///< the hybrid cells' grain weight (keyword weight)
  std::int64_t grains_made = 0;       ///< grains made from points
  std::int64_t moved_cells = 0;       ///< cells whose zone changed
  std::int64_t continuum_cells = 0, hybrid_cells = 0, discrete_cells = 0;    ///< grid cells in the box, after it
  std::int64_t rests_moved = 0;       ///< cells that gave their rest of material to nearby points
  std::int64_t rests_kept = 0;        ///< cells that kept it
  double lightest = 1.0, heaviest = 1.0;    ///< carried mass / (weight * solid mass), extremes after it
  /// the same summed over all grains (mass_drift's sums) after it: above 1 the conversions between
  /// grains and points have lost grain volume (fewer grains carry the material, each heavier)
  double mean_carried = 1.0;
  RezoneGrainEnergy grain_energy;     ///< what it did to the grains' energy (summed by RezoneTally)
};

/// The full log's first line of a rezone (without a trailing newline):
/// "fix hybrid/mpm: step N: X grains became P material points, ..."
std::string rezone_line(const RezoneReport &r);

/// The full log's second line: the totals of grains plus points (mass, momentum x y z, angular
/// momentum x y z) just before and just after the rezone, to round-off.
std::string rezone_totals_line(std::int64_t step, const double before[7], const double after[7]);

/// Rezones since a step: their counts summed, the zones, hybrid grains and mean carried mass of
/// the last, the extremes of the carried mass over all of them.
class RezoneTally {
 public:
  explicit RezoneTally(std::int64_t first_step = 0) : first_(first_step) {}
  void add(const RezoneReport &r);
  /// Starts again: the next summary covers the steps from first_step on.
  void restart(std::int64_t first_step) { *this = RezoneTally(first_step); }
  std::int64_t rezones() const { return rezones_; }
  std::int64_t first_step() const { return first_; }
  const RezoneReport &sum() const { return sum_; }
  /// "fix hybrid/mpm: <what> A-B: N rezone(s): X grains became P material points, G grains made from
  /// points, M cells moved; R cells gave their rest of material to nearby points, K kept it; now H
  /// hybrid grains, zones C continuum, Y hybrid, Z discrete cells; carried mass / solid mass L to U
  /// (mean M)"
  /// with <what> "steps" (a thermo interval) or "run of steps"; A the first step, B = last_step.
  std::string summary_line(const char *what, std::int64_t last_step) const;
  /// "fix hybrid/mpm: <what> A-B: the rezones' energy on the grains (J, J/m in 2D): made E (kinetic
  /// K, potential P), removed ..., corrected ...; by the cells' zone change: enrichment ...,
  /// homogenisation ..., repair ...; in all T": their RezoneGrainEnergy, whose sum (of either
  /// split) is what they added to the ledger's entry 27 over these steps.
  std::string energy_line(const char *what, std::int64_t last_step) const;

 private:
  std::int64_t first_;
  std::int64_t rezones_ = 0;
  RezoneReport sum_;    // counts summed; hybrid grains and zones of the last; mass extremes
};

/// The summary's prefixes: an interval between thermo outputs, a whole run.
inline constexpr const char *kSummaryInterval = "steps";
inline constexpr const char *kSummaryRun = "run of steps";

}    // namespace coupler
