// ContinuumState save/load: bit-identical round trip and clear refusals.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "mpm/hdf5_handle.hpp"
#include "mpm/output.hpp"
#include "mpm/state_file.hpp"

namespace mpm {
namespace {

namespace fs = std::filesystem;

/// A fresh directory under the system temp dir, removed at the end of the test.
class TempDir {
 public:
  explicit TempDir(const std::string& tag)
      : path_(fs::temp_directory_path() / ("mpm_state_test_" + tag + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// True if both vectors hold the same bytes.
template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

/// Random values in every field; matrices are asymmetric, so a transposition shows.
template <int D>
ContinuumState<D> random_state(int n_points, int n_cells, int n_support, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  auto vec = [&] { return Vec<D>(Vec<D>::NullaryExpr([&] { return u(rng); })); };
  auto mat = [&] { return Mat<D>(Mat<D>::NullaryExpr([&] { return u(rng); })); };
  ContinuumState<D> s;
  Particles<D>& p = s.points;
  for (int i = 0; i < n_points; ++i) {
    p.x.push_back(vec());
    p.v.push_back(vec());
    p.C.push_back(mat());
    p.stress.push_back(mat());
    p.be.push_back(mat());
    p.mass.push_back(u(rng));
    p.volume0.push_back(u(rng));
    p.J.push_back(u(rng));
    p.plastic_strain.push_back(u(rng));
    p.material.push_back(static_cast<std::uint16_t>(rng()));
    p.weight.push_back(static_cast<float>(u(rng)));
    p.body_accel.push_back(vec());
    p.fill_pressure.push_back(u(rng));
  }
  for (int c = 0; c < n_cells; ++c) s.zones.push_back(static_cast<std::int8_t>(rng() % 3));
  for (int k = 0; k < n_support; ++k) {
    s.support_nodes.push_back(rng());
    s.support_forces.push_back(vec());
    s.support_masses.push_back(u(rng));
    s.support_budgets.push_back(u(rng));
    s.support_gaps.push_back(vec());
  }
  s.time = u(rng);
  s.solver_time = u(rng);
  s.solver_steps = 123456789012L;
  s.dem_step = 9876543210LL;
  s.exchanges = 4242;
  s.cell = u(rng);
  for (int a = 0; a < 3; ++a) {
    s.box_lo[a] = u(rng);
    s.box_hi[a] = u(rng);
  }
  s.model = 1;
  return s;
}

template <int D>
void expect_identical(const ContinuumState<D>& a, const ContinuumState<D>& b) {
  const Particles<D>& p = a.points;
  const Particles<D>& q = b.points;
  EXPECT_TRUE(same_bits(p.x, q.x));
  EXPECT_TRUE(same_bits(p.v, q.v));
  EXPECT_TRUE(same_bits(p.C, q.C));
  EXPECT_TRUE(same_bits(p.stress, q.stress));
  EXPECT_TRUE(same_bits(p.be, q.be));
  EXPECT_TRUE(same_bits(p.mass, q.mass));
  EXPECT_TRUE(same_bits(p.volume0, q.volume0));
  EXPECT_TRUE(same_bits(p.J, q.J));
  EXPECT_TRUE(same_bits(p.plastic_strain, q.plastic_strain));
  EXPECT_TRUE(same_bits(p.material, q.material));
  EXPECT_TRUE(same_bits(p.weight, q.weight));
  EXPECT_TRUE(same_bits(p.body_accel, q.body_accel));
  EXPECT_TRUE(same_bits(p.fill_pressure, q.fill_pressure));
  EXPECT_TRUE(same_bits(a.zones, b.zones));
  EXPECT_TRUE(same_bits(a.support_nodes, b.support_nodes));
  EXPECT_TRUE(same_bits(a.support_forces, b.support_forces));
  EXPECT_TRUE(same_bits(a.support_masses, b.support_masses));
  EXPECT_TRUE(same_bits(a.support_budgets, b.support_budgets));
  EXPECT_TRUE(same_bits(a.support_gaps, b.support_gaps));
  EXPECT_EQ(std::memcmp(&a.time, &b.time, sizeof a.time), 0);
  EXPECT_EQ(std::memcmp(&a.solver_time, &b.solver_time, sizeof a.solver_time), 0);
  EXPECT_EQ(a.solver_steps, b.solver_steps);
  EXPECT_EQ(a.dem_step, b.dem_step);
  EXPECT_EQ(a.exchanges, b.exchanges);
  EXPECT_EQ(std::memcmp(&a.cell, &b.cell, sizeof a.cell), 0);
  EXPECT_EQ(std::memcmp(a.box_lo, b.box_lo, sizeof a.box_lo), 0);
  EXPECT_EQ(std::memcmp(a.box_hi, b.box_hi, sizeof a.box_hi), 0);
  EXPECT_EQ(a.model, b.model);
}

/// Runs f, expecting a UserError whose message contains every one of `parts`.
template <class F>
void expect_user_error(F f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no UserError thrown";
  } catch (const UserError& e) {
    for (const std::string& part : parts) EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

template <int D>
void round_trip(const std::string& tag) {
  TempDir tmp(tag);
  const std::string path = tmp.file("restart.mpm.h5");
  const ContinuumState<D> saved = random_state<D>(37, 50, 7, 2024 + D);
  // A second save over the first must truncate it.
  save_state(path, random_state<D>(5, 3, 2, 1));
  save_state(path, saved);
  expect_identical(saved, load_state<D>(path));
}

TEST(StateFile, RoundTripIsBitIdentical2D) { round_trip<2>("rt2"); }
TEST(StateFile, RoundTripIsBitIdentical3D) { round_trip<3>("rt3"); }

TEST(StateFile, EmptyPointsRoundTrip) {
  TempDir tmp("empty");
  const std::string path = tmp.file("empty.mpm.h5");
  const ContinuumState<3> saved = random_state<3>(0, 0, 0, 7);
  save_state(path, saved);
  const ContinuumState<3> loaded = load_state<3>(path);
  EXPECT_EQ(loaded.points.size(), 0u);
  expect_identical(saved, loaded);
}

TEST(StateFile, MissingFileErrorNamesThePath) {
  TempDir tmp("missing");
  const std::string path = tmp.file("nowhere.mpm.h5");
  expect_user_error([&] { load_state<2>(path); }, {path, "does not exist", "<restart>.mpm.h5"});
}

TEST(StateFile, SnapshotFileIsNotAStateFile) {
  TempDir tmp("snapshot");
  Scene scene;
  scene.dimension = 2;
  scene.output.directory = tmp.path().string();
  { SnapshotWriter<2> writer(tmp.path().string(), scene); }
  const std::string path = tmp.file("points.h5");
  ASSERT_TRUE(fs::exists(path));
  expect_user_error([&] { load_state<2>(path); }, {path, "not an MPM state file", "mpm-points"});
}

TEST(StateFile, NonHdf5FileIsNotAStateFile) {
  TempDir tmp("text");
  const std::string path = tmp.file("restart.mpm.h5");
  std::ofstream(path) << "not hdf5\n";
  expect_user_error([&] { load_state<3>(path); }, {path, "not an MPM state file"});
}

TEST(StateFile, WrongDimensionIsRefused) {
  TempDir tmp("dim");
  const std::string path = tmp.file("restart.mpm.h5");
  save_state(path, random_state<2>(4, 4, 1, 3));
  expect_user_error([&] { load_state<3>(path); }, {path, "2-dimensional", "3-dimensional"});
}

/// Opens a saved state file for editing with the HDF5 C API.
h5::File open_for_edit(const std::string& path) {
  h5::File file(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT));
  EXPECT_TRUE(file.valid());
  return file;
}

TEST(StateFile, MatricesAreStoredRowMajor) {
  TempDir tmp("layout");
  const std::string path = tmp.file("restart.mpm.h5");
  const ContinuumState<3> saved = random_state<3>(2, 1, 0, 11);
  save_state(path, saved);
  h5::File file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  h5::Dataset ds(H5Dopen2(file.get(), "/points/stress", H5P_DEFAULT));
  std::vector<double> data(2 * 9);
  ASSERT_GE(H5Dread(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), 0);
  for (int p = 0; p < 2; ++p)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) EXPECT_EQ(data[p * 9 + i * 3 + j], saved.points.stress[p](i, j));
}

TEST(StateFile, InconsistentLengthsAreRefusedOnLoad) {
  TempDir tmp("short");
  const std::string path = tmp.file("restart.mpm.h5");
  save_state(path, random_state<2>(4, 2, 1, 13));
  {
    h5::File file = open_for_edit(path);
    ASSERT_GE(H5Ldelete(file.get(), "/points/J", H5P_DEFAULT), 0);
    const double J[3] = {1, 1, 1};
    h5::write_direct(h5::Checker(path), h5::Loc{file.get(), "/"}, "/points/J", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                     {3}, J);
  }
  expect_user_error([&] { load_state<2>(path); }, {path, "inconsistent", "'J' has 3 values for 4 points"});
}

TEST(StateFile, OtherFormatVersionIsRefused) {
  TempDir tmp("version");
  const std::string path = tmp.file("restart.mpm.h5");
  save_state(path, random_state<2>(1, 1, 0, 17));
  {
    h5::File file = open_for_edit(path);
    h5::Attribute attr(H5Aopen(file.get(), "format_version", H5P_DEFAULT));
    const int version = 99;
    ASSERT_GE(H5Awrite(attr.get(), H5T_NATIVE_INT, &version), 0);
  }
  expect_user_error([&] { load_state<2>(path); }, {path, "format version 99", "reads version 3"});
}

TEST(StateFile, SaveErrorNamesThePath) {
  TempDir tmp("unwritable");
  const std::string path = tmp.file("no_such_dir/restart.mpm.h5");
  expect_user_error([&] { save_state(path, random_state<2>(1, 1, 0, 5)); }, {path});
}

TEST(StateFile, InconsistentLengthsAreRefusedOnSave) {
  TempDir tmp("inconsistent");
  ContinuumState<2> s = random_state<2>(3, 1, 2, 9);
  s.support_forces.pop_back();
  EXPECT_THROW(save_state(tmp.file("bad.mpm.h5"), s), std::invalid_argument);
  s = random_state<2>(3, 1, 2, 9);
  s.support_budgets.pop_back();
  EXPECT_THROW(save_state(tmp.file("bad.mpm.h5"), s), std::invalid_argument);
}

}  // namespace
}  // namespace mpm
