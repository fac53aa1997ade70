// RAII for HDF5: the owner of one identifier (file, group, dataset, dataspace, datatype,
// attribute, property list), closed when the owner goes, also when a call between open and close
// throws; no H5*close by hand.
#pragma once
#include <hdf5.h>

#include <utility>

namespace peri {

/// Owner of one HDF5 identifier, closed by the function given with it (H5Fclose, H5Gclose, ...).
/// An owner of a negative identifier (a failed open or create) holds nothing: ok() is false.
class H5Id {
 public:
  H5Id() = default;
  H5Id(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  H5Id(const H5Id&) = delete;
  H5Id& operator=(const H5Id&) = delete;
  H5Id(H5Id&& o) noexcept : id_(std::exchange(o.id_, -1)), close_(o.close_) {}
  H5Id& operator=(H5Id&& o) noexcept {
    std::swap(id_, o.id_);
    std::swap(close_, o.close_);
    return *this;
  }
  ~H5Id() { close(); }
  hid_t get() const { return id_; }
  bool ok() const { return id_ >= 0; }
  /// Give the identifier up without closing it: for a file whose writes failed, which HDF5 1.10
  /// may crash closing (its metadata flush meets the failed MPI-IO file). The owner then holds
  /// nothing.
  hid_t abandon() { return std::exchange(id_, -1); }
  /// Close now and report failure (a file's close flushes it); the owner then holds nothing.
  bool close() {
    const herr_t r = id_ >= 0 ? close_(id_) : 0;
    id_ = -1;
    return r >= 0;
  }

 private:
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

}  // namespace peri
