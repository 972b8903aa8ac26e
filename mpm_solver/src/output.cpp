// HDF5 snapshots of the material points, with XDMF sidecars for ParaView.
//
// Layout of <directory>/points.h5 (all floating point data float64, SI units):
//
//   /                      attributes: format = "mpm-points", format_version (int32),
//                          dimension (int32), mpm_version (string),
//                          and with grid fields: grid_origin (D), grid_dx, grid_dims (D, int64)
//   /materials             string dataset (UTF-8), the scene's material names;
//                          `material` below indexes it
//   /grid_coordinates      only with grid fields: node positions, dims x D (written once)
//   /xdmf/vertex_ids_N     int64 0..N-1, the Polyvertex connectivity XDMF readers need to make
//                          one vertex cell per point; written once per distinct point count N
//   /frames/NNNNNN         one group per frame, NNNNNN = 0-based frame index;
//                          attributes time (float64, s) and step (int64)
//       position           N x D, m
//       velocity           N x D, m/s
//       mass               N, kg (kg/m in 2D)
//       volume             N, m^3 (m^2 in 2D), = volume0 * J
//       stress             N x D x D, Cauchy stress, Pa, tension positive; stress[p, i, j] = sigma_ij
//       pressure           N, Pa, p = -trace(stress) / D
//       plastic_strain     N, accumulated equivalent plastic shear strain
//       material           N, uint16, index into /materials
//       zone               coupled runs only: N, int8, zone of the point's cell
//                          (0 discrete, 1 hybrid, 2 continuum)
//       weight             coupled runs only: N, share of its cell's material the point carries
//       velocity3          2D only: N x 3, velocity padded with a zero z component (for XDMF)
//       stress3            2D only: N x 3 x 3, stress padded with zeros (for XDMF)
//       grid/              only with grid fields
//           mass           dims (row-major, last axis fastest, as mpm::Grid stores it), kg
//           velocity       dims x D, node velocity after the grid update, m/s
//           velocity3      2D only: dims x 3, zero-padded (for XDMF)
//       grains/            coupled runs only, frames with grains (the DEM side); G grains
//           id             G, int64, the DEM host's atom id
//           position       G x 3, m (also in 2D, z = 0)
//           velocity       G x 3, m/s
//           radius         G, m
//           mass           G, the mass the grain carries (weight * its full mass), kg
//           weight         G, share of its cell's material the grain carries
//           zone           G, int8, zone of the grain's cell
//
// XDMF sidecars (rewritten after every frame through a temporary file and a rename):
//   points.xdmf  a temporal collection of Polyvertex grids, one per frame
//   grains.xdmf  once a frame had grains: a temporal collection of Polyvertex grids, one
//                per frame with grains; shares /xdmf/vertex_ids_N with points.xdmf
//   grid.xdmf    with grid fields only: a temporal collection of 2DSMesh/3DSMesh grids.
//                The grid is described by explicit node coordinates (/grid_coordinates)
//                rather than as a CoRectMesh because XDMF's CoRectMesh expects the first
//                axis to vary fastest, while mpm::Grid (and the HDF5 datasets) have the last
//                axis fastest; explicit coordinates keep the natural layout in the HDF5 file
//                and still place every node correctly in ParaView.
// XDMF has no 2-component vectors nor 2x2 tensors, so in 2D the XDMF attributes
// `velocity` and `stress` reference the padded velocity3 and stress3 datasets;
// in 3D they reference velocity and stress directly.
// Checked with ParaView 5.11: its Xdmf3 readers (S and T) read both sidecars in 2D and 3D;
// the legacy "XDMF Reader" (Xdmf2) reads all but the velocity of the 2D grid (that reader
// miscounts the components of vector attributes on 2D structured grids).
#include "mpm/output.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "coupler/version.hpp"
#include "mpm/hdf5_handle.hpp"

