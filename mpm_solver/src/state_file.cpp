// The MPM side of a coupled run's restart: <restart>.mpm.h5 next to the DEM host's restart file.
//
// Layout (floating point data float64 in the file as in memory, so values round-trip exactly):
//
//   /                  attributes: format = "mpm-coupled-state", format_version (int32) = 3,
//                      dimension (int32), mpm_version (string), time, solver_time (float64),
//                      solver_steps, dem_step, exchanges (int64), cell (float64),
//                      box_lo, box_hi (3 x float64), model (int32, coupler::ModelId)
//   /points/           one dataset per Particles field, named as the struct member; N points:
//       x, v, body_accel             N x D
//       C, stress, be                N x D x D, row-major: [p, i, j] = M(i, j)
//       mass, volume0, J, plastic_strain, fill_pressure   N
//       material                     N, uint16
//       weight                       N, float32
//   /zones             int8, one per grid cell
//   /support_nodes     uint64, nodes with a support force
//   /support_forces    support_nodes x D
//   /support_masses    reduced mass of each support node when its force was set
//   /support_budgets   energy each support force may still give the relative motion (J, J/m in 2D)
//   /support_gaps      support_nodes x D, v_dem - v_mpm the last agreement left at each
//
// Version 2 added the support budgets and gaps (coupler/support_force.hpp), version 3 the points'
// fill pressure (docs/design.md section 5.4).
#include "mpm/state_file.hpp"

#include <filesystem>
#include <stdexcept>
#include <type_traits>

#include "coupler/version.hpp"
#include "mpm/hdf5_handle.hpp"

namespace mpm {
namespace {

constexpr const char* kFormat = "mpm-coupled-state";
constexpr int kFormatVersion = 3;
constexpr const char* kKind = "MPM state file";

/// Empty if the state's arrays have consistent lengths, else what is wrong.
template <int D>
std::string inconsistency(const ContinuumState<D>& s) {
  std::string why;
  const std::size_t n = s.points.x.size();
  for_each_point_field(s.points, [&](const char* name, const auto& field) {
    if (why.empty() && field.size() != n)
      why = "points field '" + std::string(name) + "' has " + std::to_string(field.size()) + " values for " +
            std::to_string(n) + " points";
  });
  const std::size_t nodes = s.support_nodes.size();
  if (why.empty() && (s.support_forces.size() != nodes || s.support_masses.size() != nodes ||
                      s.support_budgets.size() != nodes || s.support_gaps.size() != nodes))
    why = std::to_string(s.support_forces.size()) + " support forces, " + std::to_string(s.support_masses.size()) +
          " masses, " + std::to_string(s.support_budgets.size()) + " budgets and " +
          std::to_string(s.support_gaps.size()) + " gaps for " + std::to_string(nodes) + " support nodes";
  return why;
}

template <class T>
constexpr bool is_matrix() {
  if constexpr (std::is_base_of_v<Eigen::MatrixBase<T>, T>) return T::ColsAtCompileTime > 1;
  return false;
}

/// How an array element is stored: file and memory types, and the dataset dimensions of one element.
struct Layout {
  hid_t file_type, mem_type;
  std::vector<hsize_t> item;
};

template <class T>
Layout layout_of() {
  if constexpr (std::is_same_v<T, double>) return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}};
  else if constexpr (std::is_same_v<T, float>) return {H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, {}};
  else if constexpr (std::is_same_v<T, std::uint16_t>) return {H5T_STD_U16LE, H5T_NATIVE_UINT16, {}};
  else if constexpr (std::is_same_v<T, std::uint64_t>) return {H5T_STD_U64LE, H5T_NATIVE_UINT64, {}};
  else if constexpr (std::is_same_v<T, std::int8_t>) return {H5T_STD_I8LE, H5T_NATIVE_INT8, {}};
  else {
    static_assert(sizeof(T) == T::SizeAtCompileTime * sizeof(double), "Eigen vectors and matrices: packed doubles");
    if constexpr (is_matrix<T>())
      return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {hsize_t(T::RowsAtCompileTime), hsize_t(T::ColsAtCompileTime)}};
    else
      return {H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {hsize_t(T::RowsAtCompileTime)}};
  }
}

std::vector<hsize_t> dims_of(std::size_t n, const Layout& l) {
  std::vector<hsize_t> dims{n};
  dims.insert(dims.end(), l.item.begin(), l.item.end());
  return dims;
}

std::string shape_text(const std::vector<hsize_t>& dims) {
  std::string s = "[";
  for (std::size_t i = 0; i < dims.size(); ++i) s += (i ? ", " : "") + std::to_string(dims[i]);
  return s + "]";
}

