#pragma once
// Material points as a structure of arrays: one contiguous array per field.
#include <cstdint>
#include <vector>

#include "mpm/types.hpp"

namespace mpm {

template <int D>
struct Particles {
  std::vector<Vec<D>> x;        ///< position, m
  std::vector<Vec<D>> v;        ///< velocity, m/s
  std::vector<Mat<D>> C;        ///< APIC affine velocity (velocity gradient estimate), 1/s
  std::vector<Mat<D>> stress;   ///< Cauchy stress, Pa (tension positive)
  std::vector<Mat<D>> be;       ///< elastic left Cauchy-Green tensor (Drucker-Prager state)
  std::vector<double> mass;     ///< kg (per unit depth in 2D: kg/m)
  std::vector<double> volume0;  ///< initial volume, m^3 (m^2 in 2D)
  std::vector<double> J;        ///< volume ratio V/V0
  std::vector<double> plastic_strain;  ///< accumulated equivalent plastic shear strain
  std::vector<std::uint16_t> material; ///< index into the scene's materials
  /// Coupled runs: share of its cell's material the point carries (1 - grain weight in
  /// hybrid cells); float is plenty for a label that only output reads.
  std::vector<float> weight;
  /// Coupled runs: acceleration from the support force of the grains until the next
  /// exchange (zero otherwise), m/s^2.
  std::vector<Vec<D>> body_accel;
  /// Coupled runs: the fill pressure at the point until the next exchange (zero otherwise), Pa;
  /// P2G adds it to the point's stress as -p I (docs/design.md section 5.4).
  std::vector<double> fill_pressure;

  std::size_t size() const { return x.size(); }
  double volume(std::size_t p) const { return volume0[p] * J[p]; }

  /// Appends a point at rest in its reference state.
  void add(const Vec<D>& pos, const Vec<D>& vel, double m, double vol, std::uint16_t mat) {
    x.push_back(pos);
    v.push_back(vel);
    C.push_back(Mat<D>::Zero());
    stress.push_back(Mat<D>::Zero());
    be.push_back(Mat<D>::Identity());
    mass.push_back(m);
    volume0.push_back(vol);
    J.push_back(1.0);
    plastic_strain.push_back(0.0);
    material.push_back(mat);
    weight.push_back(1.0f);
    body_accel.push_back(Vec<D>::Zero());
    fill_pressure.push_back(0.0);
  }
};

/// Calls f(name, field) for every field of the points (const or not), in a fixed order: the
/// one list of fields for code that must treat all of them alike (sorting, state files).
template <class P, class F>
void for_each_point_field(P& pts, F&& f) {
  static_assert(sizeof(pts) == 13 * sizeof(std::vector<double>), "a Particles field was added: list it here");
  f("x", pts.x);
  f("v", pts.v);
  f("C", pts.C);
  f("stress", pts.stress);
  f("be", pts.be);
  f("mass", pts.mass);
  f("volume0", pts.volume0);
  f("J", pts.J);
  f("plastic_strain", pts.plastic_strain);
  f("material", pts.material);
  f("weight", pts.weight);
  f("body_accel", pts.body_accel);
  f("fill_pressure", pts.fill_pressure);
}

/// Removes the points with remove[p] != 0, keeping the order of the others.
template <int D>
void remove_points(Particles<D>& pts, const std::vector<char>& remove) {
  for_each_point_field(pts, [&](const char*, auto& field) {
    std::size_t kept = 0;
    for (std::size_t p = 0; p < field.size(); ++p)
      if (!remove[p]) field[kept++] = field[p];
    field.resize(kept);
  });
}

}  // namespace mpm