namespace mpm {
namespace {

namespace fs = std::filesystem;

/// Values (doubles) per block in which derived datasets are assembled and
/// written, so that a derived dataset never needs a temporary of its full size.
constexpr std::size_t kBlockValues = std::size_t{1} << 18;
// 1: points and grid fields. 2: adds the coupled runs' optional frame group `grains` and
// point datasets `zone` and `weight`; files without them read as version 1 did.
constexpr int kFormatVersion = 2;

std::string frame_name(int index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06d", index);
  return buf;
}

/// The shortest %g text (15 to 17 digits) that reads back as exactly `v`.
std::string format_double(double v) {
  char buf[40];
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

std::string join_dims(const std::vector<hsize_t>& dims) {
  std::string s;
  for (std::size_t i = 0; i < dims.size(); ++i) {
    if (i) s += ' ';
    s += std::to_string(dims[i]);
  }
  return s;
}

using h5::Checker;
using h5::create_dataset;
using h5::create_group;
using h5::element_count;
using h5::Loc;
using h5::utf8_string_type;
using h5::write_attribute;
using h5::write_direct;
using h5::write_string_attribute;

/// Writes a float64 dataset whose first dimension counts items (points, or
/// slabs of grid nodes); `fill(item, out)` writes the item's product(dims[1:])
/// values to out. Values are assembled and written in blocks of whole items
/// of about kBlockValues values.
template <class Fill>
void write_derived(const Checker& h5, const Loc& loc, const char* name, const std::vector<hsize_t>& dims, Fill fill) {
  const std::string object = loc.child(name);
  h5::Dataset ds = create_dataset(h5, loc, name, H5T_IEEE_F64LE, dims);
  const std::size_t items = static_cast<std::size_t>(dims[0]);
  if (items == 0) return;
  const std::size_t per_item = element_count(dims) / items;
  const std::size_t block = std::max<std::size_t>(1, kBlockValues / std::max<std::size_t>(1, per_item));
  std::vector<double> buf(std::min(items, block) * per_item);
  if (items <= block) {
    for (std::size_t i = 0; i < items; ++i) fill(i, buf.data() + i * per_item);
    h5.ok(H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()), "write dataset", object);
    return;
  }
  h5::Dataspace file_space(h5.id(H5Dget_space(ds.get()), "get the dataspace of", object));
  std::vector<hsize_t> offset(dims.size(), 0), count = dims;
  for (std::size_t start = 0; start < items; start += block) {
    const std::size_t n = std::min(block, items - start);
    for (std::size_t i = 0; i < n; ++i) fill(start + i, buf.data() + i * per_item);
    offset[0] = start;
    count[0] = n;
    h5.ok(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, offset.data(), nullptr, count.data(), nullptr),
          "select a block of", object);
    const hsize_t mem_count = n * per_item;
    h5::Dataspace mem_space(h5.id(H5Screate_simple(1, &mem_count, nullptr), "create a memory dataspace for", object));
    h5.ok(H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, mem_space.get(), file_space.get(), H5P_DEFAULT, buf.data()),
          "write dataset", object);
  }
}

// ---------------------------------------------------------------------------
// XDMF text

std::string data_item(const std::vector<hsize_t>& dims, const char* number_type, int precision,
                      const std::string& h5_file, const std::string& dataset) {
  std::string s = "<DataItem Dimensions=\"" + join_dims(dims) + "\" NumberType=\"" + number_type + "\" Precision=\"" +
                  std::to_string(precision) + "\" Format=\"HDF\">" + h5_file + ":" + dataset + "</DataItem>";
  return s;
}

std::string attribute_xml(const char* name, const char* type, const std::string& item) {
  return std::string("        <Attribute Name=\"") + name + "\" AttributeType=\"" + type + "\" Center=\"Node\">\n" +
         "          " + item + "\n        </Attribute>\n";
}

std::string xdmf_document(const std::string& collection_name, const std::vector<std::string>& frames) {
  std::string s =
      "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
      "<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">\n"
      "  <Domain>\n"
      "    <Grid Name=\"" + collection_name + "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const std::string& f : frames) s += f;
  s += "    </Grid>\n  </Domain>\n</Xdmf>\n";
  return s;
}

/// Writes `text` to `path` through a temporary file and a rename, so that a
/// reader never sees a half-written file.
void write_file_atomically(const fs::path& path, const std::string& text) {
  fs::path tmp = path;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("XDMF output: cannot open '" + tmp.string() + "' for writing");
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.close();
    if (!out) throw std::runtime_error("XDMF output: cannot write '" + tmp.string() + "'");
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw std::runtime_error("XDMF output: cannot rename '" + tmp.string() + "' to '" + path.string() + "': " + ec.message());
}

}  // namespace

