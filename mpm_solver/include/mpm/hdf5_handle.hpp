#pragma once
// Small RAII helpers around the HDF5 C API: owning wrappers for hid_t
// identifiers, a scope guard that silences HDF5's automatic error printing,
// a function that turns the current error stack into a message, and writers
// of datasets and attributes that throw exceptions naming the file and object.
#include <hdf5.h>

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace mpm::h5 {

/// Owns one HDF5 identifier and releases it with `Close` (H5Fclose, H5Gclose, ...).
/// Move-only. An invalid (negative) identifier is never closed.
template <herr_t (*Close)(hid_t)>
class Handle {
 public:
  Handle() = default;
  explicit Handle(hid_t id) : id_(id) {}
  ~Handle() { reset(); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, H5I_INVALID_HID)) {}
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = std::exchange(other.id_, H5I_INVALID_HID);
    }
    return *this;
  }

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  /// Closes the identifier now. Errors on close are ignored (a destructor cannot report them);
  /// call the H5*close function yourself through release() where the result matters.
  void reset() {
    if (id_ >= 0) Close(id_);
    id_ = H5I_INVALID_HID;
  }
  /// Gives up ownership without closing.
  hid_t release() { return std::exchange(id_, H5I_INVALID_HID); }

 private:
  hid_t id_ = H5I_INVALID_HID;
};

using File = Handle<&H5Fclose>;
using Group = Handle<&H5Gclose>;
using Dataspace = Handle<&H5Sclose>;
using Dataset = Handle<&H5Dclose>;
using Attribute = Handle<&H5Aclose>;
using Datatype = Handle<&H5Tclose>;
using PropertyList = Handle<&H5Pclose>;

/// Turns HDF5's automatic error-stack printing off for the lifetime of the
/// guard and restores the previous handler afterwards, so that code reporting
/// HDF5 errors itself (as exceptions) does not also spray them on stderr.
class ErrorSilencer {
 public:
  ErrorSilencer() {
    H5Eget_auto2(H5E_DEFAULT, &old_func_, &old_data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~ErrorSilencer() { H5Eset_auto2(H5E_DEFAULT, old_func_, old_data_); }
  ErrorSilencer(const ErrorSilencer&) = delete;
  ErrorSilencer& operator=(const ErrorSilencer&) = delete;

 private:
  H5E_auto2_t old_func_ = nullptr;
  void* old_data_ = nullptr;
};

/// The innermost (most specific) description on the current thread's HDF5
/// error stack, on one line; the outer entries only repeat the context.
/// Clears the stack. Empty if there is no error.
inline std::string error_stack_message() {
  std::string text;
  auto walk = [](unsigned n, const H5E_error2_t* err, void* data) -> herr_t {
    if (n == 0 && err && err->desc) *static_cast<std::string*>(data) = err->desc;
    return 0;
  };
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, walk, &text);
  H5Eclear2(H5E_DEFAULT);
  for (char& c : text)
    if (c == '\n' || c == '\r') c = ' ';
  // A failed system call is described at length ("file write failed: time = ..., filename = ...,
  // file descriptor = 17, errno = 28, error message = 'No space left on device', buf = ...");
  // keep what failed and the system's reason, which messages cut to a fixed length would lose.
  const std::string key = "error message = '";
  if (const auto at = text.find(key); at != std::string::npos) {
    const auto end = text.find('\'', at + key.size());
    const auto colon = text.find(':');
    if (end != std::string::npos && colon != std::string::npos && colon < at)
      text = text.substr(0, colon) + ": " + text.substr(at + key.size(), end - at - key.size());
  }
  return text;
}

/// Checks HDF5 results and turns failures into exceptions naming the file,
/// the operation and the object.
class Checker {
 public:
  /// `kind` names the file in messages, e.g. "HDF5 output file".
  explicit Checker(std::string path, std::string kind = "HDF5 output file")
      : path_(std::move(path)), kind_(std::move(kind)) {}

  [[noreturn]] void fail(const char* op, const std::string& object) const {
    const std::string detail = h5::error_stack_message();
    std::string msg = kind_ + " '" + path_ + "': cannot " + op;
    if (!object.empty()) msg += " '" + object + "'";
    if (!detail.empty()) msg += " (" + detail + ")";
    throw std::runtime_error(msg);
  }
  hid_t id(hid_t v, const char* op, const std::string& object) const {
    if (v < 0) fail(op, object);
    return v;
  }
  void ok(herr_t v, const char* op, const std::string& object) const {
    if (v < 0) fail(op, object);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::string kind_;
};

/// A location (file or group) together with its path inside the file, for messages.
struct Loc {
  hid_t id;
  std::string path;
  std::string child(const char* name) const { return (path == "/" ? "/" : path + "/") + name; }
};

inline h5::Group create_group(const Checker& h5, const Loc& loc, const char* name) {
  return h5::Group(h5.id(H5Gcreate2(loc.id, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create group",
                         loc.child(name)));
}

inline h5::Dataset create_dataset(const Checker& h5, const Loc& loc, const char* name, hid_t file_type,
                                  const std::vector<hsize_t>& dims) {
  const std::string object = loc.child(name);
  h5::Dataspace space(h5.id(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                            "create the dataspace of", object));
  // Default creation properties: contiguous layout, no filters; fast to write and to read whole.
  return h5::Dataset(h5.id(H5Dcreate2(loc.id, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                           "create dataset", object));
}

inline std::size_t element_count(const std::vector<hsize_t>& dims) {
  std::size_t n = 1;
  for (hsize_t d : dims) n *= static_cast<std::size_t>(d);
  return n;
}

/// Writes a dataset straight from memory laid out exactly like the dataset.
inline void write_direct(const Checker& h5, const Loc& loc, const char* name, hid_t file_type, hid_t mem_type,
                         const std::vector<hsize_t>& dims, const void* data) {
  h5::Dataset ds = create_dataset(h5, loc, name, file_type, dims);
  if (element_count(dims) == 0) return;  // nothing to write (and data may be null)
  h5.ok(H5Dwrite(ds.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "write dataset", loc.child(name));
}

/// A numeric attribute: a scalar if n == 0, else a 1-D array of n values.
inline void write_attribute(const Checker& h5, const Loc& loc, const char* name, hid_t file_type, hid_t mem_type,
                            const void* data, hsize_t n = 0) {
  const std::string object = "attribute " + std::string(name) + " of " + loc.path;
  h5::Dataspace space(h5.id(n == 0 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr),
                            "create the dataspace of", object));
  h5::Attribute attr(h5.id(H5Acreate2(loc.id, name, file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), "create",
                           object));
  h5.ok(H5Awrite(attr.get(), mem_type, data), "write", object);
}

inline h5::Datatype utf8_string_type(const Checker& h5) {
  h5::Datatype type(h5.id(H5Tcopy(H5T_C_S1), "copy", "the string datatype"));
  h5.ok(H5Tset_size(type.get(), H5T_VARIABLE), "set the size of", "the string datatype");
  h5.ok(H5Tset_cset(type.get(), H5T_CSET_UTF8), "set the character set of", "the string datatype");
  return type;
}

inline void write_string_attribute(const Checker& h5, const Loc& loc, const char* name, const std::string& value) {
  h5::Datatype type = utf8_string_type(h5);
  const char* ptr = value.c_str();
  write_attribute(h5, loc, name, type.get(), type.get(), &ptr);
}

}  // namespace mpm::h5
