#pragma once
// Internal to the HDF5 files of src/io (event files, random-trigger files), not installed:
// the quiet, locked calls into libhdf5, owned identifiers and the column types.

#include <hdf5.h>

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>

#include <fmt/format.h>

#include "event_file_internal.hpp"

namespace emcalign::io::detail {

// ==================================================================================== HDF5

// HDF5 prints its error stack to stderr by default; the library must not print. This
// silences it for the scope of one call into HDF5 and restores what the caller had.
//
// It also keeps HDF5 from closing what is left open when the process exits: after a failed
// final write (a full disk), HDF5 1.10 keeps the file half-closed and its exit handler
// crashes on it. emcalign closes every file it opens itself, so the handler has nothing to
// do (H5dont_atexit must come before the first HDF5 call, which this is).
// It holds the process's HDF5 lock (event_file_internal.hpp) for the same scope.
class Hdf5Quiet {
 public:
  Hdf5Quiet() {
    [[maybe_unused]] static const bool noExitHandler = (H5dont_atexit(), true);
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~Hdf5Quiet() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }
  Hdf5Quiet(const Hdf5Quiet&) = delete;
  Hdf5Quiet& operator=(const Hdf5Quiet&) = delete;

 private:
  Hdf5Lock lock_;  // first: taken before the first call into HDF5, released after the last
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

// The most specific message of HDF5's error stack (then cleared), e.g. "file signature not
// found" or "truncated file: eof = …"; of a failed system call, the system's words ("No
// space left on device") rather than HDF5's dump of the call.
inline std::string hdf5Reason() {
  std::string reason;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned n, const H5E_error2_t* e, void* data) -> herr_t {
        if (n == 0 && e->desc != nullptr) *static_cast<std::string*>(data) = e->desc;
        return 0;
      },
      &reason);
  H5Eclear2(H5E_DEFAULT);
  constexpr std::string_view kSystem = "error message = '";
  if (const auto at = reason.find(kSystem); at != std::string::npos) {
    const auto from = at + kSystem.size();
    const auto to = reason.find('\'', from);
    if (to != std::string::npos) return reason.substr(from, to - from);
  }
  if (reason.size() > 300) reason = reason.substr(0, 300) + "…";
  return reason.empty() ? "libhdf5 gives no reason (the file is probably damaged)" : reason;
}

// An owned HDF5 identifier.
class Hid {
 public:
  using Closer = herr_t (*)(hid_t);
  Hid() = default;
  Hid(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Hid(Hid&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), closer_(o.closer_) {}
  Hid& operator=(Hid&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      closer_ = o.closer_;
    }
    return *this;
  }
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  ~Hid() { reset(); }

  [[nodiscard]] hid_t get() const { return id_; }
  [[nodiscard]] bool valid() const { return id_ >= 0; }
  /// Closes now; false when HDF5 reports a failure (e.g. the final write of a file).
  bool reset() {
    bool ok = true;
    if (id_ >= 0 && closer_ != nullptr) ok = closer_(id_) >= 0;
    id_ = H5I_INVALID_HID;
    return ok;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

// Compression: HDF5's byte shuffle, then LZ4 (the registered HDF5 filter 32004, Debian's
// hdf5-filter-plugin). Chosen by measurement (docs/apply.md, "Speed"): against shuffle +
// deflate 4 the files are 10 % larger, written 2× and read 3–5× faster.
constexpr H5Z_filter_t kLz4Filter = 32004;

enum class Kind { I8, I32, I64, F64 };

// The file type of an event file's column (event_file_internal.hpp's kColumnNames).
inline Kind eventKind(int column) {
  switch (column) {
    case kRun:
      return Kind::I32;
    case kEvent:
      return Kind::I64;
    case kVeto:
    case kCharged:
      return Kind::I8;
    default:
      return Kind::F64;
  }
}

inline hid_t fileType(Kind k) {
  switch (k) {
    case Kind::I8:
      return H5T_STD_I8LE;
    case Kind::I32:
      return H5T_STD_I32LE;
    case Kind::I64:
      return H5T_STD_I64LE;
    case Kind::F64:
      return H5T_IEEE_F64LE;
  }
  return H5T_IEEE_F64LE;
}

inline hid_t memoryType(Kind k) {
  switch (k) {
    case Kind::I8:
      return H5T_NATIVE_INT8;
    case Kind::I32:
      return H5T_NATIVE_INT32;
    case Kind::I64:
      return H5T_NATIVE_INT64;
    case Kind::F64:
      return H5T_NATIVE_DOUBLE;
  }
  return H5T_NATIVE_DOUBLE;
}

inline const char* kindName(Kind k) {
  switch (k) {
    case Kind::I8:
      return "8-bit signed integer";
    case Kind::I32:
      return "32-bit signed integer";
    case Kind::I64:
      return "64-bit signed integer";
    case Kind::F64:
      return "64-bit float";
  }
  return "?";
}

inline bool typeMatches(hid_t type, Kind k) {
  const H5T_class_t cls = H5Tget_class(type);
  const std::size_t size = H5Tget_size(type);
  switch (k) {
    case Kind::I8:
      return cls == H5T_INTEGER && size == 1 && H5Tget_sign(type) == H5T_SGN_2;
    case Kind::I32:
      return cls == H5T_INTEGER && size == 4 && H5Tget_sign(type) == H5T_SGN_2;
    case Kind::I64:
      return cls == H5T_INTEGER && size == 8 && H5Tget_sign(type) == H5T_SGN_2;
    case Kind::F64:
      return cls == H5T_FLOAT && size == 8;
  }
  return false;
}

inline std::string describeType(hid_t type) {
  const std::size_t bits = H5Tget_size(type) * 8;
  switch (H5Tget_class(type)) {
    case H5T_INTEGER:
      return fmt::format("{}-bit {} integer", bits, H5Tget_sign(type) == H5T_SGN_2 ? "signed" : "unsigned");
    case H5T_FLOAT:
      return fmt::format("{}-bit float", bits);
    case H5T_STRING:
      return "string";
    case H5T_COMPOUND:
      return "compound";
    default:
      return "another type";
  }
}

// A property list whose objects do not record times: the only thing that makes two files
// of the same rows differ byte for byte.
inline Hid creationList(hid_t cls) {
  Hid plist(H5Pcreate(cls), H5Pclose);
  if (plist.valid() && H5Pset_obj_track_times(plist.get(), 0) < 0) return {};
  return plist;
}

}  // namespace emcalign::io::detail