// ---------------------------------------------------------------------------

template <int D>
struct SnapshotWriter<D>::Impl {
  static_assert(sizeof(Vec<D>) == D * sizeof(double), "points must be D packed doubles to be written in place");
  static_assert(sizeof(Mat<D>) == D * D * sizeof(double), "matrices must be D*D packed doubles");

  fs::path directory;
  fs::path h5_path;
  std::string h5_name;  ///< file name as referenced from the XDMF sidecars
  Checker h5;
  bool grid_fields = false;
  h5::File file;
  h5::Group frames;
  int frames_written = 0;
  /// A frame failed to write (a full disk): the file is then not closed. Its flush would fail
  /// again, and a failed H5Fclose leaves HDF5 a half-freed file (which its clean-up crashed on;
  /// main.cpp keeps that clean-up from running). What was flushed before stays readable.
  bool failed = false;
  h5::Group xdmf_group;  ///< /xdmf: datasets only the XDMF sidecars need
  std::vector<hsize_t> vertex_id_sizes;  ///< point counts N with a /xdmf/vertex_ids_N dataset
  std::vector<std::string> point_frames_xml;  ///< one <Grid> per frame, cached
  std::vector<std::string> grid_frames_xml;
  std::vector<std::string> grain_frames_xml;  ///< frames with grains only
  bool grid_geometry_written = false;
  IVec<D> grid_dims = IVec<D>::Zero();
  Vec<D> grid_origin = Vec<D>::Zero();
  double grid_dx = 0;

