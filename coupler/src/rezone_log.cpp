#include "coupler/rezone_log.hpp"

#include <algorithm>

#include "coupler/text.hpp"

namespace coupler {
namespace {

std::string n(std::int64_t v) { return std::to_string(v); }

}    // namespace

std::optional<RezoneLog> parse_rezone_log(const std::string &value) {
  if (value == "full") return RezoneLog::kFull;
  if (value == "summary") return RezoneLog::kSummary;
  if (value == "quiet") return RezoneLog::kQuiet;
  return std::nullopt;
}

const char *rezone_log_name(RezoneLog level) {
  switch (level) {
    case RezoneLog::kFull: return "full";
    case RezoneLog::kSummary: return "summary";
    case RezoneLog::kQuiet: return "quiet";
  }
  return "?";
}

std::string rezone_line(const RezoneReport &r) {
  return "fix hybrid/mpm: step " + n(r.step) + ": " + n(r.grains_deleted) + " grains became " + n(r.points_made) +
         " material points, " + n(r.hybrid_grains) + " grains are hybrid (weight " + shortest(r.weight) + "), " +
         n(r.grains_made) + " grains made from points; " + n(r.moved_cells) + " cells moved; grid cells in the box: " +
         n(r.continuum_cells) + " continuum, " + n(r.hybrid_cells) + " hybrid, " + n(r.discrete_cells) + " discrete; " +
         n(r.rests_moved) + " cells gave their rest of material to nearby points, " + n(r.rests_kept) +
         " kept it; carried mass / solid mass " + general(r.lightest, 3) + " to " + general(r.heaviest, 3) +
         " (mean " + general(r.mean_carried, 4) + ")";
}

std::string rezone_totals_line(std::int64_t step, const double before[7], const double after[7]) {
  std::string line = "fix hybrid/mpm: step " + n(step) + ": totals before/after the rezone:";
  for (int k = 0; k < 7; k++) line += " " + general(before[k], 17) + " " + general(after[k], 17);
  return line;
}

void RezoneTally::add(const RezoneReport &r) {
  if (rezones_ == 0) sum_.lightest = r.lightest, sum_.heaviest = r.heaviest;
  ++rezones_;
  sum_.step = r.step;
  sum_.grains_deleted += r.grains_deleted;
  sum_.points_made += r.points_made;
  sum_.grains_made += r.grains_made;
  sum_.moved_cells += r.moved_cells;
  sum_.rests_moved += r.rests_moved;
  sum_.rests_kept += r.rests_kept;
  sum_.hybrid_grains = r.hybrid_grains;
  sum_.mean_carried = r.mean_carried;
  sum_.weight = r.weight;
  sum_.continuum_cells = r.continuum_cells, sum_.hybrid_cells = r.hybrid_cells, sum_.discrete_cells = r.discrete_cells;
  sum_.grain_energy += r.grain_energy;
  sum_.lightest = std::min(sum_.lightest, r.lightest);
  sum_.heaviest = std::max(sum_.heaviest, r.heaviest);
}

std::string RezoneTally::summary_line(const char *what, std::int64_t last_step) const {
  const RezoneReport &s = sum_;
  return "fix hybrid/mpm: " + std::string(what) + " " + n(first_) + "-" + n(last_step) + ": " + n(rezones_) +
         (rezones_ == 1 ? " rezone: " : " rezones: ") + n(s.grains_deleted) + " grains became " + n(s.points_made) +
         " material points, " + n(s.grains_made) + " grains made from points, " + n(s.moved_cells) +
         " cells moved; " + n(s.rests_moved) + " cells gave their rest of material to nearby points, " +
         n(s.rests_kept) + " kept it; now " + n(s.hybrid_grains) + " hybrid grains, zones " + n(s.continuum_cells) +
         " continuum, " + n(s.hybrid_cells) + " hybrid, " + n(s.discrete_cells) +
         " discrete cells; carried mass / solid mass " + general(s.lightest, 3) + " to " + general(s.heaviest, 3) +
         " (mean " + general(s.mean_carried, 4) + ")";
}

std::string RezoneTally::energy_line(const char *what, std::int64_t last_step) const {
  auto term = [](const char *name, const GrainEnergy &e) {
    return std::string(name) + " " + general(e.total(), 6) + " (kinetic " + general(e.kinetic, 6) + ", potential " +
           general(e.potential, 6) + ")";
  };
  const RezoneGrainEnergy &e = sum_.grain_energy;
  return "fix hybrid/mpm: " + std::string(what) + " " + n(first_) + "-" + n(last_step) +
         ": the rezones' energy on the grains (J, J/m in 2D): " + term("made", e.made) + ", " +
         term("removed", e.removed) + ", " + term("corrected", e.corrected) + "; " +
         mechanism_terms(e.by_mechanism, term) + "; in all " + general(e.total(), 6);
}

}    // namespace coupler
