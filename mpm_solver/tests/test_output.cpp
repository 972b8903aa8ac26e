// SnapshotWriter: HDF5 round trip through the plain HDF5 C API, and XDMF sidecars
// that reference datasets which exist with the declared dimensions.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "coupler/version.hpp"
#include "mpm/hdf5_handle.hpp"
#include "mpm/output.hpp"

namespace mpm {
namespace {

namespace fs = std::filesystem;

/// A fresh directory under the system temp dir, removed at the end of the test.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    path_ = fs::temp_directory_path() / ("mpm_output_test_" + tag + "_" + std::to_string(::getpid()));
    fs::remove_all(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

int count_occurrences(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t pos = text.find(what); pos != std::string::npos; pos = text.find(what, pos + what.size())) ++n;
  return n;
}

Scene make_scene(int dim, const fs::path& dir, bool grid_fields) {
  Scene scene;
  scene.dimension = dim;
  scene.output.directory = dir.string();
  scene.output.grid_fields = grid_fields;
  Material sand;
  sand.name = "sand";
  Material beads;
  beads.name = "glass_beads";
  scene.materials = {sand, beads};
  return scene;
}

/// Points with distinct, non-round values in every field, including a
/// non-symmetric stress so that the [p][i][j] = sigma_ij layout is checked.
template <int D>
Particles<D> make_points(int n, double shift) {
  Particles<D> pts;
  for (int p = 0; p < n; ++p) {
    Vec<D> x, v;
    for (int a = 0; a < D; ++a) {
      x[a] = 0.1 * p + 0.01 * a + shift + 1.0 / 3.0;
      v[a] = -0.2 * p + 0.3 * a - shift;
    }
    pts.add(x, v, 1.5 + p / 7.0, 0.001 * (p + 1), static_cast<std::uint16_t>(p % 2));
    for (int i = 0; i < D; ++i)
      for (int j = 0; j < D; ++j) pts.stress.back()(i, j) = -1000.0 * (p + 1) + 10.0 * i + 1.0 * j + shift;
    pts.J.back() = 0.9 + 0.01 * p;
    pts.plastic_strain.back() = 0.05 * p + shift;
  }
  return pts;
}

template <int D>
Grid<D> make_grid(double shift) {
  Vec<D> lower = Vec<D>::Zero(), upper = Vec<D>::Constant(1.0);
  Grid<D> grid(lower, upper, 0.25);
  for (std::size_t k = 0; k < grid.num_nodes(); ++k) {
    grid.mass[k] = 0.5 * static_cast<double>(k) + shift;
    for (int a = 0; a < D; ++a) grid.momentum[k][a] = static_cast<double>(k) * (a + 1) - shift;
  }
  return grid;
}

// --- reading back with the HDF5 C API --------------------------------------

struct Reader {
  h5::File file;
  explicit Reader(const fs::path& path) {
    h5::ErrorSilencer quiet;
    file = h5::File(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  }

  bool exists(const std::string& path) const {
    h5::ErrorSilencer quiet;
    // Check every link on the way so that a missing intermediate group is "no", not an error.
    std::size_t pos = 0;
    while ((pos = path.find('/', pos + 1)) != std::string::npos) {
      if (H5Lexists(file.get(), path.substr(0, pos).c_str(), H5P_DEFAULT) <= 0) return false;
    }
    return H5Lexists(file.get(), path.c_str(), H5P_DEFAULT) > 0;
  }

  std::vector<hsize_t> dims(const std::string& path) const {
    h5::Dataset ds(H5Dopen2(file.get(), path.c_str(), H5P_DEFAULT));
    EXPECT_TRUE(ds.valid()) << path;
    h5::Dataspace space(H5Dget_space(ds.get()));
    const int rank = H5Sget_simple_extent_ndims(space.get());
    std::vector<hsize_t> d(static_cast<std::size_t>(std::max(rank, 0)));
    if (rank > 0) H5Sget_simple_extent_dims(space.get(), d.data(), nullptr);
    return d;
  }

  std::vector<double> doubles(const std::string& path) const { return read<double>(path, H5T_NATIVE_DOUBLE); }

  template <class T>
  std::vector<T> read(const std::string& path, hid_t mem_type) const {
    h5::Dataset ds(H5Dopen2(file.get(), path.c_str(), H5P_DEFAULT));
    EXPECT_TRUE(ds.valid()) << path;
    std::size_t n = 1;
    for (hsize_t d : dims(path)) n *= d;
    std::vector<T> out(n);
    if (n > 0) EXPECT_GE(H5Dread(ds.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), 0) << path;
    return out;
  }

  template <class T>
  std::vector<T> attribute(const std::string& object, const char* name, hid_t mem_type) const {
    h5::Attribute attr(H5Aopen_by_name(file.get(), object.c_str(), name, H5P_DEFAULT, H5P_DEFAULT));
    EXPECT_TRUE(attr.valid()) << object << " @" << name;
    h5::Dataspace space(H5Aget_space(attr.get()));
    const hssize_t n = H5Sget_simple_extent_npoints(space.get());
    std::vector<T> out(static_cast<std::size_t>(std::max<hssize_t>(n, 0)));
    EXPECT_GE(H5Aread(attr.get(), mem_type, out.data()), 0);
    return out;
  }

  std::string string_attribute(const std::string& object, const char* name) const {
    h5::Attribute attr(H5Aopen_by_name(file.get(), object.c_str(), name, H5P_DEFAULT, H5P_DEFAULT));
    h5::Datatype type(H5Aget_type(attr.get()));
    EXPECT_TRUE(H5Tis_variable_str(type.get()) > 0);
    char* value = nullptr;
    h5::Datatype mem(H5Tcopy(H5T_C_S1));
    H5Tset_size(mem.get(), H5T_VARIABLE);
    H5Tset_cset(mem.get(), H5T_CSET_UTF8);
    EXPECT_GE(H5Aread(attr.get(), mem.get(), &value), 0);
    std::string s = value ? value : "";
    H5free_memory(value);
    return s;
  }

  std::vector<std::string> strings(const std::string& path) const {
    h5::Dataset ds(H5Dopen2(file.get(), path.c_str(), H5P_DEFAULT));
    h5::Datatype mem(H5Tcopy(H5T_C_S1));
    H5Tset_size(mem.get(), H5T_VARIABLE);
    H5Tset_cset(mem.get(), H5T_CSET_UTF8);
    std::vector<char*> raw(dims(path).at(0), nullptr);
    EXPECT_GE(H5Dread(ds.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, raw.data()), 0);
    std::vector<std::string> out;
    for (char* s : raw) {
      out.emplace_back(s ? s : "");
      H5free_memory(s);
    }
    return out;
  }

  hsize_t frame_count() const {
    h5::Group g(H5Gopen2(file.get(), "/frames", H5P_DEFAULT));
    H5G_info_t info{};
    EXPECT_GE(H5Gget_info(g.get(), &info), 0);
    return info.nlinks;
  }
};

/// Every dataset the XDMF file references exists with the declared dimensions.
/// Returns the number of references checked.
int check_xdmf_references(const std::string& xdmf, const Reader& reader) {
  const std::regex item(R"re(<DataItem Dimensions="([0-9 ]+)"[^>]*Format="HDF">points\.h5:([^<]+)</DataItem>)re");
  int checked = 0;
  for (auto it = std::sregex_iterator(xdmf.begin(), xdmf.end(), item); it != std::sregex_iterator(); ++it) {
    const std::string dims_text = (*it)[1];
    const std::string path = (*it)[2];
    EXPECT_TRUE(reader.exists(path)) << "XDMF references missing dataset " << path;
    if (!reader.exists(path)) continue;
    std::vector<hsize_t> declared;
    std::istringstream in(dims_text);
    for (hsize_t d; in >> d;) declared.push_back(d);
    EXPECT_EQ(declared, reader.dims(path)) << path;
    ++checked;
  }
  return checked;
}

template <int D>
void expect_frame(const Reader& r, const std::string& frame, const Particles<D>& pts, double time, long step) {
  SCOPED_TRACE(frame);
  EXPECT_EQ(r.attribute<double>(frame, "time", H5T_NATIVE_DOUBLE).at(0), time);
  EXPECT_EQ(r.attribute<std::int64_t>(frame, "step", H5T_NATIVE_INT64).at(0), step);
  const std::size_t n = pts.size();
  const hsize_t hn = n;
  EXPECT_EQ(r.dims(frame + "/position"), (std::vector<hsize_t>{hn, D}));
  EXPECT_EQ(r.dims(frame + "/stress"), (std::vector<hsize_t>{hn, D, D}));
  const auto x = r.doubles(frame + "/position");
  const auto v = r.doubles(frame + "/velocity");
  const auto mass = r.doubles(frame + "/mass");
  const auto volume = r.doubles(frame + "/volume");
  const auto stress = r.doubles(frame + "/stress");
  const auto pressure = r.doubles(frame + "/pressure");
  const auto eps = r.doubles(frame + "/plastic_strain");
  const auto mat = r.read<std::uint16_t>(frame + "/material", H5T_NATIVE_UINT16);
  ASSERT_EQ(x.size(), n * D);
  ASSERT_EQ(stress.size(), n * D * D);
  ASSERT_EQ(mat.size(), n);
  for (std::size_t p = 0; p < n; ++p) {
    for (int a = 0; a < D; ++a) {
      EXPECT_EQ(x[p * D + a], pts.x[p][a]);  // exact: no conversion anywhere
      EXPECT_EQ(v[p * D + a], pts.v[p][a]);
    }
    for (int i = 0; i < D; ++i)
      for (int j = 0; j < D; ++j) EXPECT_EQ(stress[(p * D + i) * D + j], pts.stress[p](i, j)) << p << i << j;
    EXPECT_EQ(mass[p], pts.mass[p]);
    EXPECT_EQ(volume[p], pts.volume0[p] * pts.J[p]);
    EXPECT_EQ(pressure[p], -pts.stress[p].trace() / D);
    EXPECT_EQ(eps[p], pts.plastic_strain[p]);
    EXPECT_EQ(mat[p], pts.material[p]);
  }
  if (D == 2) {
    const auto v3 = r.doubles(frame + "/velocity3");
    const auto s3 = r.doubles(frame + "/stress3");
    ASSERT_EQ(v3.size(), n * 3);
    ASSERT_EQ(s3.size(), n * 9);
    for (std::size_t p = 0; p < n; ++p) {
      EXPECT_EQ(v3[p * 3 + 0], pts.v[p][0]);
      EXPECT_EQ(v3[p * 3 + 1], pts.v[p][1]);
      EXPECT_EQ(v3[p * 3 + 2], 0.0);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          EXPECT_EQ(s3[p * 9 + i * 3 + j], (i < 2 && j < 2) ? pts.stress[p](i, j) : 0.0);
    }
  }
}

template <int D>
void expect_grid(const Reader& r, const std::string& frame, const Grid<D>& grid) {
  SCOPED_TRACE(frame + "/grid");
  std::vector<hsize_t> dims;
  for (int a = 0; a < D; ++a) dims.push_back(static_cast<hsize_t>(grid.dims[a]));
  EXPECT_EQ(r.dims(frame + "/grid/mass"), dims);
  const auto mass = r.doubles(frame + "/grid/mass");
  const auto vel = r.doubles(frame + "/grid/velocity");
  ASSERT_EQ(mass.size(), grid.num_nodes());
  ASSERT_EQ(vel.size(), grid.num_nodes() * D);
  for (std::size_t k = 0; k < grid.num_nodes(); ++k) {
    EXPECT_EQ(mass[k], grid.mass[k]);
    for (int a = 0; a < D; ++a) EXPECT_EQ(vel[k * D + a], grid.momentum[k][a]);
  }
}

// --- tests -----------------------------------------------------------------

TEST(SnapshotWriter, RoundTrip2DWithGridFields) {
  TempDir tmp("2d");
  const fs::path dir = tmp.path() / "nested" / "out";  // created by the writer
  const Scene scene = make_scene(2, dir, /*grid_fields=*/true);
  const auto pts0 = make_points<2>(7, 0.0), pts1 = make_points<2>(7, 0.5);
  const auto grid0 = make_grid<2>(0.0), grid1 = make_grid<2>(2.0);
  {
    SnapshotWriter<2> writer(dir.string(), scene);
    EXPECT_EQ(writer.frames_written(), 0);
    writer.write(pts0, grid0, 0.0, 0);
    EXPECT_EQ(writer.frames_written(), 1);
    writer.write(pts1, grid1, 0.125, 250);
    EXPECT_EQ(writer.frames_written(), 2);
  }
  ASSERT_TRUE(fs::exists(dir / "points.h5"));
  Reader r(dir / "points.h5");
  ASSERT_TRUE(r.file.valid());
  EXPECT_EQ(r.attribute<int>("/", "dimension", H5T_NATIVE_INT).at(0), 2);
  EXPECT_EQ(r.string_attribute("/", "mpm_version"), coupler::release_version());
  EXPECT_EQ(r.strings("/materials"), (std::vector<std::string>{"sand", "glass_beads"}));
  EXPECT_EQ(r.frame_count(), 2u);
  expect_frame(r, "/frames/000000", pts0, 0.0, 0);
  expect_frame(r, "/frames/000001", pts1, 0.125, 250);
  expect_grid(r, "/frames/000000", grid0);
  expect_grid(r, "/frames/000001", grid1);

  const auto origin = r.attribute<double>("/", "grid_origin", H5T_NATIVE_DOUBLE);
  const auto dims = r.attribute<std::int64_t>("/", "grid_dims", H5T_NATIVE_INT64);
  ASSERT_EQ(origin.size(), 2u);
  ASSERT_EQ(dims.size(), 2u);
  EXPECT_EQ(origin[0], grid0.origin[0]);
  EXPECT_EQ(origin[1], grid0.origin[1]);
  EXPECT_EQ(dims[0], grid0.dims[0]);
  EXPECT_EQ(dims[1], grid0.dims[1]);
  EXPECT_EQ(r.attribute<double>("/", "grid_dx", H5T_NATIVE_DOUBLE).at(0), grid0.dx);
  // Node coordinates: [i][j][a] = origin + dx * (i, j).
  const auto coords = r.doubles("/grid_coordinates");
  ASSERT_EQ(coords.size(), grid0.num_nodes() * 2);
  for (std::size_t k = 0; k < grid0.num_nodes(); ++k) {
    const Vec<2> x = grid0.node_position(grid0.node_of(k));
    EXPECT_EQ(coords[k * 2 + 0], x[0]);
    EXPECT_EQ(coords[k * 2 + 1], x[1]);
  }

  const std::string xdmf = read_text(dir / "points.xdmf");
  EXPECT_EQ(count_occurrences(xdmf, "<Grid "), 3);  // temporal collection + 2 frames
  EXPECT_EQ(count_occurrences(xdmf, "</Grid>"), 3);
  EXPECT_NE(xdmf.find("GeometryType=\"XY\""), std::string::npos);
  EXPECT_NE(xdmf.find("<Time Value=\"0.125\"/>"), std::string::npos);
  EXPECT_NE(xdmf.find("points.h5:/frames/000001/position"), std::string::npos);
  EXPECT_EQ(check_xdmf_references(xdmf, r), 2 * 9);  // topology + geometry + 7 attributes per frame

  // One shared Polyvertex connectivity 0..N-1 for both frames (same N).
  const auto ids = r.read<std::int64_t>("/xdmf/vertex_ids_7", H5T_NATIVE_INT64);
  ASSERT_EQ(ids.size(), 7u);
  for (std::size_t i = 0; i < ids.size(); ++i) EXPECT_EQ(ids[i], static_cast<std::int64_t>(i));
  EXPECT_EQ(count_occurrences(xdmf, "points.h5:/xdmf/vertex_ids_7<"), 2);

  const std::string grid_xdmf = read_text(dir / "grid.xdmf");
  EXPECT_EQ(count_occurrences(grid_xdmf, "<Grid "), 3);
  EXPECT_NE(grid_xdmf.find("TopologyType=\"2DSMesh\""), std::string::npos);
  EXPECT_EQ(check_xdmf_references(grid_xdmf, r), 2 * 3);  // coordinates + mass + velocity
  EXPECT_FALSE(fs::exists(dir / "points.xdmf.tmp"));
}

TEST(SnapshotWriter, RoundTrip3DWithoutGridFields) {
  TempDir tmp("3d");
  const Scene scene = make_scene(3, tmp.path(), /*grid_fields=*/false);
  const auto pts0 = make_points<3>(5, 0.0), pts1 = make_points<3>(5, -0.25);
  const Grid<3> grid = make_grid<3>(0.0);
  {
    SnapshotWriter<3> writer(tmp.path().string(), scene);
    writer.write(pts0, grid, 0.0, 0);
    writer.write(pts1, grid, 1.0 / 3.0, 1234567890123L);
    EXPECT_EQ(writer.frames_written(), 2);
  }
  Reader r(tmp.path() / "points.h5");
  ASSERT_TRUE(r.file.valid());
  EXPECT_EQ(r.attribute<int>("/", "dimension", H5T_NATIVE_INT).at(0), 3);
  EXPECT_EQ(r.frame_count(), 2u);
  expect_frame(r, "/frames/000000", pts0, 0.0, 0);
  expect_frame(r, "/frames/000001", pts1, 1.0 / 3.0, 1234567890123L);
  EXPECT_FALSE(r.exists("/frames/000000/grid"));
  EXPECT_FALSE(r.exists("/frames/000000/velocity3"));
  EXPECT_FALSE(r.exists("/grid_coordinates"));

  const std::string xdmf = read_text(tmp.path() / "points.xdmf");
  EXPECT_EQ(count_occurrences(xdmf, "<Grid "), 3);
  EXPECT_NE(xdmf.find("GeometryType=\"XYZ\""), std::string::npos);
  EXPECT_NE(xdmf.find("<Time Value=\"0.3333333333333333\"/>"), std::string::npos);  // round-trips exactly
  EXPECT_EQ(check_xdmf_references(xdmf, r), 2 * 9);
  EXPECT_FALSE(fs::exists(tmp.path() / "grid.xdmf"));
}

TEST(SnapshotWriter, LargePointSetIsWrittenInBlocks) {
  // Derived datasets (volume, stress, pressure, velocity3, stress3) are assembled
  // in blocks of 2^18 values; 100k points span several blocks for every one of them.
  TempDir tmp("large");
  const Scene scene = make_scene(2, tmp.path(), false);
  const int n = 100000;
  const auto pts = make_points<2>(n, 0.0);
  {
    SnapshotWriter<2> writer(tmp.path().string(), scene);
    writer.write(pts, Grid<2>{}, 1.0, 10);
  }
  Reader r(tmp.path() / "points.h5");
  const auto volume = r.doubles("/frames/000000/volume");
  const auto stress = r.doubles("/frames/000000/stress");
  const auto pressure = r.doubles("/frames/000000/pressure");
  const auto v3 = r.doubles("/frames/000000/velocity3");
  const auto s3 = r.doubles("/frames/000000/stress3");
  ASSERT_EQ(volume.size(), std::size_t(n));
  ASSERT_EQ(s3.size(), std::size_t(n) * 9);
  std::size_t bad = 0;
  for (std::size_t p = 0; p < std::size_t(n); ++p) {
    bad += volume[p] != pts.volume(p);
    bad += pressure[p] != -pts.stress[p].trace() / 2;
    bad += v3[p * 3 + 1] != pts.v[p][1] || v3[p * 3 + 2] != 0.0;
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) {
        bad += stress[p * 4 + i * 2 + j] != pts.stress[p](i, j);
        bad += s3[p * 9 + i * 3 + j] != pts.stress[p](i, j);
      }
    bad += s3[p * 9 + 8] != 0.0;
  }
  EXPECT_EQ(bad, 0u);
}

TEST(SnapshotWriter, XdmfIsValidBeforeAndAfterEachFrame) {
  TempDir tmp("partial");
  const Scene scene = make_scene(2, tmp.path(), false);
  SnapshotWriter<2> writer(tmp.path().string(), scene);
  const std::string empty = read_text(tmp.path() / "points.xdmf");
  EXPECT_EQ(count_occurrences(empty, "<Grid "), 1);
  EXPECT_NE(empty.find("</Xdmf>"), std::string::npos);
  const Grid<2> grid = make_grid<2>(0.0);
  writer.write(make_points<2>(3, 0.0), grid, 0.0, 0);
  const std::string one = read_text(tmp.path() / "points.xdmf");
  EXPECT_EQ(count_occurrences(one, "<Grid "), 2);
  EXPECT_NE(one.find("</Xdmf>"), std::string::npos);
}

TEST(SnapshotWriter, EmptyPointSetAndEmptyMaterialList) {
  TempDir tmp("empty");
  Scene scene = make_scene(3, tmp.path(), false);
  scene.materials.clear();
  {
    SnapshotWriter<3> writer(tmp.path().string(), scene);
    writer.write(Particles<3>{}, Grid<3>{}, 0.5, 3);
  }
  Reader r(tmp.path() / "points.h5");
  EXPECT_EQ(r.dims("/frames/000000/position"), (std::vector<hsize_t>{0, 3}));
  EXPECT_EQ(r.dims("/materials"), (std::vector<hsize_t>{0}));
}

TEST(SnapshotWriter, ErrorsNameTheFileAndTheOperation) {
  TempDir tmp("errors");
  fs::create_directories(tmp.path() / "points.h5");  // a directory where the file should go
  const Scene scene = make_scene(2, tmp.path(), false);
  try {
    SnapshotWriter<2> writer(tmp.path().string(), scene);
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find((tmp.path() / "points.h5").string()), std::string::npos) << msg;
    EXPECT_NE(msg.find("create"), std::string::npos) << msg;
    std::cout << "  (message: " << msg << ")\n";
  }
  // A directory that cannot be created (a regular file is in the way).
  std::ofstream(tmp.path() / "blocker") << "x";
  const fs::path bad = tmp.path() / "blocker" / "out";
  EXPECT_THROW(SnapshotWriter<2>(bad.string(), make_scene(2, bad, false)), std::runtime_error);
  // Inconsistent point arrays are refused before anything is written.
  {
    SnapshotWriter<2> writer((tmp.path() / "ok").string(), scene);
    auto pts = make_points<2>(3, 0.0);
    pts.mass.pop_back();
    EXPECT_THROW(writer.write(pts, Grid<2>{}, 0.0, 0), std::invalid_argument);
    EXPECT_EQ(writer.frames_written(), 0);
  }
  // A scene of the wrong dimension.
  EXPECT_THROW(SnapshotWriter<3>((tmp.path() / "d").string(), scene), std::invalid_argument);
}

TEST(SnapshotWriter, GridThatChangesBetweenFramesIsRefusedAndLeavesNoPartialFrame) {
  TempDir tmp("gridchange");
  const Scene scene = make_scene(2, tmp.path(), true);
  const auto pts = make_points<2>(2, 0.0);
  {
    SnapshotWriter<2> writer(tmp.path().string(), scene);
    writer.write(pts, make_grid<2>(0.0), 0.0, 0);
    Grid<2> other(Vec<2>::Zero(), Vec<2>::Constant(2.0), 0.25);
    EXPECT_THROW(writer.write(pts, other, 0.1, 1), std::invalid_argument);
    EXPECT_EQ(writer.frames_written(), 1);
    writer.write(pts, make_grid<2>(1.0), 0.2, 2);  // the failed frame's name is reused
    EXPECT_EQ(writer.frames_written(), 2);
  }
  Reader r(tmp.path() / "points.h5");
  EXPECT_EQ(r.frame_count(), 2u);
  EXPECT_EQ(r.attribute<double>("/frames/000001", "time", H5T_NATIVE_DOUBLE).at(0), 0.2);
}

// --- coupled runs: grains and the points' zone and weight ------------------

GrainFrame make_grains(int n, double shift) {
  GrainFrame g;
  for (int i = 0; i < n; ++i) {
    g.id.push_back(1000000000000LL + 7 * i);  // beyond 32 bits
    for (int a = 0; a < 3; ++a) {
      g.x.push_back(0.01 * i + 0.1 * a + shift + 1.0 / 7.0);
      g.v.push_back(-0.03 * i + a - shift);
    }
    g.radius.push_back(0.001 + 1e-5 * i);
    g.weight.push_back(i % 3 == 1 ? 0.25 + 0.1 * shift : 1.0);
    g.mass.push_back(g.weight.back() * (2e-3 + 1e-4 * i));
    g.zone.push_back(static_cast<std::int8_t>(i % 3));
  }
  return g;
}

PointCoupling make_coupling(std::size_t n) {
  PointCoupling c;
  for (std::size_t p = 0; p < n; ++p) {
    c.zone.push_back(static_cast<std::int8_t>(p % 2 + 1));  // points live in hybrid and continuum cells
    c.weight.push_back(p % 2 ? 1.0 : 0.75 - 0.01 * static_cast<double>(p));
  }
  return c;
}

void expect_grains(const Reader& r, const std::string& frame, const GrainFrame& g) {
  SCOPED_TRACE(frame + "/grains");
  const std::string base = frame + "/grains/";
  const hsize_t n = g.size();
  EXPECT_EQ(r.dims(base + "id"), (std::vector<hsize_t>{n}));
  EXPECT_EQ(r.dims(base + "position"), (std::vector<hsize_t>{n, 3}));
  EXPECT_EQ(r.dims(base + "velocity"), (std::vector<hsize_t>{n, 3}));
  EXPECT_EQ(r.read<std::int64_t>(base + "id", H5T_NATIVE_INT64), g.id);
  EXPECT_EQ(r.doubles(base + "position"), g.x);
  EXPECT_EQ(r.doubles(base + "velocity"), g.v);
  EXPECT_EQ(r.doubles(base + "radius"), g.radius);
  EXPECT_EQ(r.doubles(base + "mass"), g.mass);
  EXPECT_EQ(r.doubles(base + "weight"), g.weight);
  EXPECT_EQ(r.read<std::int8_t>(base + "zone", H5T_NATIVE_INT8), g.zone);
  // Stored as the types the layout documents, not just readable as them.
  h5::Dataset zone(H5Dopen2(r.file.get(), (base + "zone").c_str(), H5P_DEFAULT));
  h5::Datatype zone_type(H5Dget_type(zone.get()));
  EXPECT_GT(H5Tequal(zone_type.get(), H5T_STD_I8LE), 0);
  h5::Dataset id(H5Dopen2(r.file.get(), (base + "id").c_str(), H5P_DEFAULT));
  h5::Datatype id_type(H5Dget_type(id.get()));
  EXPECT_GT(H5Tequal(id_type.get(), H5T_STD_I64LE), 0);
}

/// Frame 0 without grains or coupling, frames 1 and 2 with both (different grain counts).
template <int D>
void coupled_round_trip(const std::string& tag) {
  TempDir tmp(tag);
  const Scene scene = make_scene(D, tmp.path(), /*grid_fields=*/true);
  const auto pts = make_points<D>(6, 0.0);
  const Grid<D> grid = make_grid<D>(0.0);
  const GrainFrame grains1 = make_grains(5, 0.0), grains2 = make_grains(8, 0.5);
  const PointCoupling coupling = make_coupling(pts.size());
  {
    SnapshotWriter<D> writer(tmp.path().string(), scene);
    writer.write(pts, grid, 0.0, 0);
    EXPECT_FALSE(fs::exists(tmp.path() / "grains.xdmf"));  // no frame with grains yet
    writer.write(pts, grid, 0.25, 10, &grains1, &coupling);
    writer.write(pts, grid, 0.5, 20, &grains2, &coupling);
    EXPECT_EQ(writer.frames_written(), 3);
  }
  Reader r(tmp.path() / "points.h5");
  ASSERT_TRUE(r.file.valid());
  EXPECT_EQ(r.string_attribute("/", "format"), "mpm-points");
  EXPECT_EQ(r.attribute<int>("/", "format_version", H5T_NATIVE_INT).at(0), 2);
  EXPECT_EQ(r.frame_count(), 3u);
  expect_frame(r, "/frames/000001", pts, 0.25, 10);  // the point datasets are unchanged
  expect_grid(r, "/frames/000001", grid);

  EXPECT_FALSE(r.exists("/frames/000000/grains"));
  EXPECT_FALSE(r.exists("/frames/000000/zone"));
  EXPECT_FALSE(r.exists("/frames/000000/weight"));
  expect_grains(r, "/frames/000001", grains1);
  expect_grains(r, "/frames/000002", grains2);
  for (const std::string frame : {"/frames/000001", "/frames/000002"}) {
    SCOPED_TRACE(frame);
    EXPECT_EQ(r.read<std::int8_t>(frame + "/zone", H5T_NATIVE_INT8), coupling.zone);
    EXPECT_EQ(r.doubles(frame + "/weight"), coupling.weight);
  }
  // Polyvertex connectivity shared with the points: one dataset per distinct count.
  EXPECT_EQ(r.read<std::int64_t>("/xdmf/vertex_ids_5", H5T_NATIVE_INT64), (std::vector<std::int64_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(r.dims("/xdmf/vertex_ids_8"), (std::vector<hsize_t>{8}));
  EXPECT_TRUE(r.exists("/xdmf/vertex_ids_6"));

  const std::string grains_xdmf = read_text(tmp.path() / "grains.xdmf");
  EXPECT_EQ(count_occurrences(grains_xdmf, "<Grid "), 3);  // collection + the 2 frames with grains
  EXPECT_EQ(grains_xdmf.find("/frames/000000/"), std::string::npos);
  EXPECT_NE(grains_xdmf.find("GeometryType=\"XYZ\""), std::string::npos);
  EXPECT_NE(grains_xdmf.find("<Time Value=\"0.25\"/>"), std::string::npos);
  for (const char* ds : {"position", "velocity", "radius", "mass", "weight", "zone"})
    EXPECT_NE(grains_xdmf.find(std::string("points.h5:/frames/000002/grains/") + ds + "<"), std::string::npos) << ds;
  EXPECT_EQ(count_occurrences(grains_xdmf, "points.h5:/xdmf/vertex_ids_5<"), 1);
  EXPECT_EQ(count_occurrences(grains_xdmf, "points.h5:/xdmf/vertex_ids_8<"), 1);
  EXPECT_EQ(check_xdmf_references(grains_xdmf, r), 2 * 7);  // topology + geometry + 5 attributes per frame
  EXPECT_FALSE(fs::exists(tmp.path() / "grains.xdmf.tmp"));

  const std::string points_xdmf = read_text(tmp.path() / "points.xdmf");
  EXPECT_EQ(count_occurrences(points_xdmf, "<Attribute Name=\"zone\""), 2);
  EXPECT_EQ(count_occurrences(points_xdmf, "<Attribute Name=\"weight\""), 2);
  EXPECT_NE(points_xdmf.find("points.h5:/frames/000001/zone<"), std::string::npos);
  EXPECT_EQ(check_xdmf_references(points_xdmf, r), 9 + 2 * 11);
}

TEST(SnapshotWriter, CoupledFramesWithGrains2D) { coupled_round_trip<2>("coupled2d"); }
TEST(SnapshotWriter, CoupledFramesWithGrains3D) { coupled_round_trip<3>("coupled3d"); }

template <int D>
void mismatched_lengths(const std::string& tag) {
  TempDir tmp(tag);
  const Scene scene = make_scene(D, tmp.path(), /*grid_fields=*/true);
  const auto pts = make_points<D>(4, 0.0);
  const Grid<D> grid = make_grid<D>(0.0);
  const GrainFrame good = make_grains(3, 0.0);
  const PointCoupling coupling = make_coupling(pts.size());
  std::vector<std::pair<std::string, GrainFrame>> bad_grains;
  auto broken = [&](const char* what, auto edit) {
    GrainFrame g = good;
    edit(g);
    bad_grains.emplace_back(what, g);
  };
  broken("x", [](GrainFrame& g) { g.x.pop_back(); });
  broken("v", [](GrainFrame& g) { g.v.push_back(0.0); });
  broken("radius", [](GrainFrame& g) { g.radius.pop_back(); });
  broken("mass", [](GrainFrame& g) { g.mass.clear(); });
  broken("weight", [](GrainFrame& g) { g.weight.push_back(1.0); });
  broken("zone", [](GrainFrame& g) { g.zone.pop_back(); });
  broken("id", [](GrainFrame& g) { g.id.push_back(99); });
  PointCoupling short_zone = coupling, long_weight = coupling;
  short_zone.zone.pop_back();
  long_weight.weight.push_back(1.0);
  const std::string path = (tmp.path() / "points.h5").string();
  {
    SnapshotWriter<D> writer(tmp.path().string(), scene);
    writer.write(pts, grid, 0.0, 0, &good, &coupling);
    for (const auto& [what, g] : bad_grains) {
      SCOPED_TRACE(what);
      try {
        writer.write(pts, grid, 0.1, 1, &g, &coupling);
        ADD_FAILURE() << "expected std::invalid_argument";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      }
    }
    EXPECT_THROW(writer.write(pts, grid, 0.1, 1, &good, &short_zone), std::invalid_argument);
    EXPECT_THROW(writer.write(pts, grid, 0.1, 1, nullptr, &long_weight), std::invalid_argument);
    // A frame refused later (in the grid output), after its grains' connectivity was written.
    Grid<D> other(Vec<D>::Zero(), Vec<D>::Constant(2.0), 0.25);
    const GrainFrame seven = make_grains(7, 0.0);
    EXPECT_THROW(writer.write(pts, other, 0.1, 1, &seven, &coupling), std::invalid_argument);
    EXPECT_EQ(writer.frames_written(), 1);
    EXPECT_EQ(count_occurrences(read_text(tmp.path() / "grains.xdmf"), "<Grid "), 2);
    writer.write(pts, grid, 0.2, 2, &seven, &coupling);  // reuses the refused frames' name
    EXPECT_EQ(writer.frames_written(), 2);
  }
  Reader r(path);
  EXPECT_EQ(r.frame_count(), 2u);
  EXPECT_EQ(r.attribute<double>("/frames/000001", "time", H5T_NATIVE_DOUBLE).at(0), 0.2);
  expect_grains(r, "/frames/000000", good);
  expect_grains(r, "/frames/000001", make_grains(7, 0.0));
  const std::string grains_xdmf = read_text(tmp.path() / "grains.xdmf");
  EXPECT_EQ(count_occurrences(grains_xdmf, "<Grid "), 3);
  EXPECT_EQ(check_xdmf_references(grains_xdmf, r), 2 * 7);
}

TEST(SnapshotWriter, MismatchedGrainOrCouplingLengthsThrowAndLeaveNoFrame2D) { mismatched_lengths<2>("mismatch2d"); }
TEST(SnapshotWriter, MismatchedGrainOrCouplingLengthsThrowAndLeaveNoFrame3D) { mismatched_lengths<3>("mismatch3d"); }

TEST(SnapshotWriter, EmptyGrainFrame) {
  TempDir tmp("nograins");
  const Scene scene = make_scene(2, tmp.path(), false);
  const GrainFrame none;
  {
    SnapshotWriter<2> writer(tmp.path().string(), scene);
    writer.write(make_points<2>(2, 0.0), Grid<2>{}, 0.0, 0, &none);
  }
  Reader r(tmp.path() / "points.h5");
  EXPECT_EQ(r.dims("/frames/000000/grains/position"), (std::vector<hsize_t>{0, 3}));
  EXPECT_EQ(r.dims("/frames/000000/grains/zone"), (std::vector<hsize_t>{0}));
  const std::string grains_xdmf = read_text(tmp.path() / "grains.xdmf");
  EXPECT_NE(grains_xdmf.find("NumberOfElements=\"0\""), std::string::npos);
  EXPECT_EQ(check_xdmf_references(grains_xdmf, r), 6);  // geometry + 5 attributes, no connectivity
}

}  // namespace
}  // namespace mpm
