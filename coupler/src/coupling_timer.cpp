#include "coupler/coupling_timer.hpp"

#include <cmath>
#include <cstdio>

namespace coupler {

double CouplingTimer::total() const {
  double sum = 0.0;
  for (double s : seconds) sum += s;
  return sum;
}

SectionTiming section_timing(double min, double max, double sum, double sum_sq, int nprocs, double wall) {
  SectionTiming t;
  if (nprocs < 1) return t;
  t.min = min;
  t.max = max;
  t.avg = sum / nprocs;
  const double mean_sq = sum_sq / nprocs;
  // LAMMPS's measure of load imbalance (finish.cpp), and its cut-off
  if (t.avg > 0.001 && mean_sq / t.avg - t.avg > 1.0e-10) t.varavg = std::sqrt(mean_sq / t.avg - t.avg) * 100.0;
  t.percent = wall > 0.0 ? t.avg / wall * 100.0 : 0.0;
  return t;
}

std::string timing_header(const std::string &title) {
  return title + "\nSection |  min time  |  avg time  |  max time  |%varavg| %total\n"
                 "---------------------------------------------------------------\n";
}

std::string timing_line(const std::string &label, const SectionTiming &t) {
  char line[160];
  std::snprintf(line, sizeof(line), "%-8.8s| %-11.5g| %-11.5g| %-11.5g|%6.1f |%6.2f\n", label.c_str(), t.min, t.avg,
                t.max, t.varavg, t.percent);
  return line;
}

}    // namespace coupler