template <class T>
void write_array(const h5::Checker& h5, const h5::Loc& loc, const char* name, const std::vector<T>& v) {
  const Layout l = layout_of<T>();
  if constexpr (is_matrix<T>()) {
    // Eigen stores column-major, so the storage of each transpose is the row-major matrix.
    std::vector<T> rows(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) rows[i] = v[i].transpose();
    h5::write_direct(h5, loc, name, l.file_type, l.mem_type, dims_of(v.size(), l), rows.data());
  } else {
    h5::write_direct(h5, loc, name, l.file_type, l.mem_type, dims_of(v.size(), l), v.data());
  }
}

template <class T>
void read_array(const h5::Checker& h5, const h5::Loc& loc, const char* name, std::vector<T>& v) {
  const std::string object = loc.child(name);
  const Layout l = layout_of<T>();
  h5::Dataset ds(h5.id(H5Dopen2(loc.id, name, H5P_DEFAULT), "open dataset", object));
  h5::Dataspace space(h5.id(H5Dget_space(ds.get()), "get the dataspace of", object));
  std::vector<hsize_t> dims(H5S_MAX_RANK);
  const int rank = H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  if (rank < 0) h5.fail("get the dimensions of", object);
  dims.resize(rank);
  if (rank < 1 || dims != dims_of(dims[0], l))
    throw UserError(std::string(kKind) + " '" + h5.path() + "': dataset '" + object + "' has shape " +
                    shape_text(dims) + " where " + shape_text(dims_of(0, l)).replace(1, 1, "n") + " is expected");
  v.resize(dims[0]);
  if (!v.empty())
    h5.ok(H5Dread(ds.get(), l.mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), "read dataset", object);
  if constexpr (is_matrix<T>())
    for (T& m : v) m.transposeInPlace();
}

/// Reads a numeric attribute of n values into out.
void read_attribute(const h5::Checker& h5, hid_t loc, const char* name, hid_t mem_type, void* out, hssize_t n = 1) {
  const std::string object = "attribute " + std::string(name) + " of /";
  h5::Attribute attr(h5.id(H5Aopen(loc, name, H5P_DEFAULT), "open", object));
  h5::Dataspace space(h5.id(H5Aget_space(attr.get()), "get the dataspace of", object));
  if (H5Sget_simple_extent_npoints(space.get()) != n)
    throw UserError(std::string(kKind) + " '" + h5.path() + "': " + object + " does not have " + std::to_string(n) +
                    " value(s)");
  h5.ok(H5Aread(attr.get(), mem_type, out), "read", object);
}

template <class T>
T attribute(const h5::Checker& h5, hid_t loc, const char* name, hid_t mem_type) {
  T value{};
  read_attribute(h5, loc, name, mem_type, &value);
  return value;
}

/// The value of a scalar variable-length string attribute; empty if there is none.
std::string string_attribute(hid_t loc, const char* name) {
  if (H5Aexists(loc, name) <= 0) return {};
  h5::Attribute attr(H5Aopen(loc, name, H5P_DEFAULT));
  h5::Datatype type(H5Aget_type(attr.get()));
  h5::Dataspace space(H5Aget_space(attr.get()));
  if (!type.valid() || !space.valid() || H5Tget_class(type.get()) != H5T_STRING ||
      H5Tis_variable_str(type.get()) <= 0 || H5Sget_simple_extent_npoints(space.get()) != 1)
    return {};
  char* text = nullptr;
  if (H5Aread(attr.get(), type.get(), &text) < 0 || !text) return {};
  std::string value = text;
  H5free_memory(text);
  return value;
}

/// Runs f with HDF5's error printing off, reporting HDF5 failures as UserError.
template <class F>
auto user_errors(F&& f) {
  h5::ErrorSilencer quiet;
  try {
    return f();
  } catch (const UserError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw UserError(e.what());
  }
}

}  // namespace

