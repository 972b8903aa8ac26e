#include "coupler/dem_grains.hpp"

#include <algorithm>
#include <map>

#include "coupler/conversion.hpp"
#include "coupler/oracle.hpp"

namespace coupler {

double GrainRules::solid_mass(double radius) const {
  return density * grain_volume(dimension, radius);
}

void grain_totals(const DemGrains &g, double inertia, double out[7]) {
  // of the group's grains only: frozen floors or driven bodies outside it have their momentum imposed
  std::fill(out, out + 7, 0.0);
  double **x = g.x, **v = g.v, **omega = g.omega;
  for (int i = 0; i < g.n; i++) {
    if (!g.coupled(i)) continue;
    const double m = g.rmass[i];
    out[0] += m;
    for (int a = 0; a < 3; a++) out[1 + a] += m * v[i][a];
    const double I = inertia * m * g.radius[i] * g.radius[i];
    out[4] += m * (x[i][1] * v[i][2] - x[i][2] * v[i][1]) + I * omega[i][0];
    out[5] += m * (x[i][2] * v[i][0] - x[i][0] * v[i][2]) + I * omega[i][1];
    out[6] += m * (x[i][0] * v[i][1] - x[i][1] * v[i][0]) + I * omega[i][2];
  }
}

GrainEnergy grain_energy_of(const DemGrains &g, int i, double inertia, const double gravity[3]) {
  const double m = g.rmass[i], I = inertia * m * g.radius[i] * g.radius[i];
  double speed2 = 0.0, spin2 = 0.0, height = 0.0;
  for (int a = 0; a < 3; a++) {
    speed2 += g.v[i][a] * g.v[i][a];
    spin2 += g.omega[i][a] * g.omega[i][a];
    height += gravity[a] * g.x[i][a];
  }
  return {0.5 * m * speed2 + 0.5 * I * spin2, -m * height};
}

double grain_energy(const DemGrains &g, double inertia, const double gravity[3]) {
  double energy = 0.0;
  for (int i = 0; i < g.n; i++)
    if (g.coupled(i)) energy += grain_energy_of(g, i, inertia, gravity).total();
  return energy;
}

template <int D>
std::vector<CellGrains> cell_grains(const GridGeometry<D> &grid, const DemGrains &g) {
  std::map<std::size_t, CellGrains> cells;
  for (int i = 0; i < g.n; i++) {
    if (!g.coupled(i)) continue;
    const auto c = cell_of<D>(grid, Eigen::Map<const Eigen::Matrix<double, D, 1>>(g.x[i]));
    if (!cell_on_grid<D>(grid, c)) continue;
    const std::size_t k = cell_index<D>(grid, c);
    auto &cell = cells[k];
    cell.cell = k;
    cell.volume += grain_volume<D>(g.radius[i]);
    cell.mass += g.rmass[i];
    double speed2 = 0;
    for (int a = 0; a < D; a++) speed2 += g.v[i][a] * g.v[i][a];
    cell.kinetic += 0.5 * g.rmass[i] * speed2;
  }
  std::vector<CellGrains> out;
  out.reserve(cells.size());
  for (const auto &kv : cells) out.push_back(kv.second);
  return out;
}

void mass_drift(const DemGrains &g, const GrainRules &rules, double extremes[2], double sums[2]) {
  extremes[0] = -1.0e20, extremes[1] = 0.0;    // -lightest, heaviest
  sums[0] = sums[1] = 0.0;
  for (int i = 0; i < g.n; i++) {
    if (!g.coupled(i)) continue;
    const double share = g.weight[i] * rules.solid_mass(g.radius[i]), f = g.rmass[i] / share;
    extremes[0] = std::max(extremes[0], -f), extremes[1] = std::max(extremes[1], f);
    sums[0] += g.rmass[i], sums[1] += share;
  }
}

std::int64_t hybrid_grain_count(const DemGrains &g) {
  std::int64_t n = 0;
  for (int i = 0; i < g.n; i++) n += g.coupled(i) && g.weight[i] < 1.0 ? 1 : 0;
  return n;
}

template std::vector<CellGrains> cell_grains<2>(const GridGeometry<2> &, const DemGrains &);
template std::vector<CellGrains> cell_grains<3>(const GridGeometry<3> &, const DemGrains &);


void GrainArrays::copy(int from, int to) const {
  weight[to] = weight[from];
  for (int a = 0; a < 3; a++) support[to][a] = support[from][a];
  for (int k = 0; k < 6; k++) stress[to][k] = stress[from][k];
}

void GrainArrays::reset(int i) const {
  weight[i] = 1.0;
  for (int a = 0; a < 3; a++) support[i][a] = 0.0;
  for (int k = 0; k < 6; k++) stress[i][k] = 0.0;    // made after the stress was stored: none
}

int GrainArrays::pack(int i, double *buf) const {
  buf[0] = weight[i];
  for (int a = 0; a < 3; a++) buf[1 + a] = support[i][a];
  for (int k = 0; k < 6; k++) buf[4 + k] = stress[i][k];
  return kValues;
}

int GrainArrays::unpack(int i, const double *buf) const {
  weight[i] = buf[0];
  for (int a = 0; a < 3; a++) support[i][a] = buf[1 + a];
  for (int k = 0; k < 6; k++) stress[i][k] = buf[4 + k];
  return kValues;
}

int GrainArrays::pack_restart(int i, double *buf) const {
  buf[0] = kRestartValues;
  buf[1] = weight[i];
  for (int a = 0; a < 3; a++) buf[2 + a] = support[i][a];
  return kRestartValues;
}

void GrainArrays::unpack_restart(int i, const double *values) const {
  weight[i] = values[1];
  for (int a = 0; a < 3; a++) support[i][a] = values[2 + a];
}

std::vector<int> supported_grains(double *const *support, int n) {
  std::vector<int> index;
  for (int i = 0; i < n; i++)
    if (support[i][0] != 0.0 || support[i][1] != 0.0 || support[i][2] != 0.0) index.push_back(i);
  return index;
}

int delete_flagged(const std::vector<char> &flags, int n, const std::function<void(int, int)> &move) {
  for (int i = static_cast<int>(flags.size()) - 1; i >= 0; i--)
    if (flags[i]) move(--n, i);
  return n;
}

}    // namespace coupler