  ~Impl() {
    if (failed) file.release();
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  Impl(const std::string& dir, const Scene& scene)
      : directory(dir.empty() ? fs::path(".") : fs::path(dir)),
        h5_path(directory / "points.h5"),
        h5_name("points.h5"),
        h5(h5_path.string()),
        grid_fields(scene.output.grid_fields) {
    if (scene.dimension != D)
      throw std::invalid_argument("SnapshotWriter<" + std::to_string(D) + ">: the scene is " +
                                  std::to_string(scene.dimension) + "-dimensional");
    std::error_code ec;
    fs::create_directories(directory, ec);
    if (ec) throw std::runtime_error("cannot create output directory '" + directory.string() + "': " + ec.message());

    file = h5::File(h5.id(H5Fcreate(h5_path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), "create the file", ""));
    const Loc root{file.get(), "/"};
    write_string_attribute(h5, root, "format", "mpm-points");
    write_attribute(h5, root, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT, &kFormatVersion);
    const int dim = D;
    write_attribute(h5, root, "dimension", H5T_STD_I32LE, H5T_NATIVE_INT, &dim);
    write_string_attribute(h5, root, "mpm_version", coupler::release_version());

    std::vector<const char*> names;
    names.reserve(scene.materials.size());
    for (const Material& m : scene.materials) names.push_back(m.name.c_str());
    {
      h5::Datatype type = utf8_string_type(h5);
      const std::vector<hsize_t> dims{names.size()};
      write_direct(h5, root, "materials", type.get(), type.get(), dims, names.data());
    }
    frames = create_group(h5, root, "frames");
    xdmf_group = create_group(h5, root, "xdmf");
    h5.ok(H5Fflush(file.get(), H5F_SCOPE_GLOBAL), "flush", "");
    write_file_atomically(directory / "points.xdmf", xdmf_document("points", point_frames_xml));
  }

  /// Throws std::invalid_argument unless `size` is `expected`.
  void check_length(const char* what, std::size_t size, std::size_t expected) const {
    if (size != expected)
      throw std::invalid_argument("SnapshotWriter: " + std::string(what) + " has " + std::to_string(size) +
                                  " values, expected " + std::to_string(expected) + " (writing '" + h5.path() + "')");
  }

  void write(const Particles<D>& pts, const Grid<D>& grid, double time, long step, const GrainFrame* grains,
             const PointCoupling* coupling) {
    const std::size_t n = pts.size();
    if (pts.v.size() != n || pts.stress.size() != n || pts.mass.size() != n || pts.volume0.size() != n ||
        pts.J.size() != n || pts.plastic_strain.size() != n || pts.material.size() != n)
      throw std::invalid_argument("SnapshotWriter: the point arrays differ in length (writing '" + h5.path() + "')");
    // All checks before the first write, so that a refused frame leaves the file untouched.
    if (coupling) {
      check_length("the points' zone", coupling->zone.size(), n);
      check_length("the points' weight", coupling->weight.size(), n);
    }
    if (grains) {
      const std::size_t g = grains->size();
      check_length("the grains' x", grains->x.size(), 3 * g);
      check_length("the grains' v", grains->v.size(), 3 * g);
      check_length("the grains' radius", grains->radius.size(), g);
      check_length("the grains' mass", grains->mass.size(), g);
      check_length("the grains' weight", grains->weight.size(), g);
      check_length("the grains' zone", grains->zone.size(), g);
    }
    const std::string name = frame_name(frames_written);
    const Loc frames_loc{frames.get(), "/frames"};
    try {
      ensure_vertex_ids(pts.size());
      if (grains) ensure_vertex_ids(grains->size());
      h5::Group group = create_group(h5, frames_loc, name.c_str());
      const Loc frame{group.get(), frames_loc.child(name.c_str())};
      write_frame(frame, pts, grid, time, step);
      if (coupling) write_coupling(frame, *coupling);
      if (grains) write_grains(frame, *grains);
      h5.ok(H5Fflush(file.get(), H5F_SCOPE_GLOBAL), "flush", "");
    } catch (...) {
      // Leave no half-written frame behind: a retry or the next frame reuses the name.
      H5Ldelete(frames.get(), name.c_str(), H5P_DEFAULT);
      if (grid_fields && !grid_geometry_written) {
        for (const char* attr : {"grid_origin", "grid_dx", "grid_dims"}) H5Adelete(file.get(), attr);
        H5Ldelete(file.get(), "grid_coordinates", H5P_DEFAULT);
      }
      H5Eclear2(H5E_DEFAULT);
      failed = true;
      throw;
    }
    point_frames_xml.push_back(points_xml(name, pts.size(), time, coupling != nullptr));
    if (grid_fields) grid_frames_xml.push_back(grid_xml(name, time));
    if (grains) grain_frames_xml.push_back(grains_xml(name, grains->size(), time));
    ++frames_written;
    write_file_atomically(directory / "points.xdmf", xdmf_document("points", point_frames_xml));
    if (grid_fields) write_file_atomically(directory / "grid.xdmf", xdmf_document("grid", grid_frames_xml));
    if (!grain_frames_xml.empty())
      write_file_atomically(directory / "grains.xdmf", xdmf_document("grains", grain_frames_xml));
  }

  void write_coupling(const Loc& g, const PointCoupling& c) {
    const std::vector<hsize_t> scalar{c.zone.size()};
    write_direct(h5, g, "zone", H5T_STD_I8LE, H5T_NATIVE_INT8, scalar, c.zone.data());
    write_direct(h5, g, "weight", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scalar, c.weight.data());
  }

  void write_grains(const Loc& frame, const GrainFrame& grains) {
    h5::Group group = create_group(h5, frame, "grains");
    const Loc g{group.get(), frame.child("grains")};
    const hsize_t n = grains.size();
    const std::vector<hsize_t> scalar{n}, vector{n, 3};
    write_direct(h5, g, "id", H5T_STD_I64LE, H5T_NATIVE_INT64, scalar, grains.id.data());
    write_direct(h5, g, "position", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, vector, grains.x.data());
    write_direct(h5, g, "velocity", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, vector, grains.v.data());
    write_direct(h5, g, "radius", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scalar, grains.radius.data());
    write_direct(h5, g, "mass", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scalar, grains.mass.data());
    write_direct(h5, g, "weight", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scalar, grains.weight.data());
    write_direct(h5, g, "zone", H5T_STD_I8LE, H5T_NATIVE_INT8, scalar, grains.zone.data());
  }

  void write_frame(const Loc& g, const Particles<D>& pts, const Grid<D>& grid, double time, long step) {
    write_attribute(h5, g, "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &time);
    const std::int64_t step64 = step;
    write_attribute(h5, g, "step", H5T_STD_I64LE, H5T_NATIVE_INT64, &step64);

    const hsize_t n = pts.size();
    const std::vector<hsize_t> scalar{n}, vector{n, D}, tensor{n, D, D};
    const double* no_data = nullptr;
    auto doubles = [&](const auto& v) { return v.empty() ? no_data : v.data()->data(); };
    write_direct(h5, g, "position", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, vector, doubles(pts.x));
    write_direct(h5, g, "velocity", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, vector, doubles(pts.v));
    write_direct(h5, g, "mass", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scalar, pts.mass.data());
    write_derived(h5, g, "volume", scalar, [&](std::size_t p, double* out) { *out = pts.volume(p); });
    // Eigen stores matrices column-major; the dataset is row-major [p][i][j] = sigma_ij.
    write_derived(h5, g, "stress", tensor, [&](std::size_t p, double* out) {
      const Mat<D>& s = pts.stress[p];
      for (int i = 0; i < D; ++i)
        for (int j = 0; j < D; ++j) out[i * D + j] = s(i, j);
    });
    write_derived(h5, g, "pressure", scalar,
                  [&](std::size_t p, double* out) { *out = -pts.stress[p].trace() / D; });
    write_direct(h5, g, "plastic_strain", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, scalar, pts.plastic_strain.data());
    write_direct(h5, g, "material", H5T_STD_U16LE, H5T_NATIVE_UINT16, scalar, pts.material.data());
    if constexpr (D == 2) {
      write_derived(h5, g, "velocity3", {n, 3}, [&](std::size_t p, double* out) {
        out[0] = pts.v[p][0];
        out[1] = pts.v[p][1];
        out[2] = 0.0;
      });
      write_derived(h5, g, "stress3", {n, 3, 3}, [&](std::size_t p, double* out) {
        const Mat<D>& s = pts.stress[p];
        for (int k = 0; k < 9; ++k) out[k] = 0.0;
        for (int i = 0; i < 2; ++i)
          for (int j = 0; j < 2; ++j) out[i * 3 + j] = s(i, j);
      });
    }
    if (grid_fields) write_grid(g, grid);
  }

  /// Nodes in one slab of the first axis: write_derived's items for grid datasets.
  static std::size_t nodes_per_slab(const Grid<D>& grid) {
    return grid.dims[0] > 0 ? grid.num_nodes() / static_cast<std::size_t>(grid.dims[0]) : 0;
  }

  std::vector<hsize_t> node_dims() const {
    std::vector<hsize_t> dims(D);
    for (int a = 0; a < D; ++a) dims[a] = static_cast<hsize_t>(grid_dims[a]);
    return dims;
  }

  void write_grid(const Loc& frame, const Grid<D>& grid) {
    const std::size_t nodes = grid.num_nodes();
    if (grid.mass.size() != nodes || grid.momentum.size() != nodes)
      throw std::invalid_argument("SnapshotWriter: grid field sizes do not match the grid dimensions");
    if (!grid_geometry_written) {
      write_grid_geometry(grid);
    } else if (grid.dims != grid_dims || grid.origin != grid_origin || grid.dx != grid_dx) {
      throw std::invalid_argument("SnapshotWriter: the grid changed between frames; "
                                  "grid output assumes one fixed grid per run (in '" + h5.path() + "')");
    }
    h5::Group group = create_group(h5, frame, "grid");
    const Loc g{group.get(), frame.child("grid")};
    std::vector<hsize_t> dims = node_dims();
    write_direct(h5, g, "mass", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, dims, grid.mass.data());
    std::vector<hsize_t> vdims = dims;
    vdims.push_back(D);
    write_direct(h5, g, "velocity", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, vdims,
                 nodes ? grid.momentum.data()->data() : nullptr);
    if constexpr (D == 2) {
      vdims.back() = 3;
      const std::size_t per_slab = nodes_per_slab(grid);
      write_derived(h5, g, "velocity3", vdims, [&](std::size_t i0, double* out) {
        for (std::size_t r = 0; r < per_slab; ++r, out += 3) {
          const Vec<D>& v = grid.momentum[i0 * per_slab + r];
          out[0] = v[0];
          out[1] = v[1];
          out[2] = 0.0;
        }
      });
    }
  }

  /// Root attributes and node coordinates, written at the first frame (the
  /// grid is only known then).
  void write_grid_geometry(const Grid<D>& grid) {
    grid_dims = grid.dims;
    grid_origin = grid.origin;
    grid_dx = grid.dx;
    const Loc root{file.get(), "/"};
    write_attribute(h5, root, "grid_origin", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, grid_origin.data(), D);
    write_attribute(h5, root, "grid_dx", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &grid_dx);
    std::int64_t dims64[D];
    for (int a = 0; a < D; ++a) dims64[a] = grid_dims[a];
    write_attribute(h5, root, "grid_dims", H5T_STD_I64LE, H5T_NATIVE_INT64, dims64, D);
    std::vector<hsize_t> cdims = node_dims();
    cdims.push_back(D);
    const std::size_t per_slab = nodes_per_slab(grid);
    write_derived(h5, root, "grid_coordinates", cdims, [&](std::size_t i0, double* out) {
      for (std::size_t r = 0; r < per_slab; ++r) {
        const Vec<D> x = grid.node_position(grid.node_of(i0 * per_slab + r));
        for (int a = 0; a < D; ++a) out[r * D + a] = x[a];
      }
    });
    grid_geometry_written = true;
  }

  static std::string vertex_ids_name(hsize_t n) { return "vertex_ids_" + std::to_string(n); }

  /// XDMF readers (ParaView's Xdmf3 readers) make one vertex cell per point
  /// only from explicit Polyvertex connectivity, 0..N-1. It is the same for
  /// every frame with N points, so it is written once per distinct N.
  void ensure_vertex_ids(std::size_t n_points) {
    const hsize_t n = n_points;
    if (n == 0 || std::find(vertex_id_sizes.begin(), vertex_id_sizes.end(), n) != vertex_id_sizes.end()) return;
    const std::string name = vertex_ids_name(n);
    try {
      write_derived_int64(Loc{xdmf_group.get(), "/xdmf"}, name.c_str(), n);
    } catch (...) {
      // Not recorded in vertex_id_sizes, so a later frame writes it again: remove the remains.
      H5Ldelete(xdmf_group.get(), name.c_str(), H5P_DEFAULT);
      throw;
    }
    vertex_id_sizes.push_back(n);
  }

  void write_derived_int64(const Loc& loc, const char* name, hsize_t n) {
    const std::string object = loc.child(name);
    h5::Dataset ds = create_dataset(h5, loc, name, H5T_STD_I64LE, {n});
    h5::Dataspace file_space(h5.id(H5Dget_space(ds.get()), "get the dataspace of", object));
    std::vector<std::int64_t> buf(std::min<hsize_t>(n, kBlockValues));
    for (hsize_t start = 0; start < n; start += buf.size()) {
      const hsize_t count = std::min<hsize_t>(buf.size(), n - start);
      for (hsize_t i = 0; i < count; ++i) buf[i] = static_cast<std::int64_t>(start + i);
      h5.ok(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, &start, nullptr, &count, nullptr),
            "select a block of", object);
      h5::Dataspace mem_space(h5.id(H5Screate_simple(1, &count, nullptr), "create a memory dataspace for", object));
      h5.ok(H5Dwrite(ds.get(), H5T_NATIVE_INT64, mem_space.get(), file_space.get(), H5P_DEFAULT, buf.data()),
            "write dataset", object);
    }
  }

  /// Opening <Grid>, time and Polyvertex topology of a point set of n vertices.
  std::string polyvertex_xml(const std::string& grid_name, hsize_t n, double time) const {
    std::string s;
    s += "      <Grid Name=\"" + grid_name + "\" GridType=\"Uniform\">\n";
    s += "        <Time Value=\"" + format_double(time) + "\"/>\n";
    s += "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + std::to_string(n) +
         "\" NodesPerElement=\"1\">\n";
    if (n > 0) s += "          " + data_item({n}, "Int", 8, h5_name, "/xdmf/" + vertex_ids_name(n)) + "\n";
    s += "        </Topology>\n";
    return s;
  }

  std::string points_xml(const std::string& name, std::size_t n_points, double time, bool coupling) const {
    const hsize_t n = n_points;
    const std::string base = "/frames/" + name + "/";
    std::string s = polyvertex_xml("points_" + name, n, time);
    s += std::string("        <Geometry GeometryType=\"") + (D == 2 ? "XY" : "XYZ") + "\">\n";
    s += "          " + data_item({n, D}, "Float", 8, h5_name, base + "position") + "\n";
    s += "        </Geometry>\n";
    if constexpr (D == 2) {
      s += attribute_xml("velocity", "Vector", data_item({n, 3}, "Float", 8, h5_name, base + "velocity3"));
      s += attribute_xml("stress", "Tensor", data_item({n, 3, 3}, "Float", 8, h5_name, base + "stress3"));
    } else {
      s += attribute_xml("velocity", "Vector", data_item({n, 3}, "Float", 8, h5_name, base + "velocity"));
      s += attribute_xml("stress", "Tensor", data_item({n, 3, 3}, "Float", 8, h5_name, base + "stress"));
    }
    for (const char* scalar : {"pressure", "mass", "volume", "plastic_strain"})
      s += attribute_xml(scalar, "Scalar", data_item({n}, "Float", 8, h5_name, base + scalar));
    s += attribute_xml("material", "Scalar", data_item({n}, "UInt", 2, h5_name, base + "material"));
    if (coupling) {
      s += attribute_xml("zone", "Scalar", data_item({n}, "Char", 1, h5_name, base + "zone"));
      s += attribute_xml("weight", "Scalar", data_item({n}, "Float", 8, h5_name, base + "weight"));
    }
    s += "      </Grid>\n";
    return s;
  }

  std::string grains_xml(const std::string& name, std::size_t n_grains, double time) const {
    const hsize_t n = n_grains;
    const std::string base = "/frames/" + name + "/grains/";
    std::string s = polyvertex_xml("grains_" + name, n, time);
    s += "        <Geometry GeometryType=\"XYZ\">\n";
    s += "          " + data_item({n, 3}, "Float", 8, h5_name, base + "position") + "\n";
    s += "        </Geometry>\n";
    s += attribute_xml("velocity", "Vector", data_item({n, 3}, "Float", 8, h5_name, base + "velocity"));
    for (const char* scalar : {"radius", "mass", "weight"})
      s += attribute_xml(scalar, "Scalar", data_item({n}, "Float", 8, h5_name, base + scalar));
    s += attribute_xml("zone", "Scalar", data_item({n}, "Char", 1, h5_name, base + "zone"));
    s += "      </Grid>\n";
    return s;
  }

  std::string grid_xml(const std::string& name, double time) const {
    const std::vector<hsize_t> dims = node_dims();
    std::vector<hsize_t> vdims = dims;
    vdims.push_back(3);
    std::vector<hsize_t> cdims = dims;
    cdims.push_back(D);
    const std::string base = "/frames/" + name + "/grid/";
    std::string s;
    s += "      <Grid Name=\"grid_" + name + "\" GridType=\"Uniform\">\n";
    s += "        <Time Value=\"" + format_double(time) + "\"/>\n";
    s += std::string("        <Topology TopologyType=\"") + (D == 2 ? "2DSMesh" : "3DSMesh") + "\" Dimensions=\"" +
         join_dims(dims) + "\"/>\n";
    s += std::string("        <Geometry GeometryType=\"") + (D == 2 ? "XY" : "XYZ") + "\">\n";
    s += "          " + data_item(cdims, "Float", 8, h5_name, "/grid_coordinates") + "\n";
    s += "        </Geometry>\n";
    s += attribute_xml("mass", "Scalar", data_item(dims, "Float", 8, h5_name, base + "mass"));
    s += attribute_xml("velocity", "Vector",
                       data_item(vdims, "Float", 8, h5_name, base + (D == 2 ? "velocity3" : "velocity")));
    s += "      </Grid>\n";
    return s;
  }
};

template <int D>
SnapshotWriter<D>::SnapshotWriter(const std::string& directory, const Scene& scene) {
  h5::ErrorSilencer quiet;
  impl_ = std::make_unique<Impl>(directory, scene);
}

template <int D>
SnapshotWriter<D>::~SnapshotWriter() {
  h5::ErrorSilencer quiet;
  impl_.reset();  // closes the file while HDF5's error printing is off
}

template <int D>
void SnapshotWriter<D>::write(const Particles<D>& points, const Grid<D>& grid, double time, long step,
                              const GrainFrame* grains, const PointCoupling* coupling) {
  h5::ErrorSilencer quiet;
  impl_->write(points, grid, time, step, grains, coupling);
}

template <int D>
int SnapshotWriter<D>::frames_written() const {
  return impl_->frames_written;
}

template class SnapshotWriter<2>;
template class SnapshotWriter<3>;

}  // namespace mpm