template <int D>
void save_state(const std::string& path, const ContinuumState<D>& s) {
  if (const std::string why = inconsistency(s); !why.empty())
    throw std::invalid_argument("save_state('" + path + "'): " + why);
  user_errors([&] {
    const h5::Checker h5(path, kKind);
    h5::File file(h5.id(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), "create the file", ""));
    {
      const h5::Loc root{file.get(), "/"};
      const int version = kFormatVersion, dim = D, model = s.model;
      const std::int64_t steps = s.solver_steps;
      h5::write_string_attribute(h5, root, "format", kFormat);
      h5::write_attribute(h5, root, "format_version", H5T_STD_I32LE, H5T_NATIVE_INT, &version);
      h5::write_attribute(h5, root, "dimension", H5T_STD_I32LE, H5T_NATIVE_INT, &dim);
      h5::write_string_attribute(h5, root, "mpm_version", coupler::release_version());
      h5::write_attribute(h5, root, "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &s.time);
      h5::write_attribute(h5, root, "solver_time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &s.solver_time);
      h5::write_attribute(h5, root, "solver_steps", H5T_STD_I64LE, H5T_NATIVE_INT64, &steps);
      h5::write_attribute(h5, root, "dem_step", H5T_STD_I64LE, H5T_NATIVE_INT64, &s.dem_step);
      h5::write_attribute(h5, root, "exchanges", H5T_STD_I64LE, H5T_NATIVE_INT64, &s.exchanges);
      h5::write_attribute(h5, root, "cell", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &s.cell);
      h5::write_attribute(h5, root, "box_lo", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, s.box_lo, 3);
      h5::write_attribute(h5, root, "box_hi", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, s.box_hi, 3);
      h5::write_attribute(h5, root, "model", H5T_STD_I32LE, H5T_NATIVE_INT, &model);

      h5::Group group = h5::create_group(h5, root, "points");
      const h5::Loc points{group.get(), "/points"};
      for_each_point_field(s.points, [&](const char* name, const auto& field) { write_array(h5, points, name, field); });
      write_array(h5, root, "zones", s.zones);
      write_array(h5, root, "support_nodes", s.support_nodes);
      write_array(h5, root, "support_forces", s.support_forces);
      write_array(h5, root, "support_masses", s.support_masses);
      write_array(h5, root, "support_budgets", s.support_budgets);
      write_array(h5, root, "support_gaps", s.support_gaps);
    }
    h5.ok(H5Fclose(file.release()), "close the file", "");
  });
}

template <int D>
ContinuumState<D> load_state(const std::string& path) {
  if (!std::filesystem::exists(path))
    throw UserError("the MPM state file '" + path +
                    "' does not exist: it is written next to the DEM host's restart file as <restart>.mpm.h5");
  return user_errors([&] {
    const h5::Checker h5(path, kKind);
    const std::string not_state = "'" + path + "' is not an MPM state file";
    h5::File file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
    if (!file.valid()) throw UserError(not_state + " (HDF5 cannot open it: " + h5::error_stack_message() + ")");
    const hid_t root = file.get();
    const std::string format = string_attribute(root, "format");
    if (format != kFormat)
      throw UserError(not_state + (format.empty() ? std::string(" (it has no format attribute)")
                                                  : " (its format is '" + format + "', not '" + kFormat + "')"));
    const int version = attribute<int>(h5, root, "format_version", H5T_NATIVE_INT);
    if (version != kFormatVersion)
      throw UserError("the MPM state file '" + path + "' has format version " + std::to_string(version) +
                      "; this mpm_solver (" + coupler::release_version() + ") reads version " +
                      std::to_string(kFormatVersion));
    const int dim = attribute<int>(h5, root, "dimension", H5T_NATIVE_INT);
    if (dim != D)
      throw UserError("the MPM state file '" + path + "' holds a " + std::to_string(dim) +
                      "-dimensional continuum, but this run is " + std::to_string(D) + "-dimensional");

    ContinuumState<D> s;
    s.time = attribute<double>(h5, root, "time", H5T_NATIVE_DOUBLE);
    s.solver_time = attribute<double>(h5, root, "solver_time", H5T_NATIVE_DOUBLE);
    s.solver_steps = static_cast<long>(attribute<std::int64_t>(h5, root, "solver_steps", H5T_NATIVE_INT64));
    s.dem_step = attribute<std::int64_t>(h5, root, "dem_step", H5T_NATIVE_INT64);
    s.exchanges = attribute<std::int64_t>(h5, root, "exchanges", H5T_NATIVE_INT64);
    s.cell = attribute<double>(h5, root, "cell", H5T_NATIVE_DOUBLE);
    read_attribute(h5, root, "box_lo", H5T_NATIVE_DOUBLE, s.box_lo, 3);
    read_attribute(h5, root, "box_hi", H5T_NATIVE_DOUBLE, s.box_hi, 3);
    s.model = attribute<int>(h5, root, "model", H5T_NATIVE_INT);

    const h5::Loc top{root, "/"};
    {
      h5::Group group(h5.id(H5Gopen2(root, "points", H5P_DEFAULT), "open group", "/points"));
      const h5::Loc points{group.get(), "/points"};
      for_each_point_field(s.points, [&](const char* name, auto& field) { read_array(h5, points, name, field); });
    }
    read_array(h5, top, "zones", s.zones);
    read_array(h5, top, "support_nodes", s.support_nodes);
    read_array(h5, top, "support_forces", s.support_forces);
    read_array(h5, top, "support_masses", s.support_masses);
    read_array(h5, top, "support_budgets", s.support_budgets);
    read_array(h5, top, "support_gaps", s.support_gaps);
    if (const std::string why = inconsistency(s); !why.empty())
      throw UserError("the MPM state file '" + path + "' is inconsistent: " + why);
    return s;
  });
}

template void save_state<2>(const std::string&, const ContinuumState<2>&);
template void save_state<3>(const std::string&, const ContinuumState<3>&);
template ContinuumState<2> load_state<2>(const std::string&);
template ContinuumState<3> load_state<3>(const std::string&);

}  // namespace mpm
