#include "peri/io/checkpoint.hpp"

#include <fcntl.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <sstream>

#include "peri/core/collective.hpp"
#include "peri/core/error.hpp"
#include "peri/core/hdf5.hpp"
#include "peri/io/output.hpp"

namespace peri {
namespace {

constexpr char kMagic[] = "peridrive checkpoint\n";
constexpr std::size_t kMaxExtras = 4096;
constexpr hsize_t kChunkRows = hsize_t(1) << 16;  // rows a reader streams at a time

// ------------------------------------------------------------------------------------------------
// Writing (collective)

std::string bcast_string(const std::string& s, MPI_Comm comm) {
  long long n = static_cast<long long>(s.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
  std::string out = s;
  out.resize(static_cast<std::size_t>(n));
  if (n > 0) MPI_Bcast(out.data(), static_cast<int>(n), MPI_CHAR, 0, comm);
  return out;
}

/// The collective writer of one file: every HDF5 call that may fail is followed by one verdict
/// of all ranks (agree_on_message), so that a failure on any rank ends the write on every rank at
/// the same call and none waits in a collective call that another has left.
class Writer {
 public:
  Writer(std::string path, MPI_Comm comm) : path_(std::move(path)), comm_(comm) {
    MPI_Comm_rank(comm_, &rank_);
  }
  bool root() const { return rank_ == 0; }
  MPI_Comm comm() const { return comm_; }

  /// Error on every rank unless every rank's `ok`; the file (if open) is then given up.
  void agree(bool ok, const std::string& what) {
    const std::string verdict = agree_on_message(ok ? "" : "HDF5 failed at " + what, comm_);
    if (verdict.empty()) return;
    // HDF5 1.10 may crash closing a file whose MPI-IO writes failed: it is left open, and the
    // process must end without finalizing (abandoned_output_files()).
    if (file_.ok()) {
      file_.abandon();
      mark_output_file_abandoned();
    }
    throw Error("cannot write checkpoint '" + path_ + "': " + verdict);
  }

  void create(hid_t fcpl, hid_t fapl) {
    file_ = H5Id(H5Fcreate(path_.c_str(), H5F_ACC_TRUNC, fcpl, fapl), H5Fclose);
    const std::string verdict = agree_on_message(file_.ok() ? "" : "cannot create it", comm_);
    if (!verdict.empty()) {
      if (file_.ok()) {  // closing is collective: the ranks that created it give it up instead
        file_.abandon();
        mark_output_file_abandoned();
      }
      throw Error("cannot create checkpoint '" + path_ + "': " + verdict);
    }
  }
  hid_t file() const { return file_.get(); }
  void close() { agree(file_.close(), "closing the file"); }

  /// Attributes: every rank writes the same value (rank 0's, broadcast by the caller).
  void string_attr(hid_t obj, const char* name, const std::string& value) {
    H5Id type(H5Tcopy(H5T_C_S1), H5Tclose);
    bool ok = type.ok() && H5Tset_size(type.get(), std::max<std::size_t>(value.size(), 1)) >= 0;
    H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
    H5Id attr(ok ? H5Acreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT) : -1, H5Aclose);
    const std::string padded = value.empty() ? std::string(1, '\0') : value;
    ok = attr.ok() && H5Awrite(attr.get(), type.get(), padded.data()) >= 0;
    agree(ok, name);
  }
  template <class T>
  void scalar_attr(hid_t obj, const char* name, hid_t type, T value) {
    H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
    H5Id attr(H5Acreate2(obj, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    agree(attr.ok() && H5Awrite(attr.get(), type, &value) >= 0, name);
  }
  /// A text of any length (an attribute is limited to the 64 KB of its object's header); the
  /// same length on every rank, rank 0's bytes.
  void string_dataset(hid_t obj, const char* name, const std::string& value) {
    H5Id type(H5Tcopy(H5T_C_S1), H5Tclose);
    const bool typed = type.ok() && H5Tset_size(type.get(), std::max<std::size_t>(value.size(), 1)) >= 0 &&
                       H5Tset_strpad(type.get(), H5T_STR_NULLPAD) >= 0 && H5Tset_cset(type.get(), H5T_CSET_UTF8) >= 0;
    H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
    H5Id d(typed ? H5Dcreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT) : -1,
           H5Dclose);
    agree(d.ok(), name);
    bool ok = true;
    if (root()) {  // independent write of rank 0's bytes
      const std::string padded = value.empty() ? std::string(1, '\0') : value;
      ok = H5Dwrite(d.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, padded.data()) >= 0;
    }
    agree(ok, name);
  }
  /// A small dataset of `total` rows written by rank 0 alone (tallies, extras).
  template <class T>
  void root_dataset(hid_t group, const char* name, hid_t type, const std::vector<T>& v, hsize_t total, hsize_t cols) {
    H5Id d = create_dataset(group, name, type, total, cols);
    bool ok = true;
    if (root() && total > 0) {
      ok = v.size() == total * cols && H5Dwrite(d.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0;
    }
    agree(ok, name);
  }
  /// Rows [first, first + count) of a dataset of `total` rows, from every rank in one collective
  /// write.
  template <class T>
  void rows(hid_t group, const char* name, hid_t type, const T* data, hsize_t first, hsize_t count, hsize_t total,
            hsize_t cols) {
    H5Id d = create_dataset(group, name, type, total, cols);
    if (total == 0) return;
    const int nd = cols == 1 ? 1 : 2;
    H5Id filespace(H5Dget_space(d.get()), H5Sclose);
    const hsize_t start[2] = {first, 0}, counts[2] = {count, cols};
    bool ok = filespace.ok();
    if (ok && count > 0) ok = H5Sselect_hyperslab(filespace.get(), H5S_SELECT_SET, start, nullptr, counts, nullptr) >= 0;
    else if (ok) ok = H5Sselect_none(filespace.get()) >= 0;
    const hsize_t one[2] = {1, cols};
    H5Id memspace(H5Screate_simple(nd, count > 0 ? counts : one, nullptr), H5Sclose);
    if (ok && count == 0) ok = memspace.ok() && H5Sselect_none(memspace.get()) >= 0;
    H5Id dxpl(H5Pcreate(H5P_DATASET_XFER), H5Pclose);
    ok = ok && memspace.ok() && dxpl.ok() && H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE) >= 0;
    agree(ok, std::string("selecting the rows of ") + name);
    const T dummy[2] = {};
    agree(H5Dwrite(d.get(), type, memspace.get(), filespace.get(), dxpl.get(), count > 0 ? data : dummy) >= 0,
          std::string("writing ") + name);
  }
  H5Id group(hid_t file, const char* name) {
    H5Id g(H5Gcreate2(file, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    agree(g.ok(), name);
    return g;
  }

 private:
  H5Id create_dataset(hid_t group, const char* name, hid_t type, hsize_t total, hsize_t cols) {
    const hsize_t dims[2] = {total, cols};
    H5Id space(H5Screate_simple(cols == 1 ? 1 : 2, dims, nullptr), H5Sclose);
    // No fill values: every byte is written (and a parallel fill would be one more collective write).
    H5Id dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    const bool ok = space.ok() && dcpl.ok() && H5Pset_fill_time(dcpl.get(), H5D_FILL_TIME_NEVER) >= 0;
    H5Id d(ok ? H5Dcreate2(group, name, type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT) : -1, H5Dclose);
    agree(d.ok(), name);
    return d;
  }

  std::string path_;
  MPI_Comm comm_;
  int rank_ = 0;
  H5Id file_;
};

std::string hex64(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016" PRIx64, v);
  return buf;
}

std::string errno_text() { return std::strerror(errno); }

/// Hash of the bytes of `f` from `offset` to its end; also returns the file size.
std::uint64_t hash_tail(std::FILE* f, std::size_t offset, std::uint64_t& size, bool& io_error) {
  io_error = std::fseek(f, 0, SEEK_END) != 0;
  const long end = io_error ? -1 : std::ftell(f);
  io_error = io_error || end < 0 || std::fseek(f, static_cast<long>(offset), SEEK_SET) != 0;
  size = end < 0 ? 0 : static_cast<std::uint64_t>(end);
  std::uint64_t h = fnv1a64(nullptr, 0);
  std::vector<unsigned char> buf(1 << 20);
  for (;;) {
    const std::size_t n = std::fread(buf.data(), 1, buf.size(), f);
    h = fnv1a64(buf.data(), n, h);
    if (n < buf.size()) break;
  }
  io_error = io_error || std::ferror(f);
  return h;
}

void fsync_dir(const std::string& file) {
  std::string dir = std::filesystem::path(file).parent_path().string();
  if (dir.empty()) dir = ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

// ------------------------------------------------------------------------------------------------
// Reading

class Reader {
 public:
  Reader(std::string path, std::uint64_t file_bytes) : path_(std::move(path)), file_bytes_(file_bytes) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError("checkpoint '" + path_ + "': " + what);
  }

  std::string string_attr(hid_t obj, const char* name) const {
    H5Id attr(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose);
    if (!attr.ok()) fail(std::string("missing attribute '") + name + "'");
    H5Id type(H5Aget_type(attr.get()), H5Tclose);
    H5Id space(H5Aget_space(attr.get()), H5Sclose);
    return fixed_string("attribute '" + std::string(name) + "'", type.get(), space.get(),
                        [&](hid_t mem, char* buf) { return H5Aread(attr.get(), mem, buf); });
  }

  /// A scalar string dataset (texts of any length: the resolved scene).
  std::string string_dataset(hid_t obj, const char* name) const {
    H5Id d(H5Dopen2(obj, name, H5P_DEFAULT), H5Dclose);
    if (!d.ok()) fail(std::string("missing dataset '") + name + "'");
    H5Id type(H5Dget_type(d.get()), H5Tclose);
    H5Id space(H5Dget_space(d.get()), H5Sclose);
    return fixed_string("dataset '" + std::string(name) + "'", type.get(), space.get(), [&](hid_t mem, char* buf) {
      return H5Dread(d.get(), mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
    });
  }

  template <class T>
  T scalar_attr(hid_t obj, const char* name, hid_t mem_type, H5T_class_t cls) const {
    H5Id attr(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose);
    if (!attr.ok()) fail(std::string("missing attribute '") + name + "'");
    H5Id type(H5Aget_type(attr.get()), H5Tclose);
    H5Id space(H5Aget_space(attr.get()), H5Sclose);
    if (!type.ok() || H5Tget_class(type.get()) != cls || H5Tget_size(type.get()) > 16 || !space.ok() ||
        H5Sget_simple_extent_npoints(space.get()) != 1)
      fail(std::string("attribute '") + name + "' has the wrong type or shape");
    T value{};
    if (H5Aread(attr.get(), mem_type, &value) < 0) fail(std::string("cannot read attribute '") + name + "'");
    return value;
  }

  /// A 1-D (cols = 1) or 2-D [rows, cols] dataset of class `cls` with elements of `size` bytes,
  /// no larger than the file; `rows` is set to its row count.
  H5Id open_dataset(hid_t file, const std::string& name, H5T_class_t cls, std::size_t size, hsize_t cols,
                    hsize_t& rows) const {
    H5Id d(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
    if (!d.ok()) fail("missing dataset '" + name + "'");
    H5Id type(H5Dget_type(d.get()), H5Tclose);
    H5Id space(H5Dget_space(d.get()), H5Sclose);
    if (!type.ok() || H5Tget_class(type.get()) != cls || H5Tget_size(type.get()) != size || !space.ok())
      fail("dataset '" + name + "' has the wrong type");
    const int rank = H5Sget_simple_extent_ndims(space.get());
    hsize_t dims[2] = {0, 0};
    if (rank != (cols == 1 ? 1 : 2) || H5Sget_simple_extent_dims(space.get(), dims, nullptr) != rank ||
        (cols != 1 && dims[1] != cols))
      fail("dataset '" + name + "' has the wrong shape");
    // Never allocate more than the file could hold (a forged shape must not exhaust memory).
    if (dims[0] > file_bytes_ / size / cols) fail("dataset '" + name + "' is larger than the file");
    rows = dims[0];
    return d;
  }

  /// Rows [first, first + count) of an open dataset of `cols` columns into `out`.
  template <class T>
  void read_rows(hid_t d, const std::string& name, hid_t mem_type, hsize_t first, hsize_t count, hsize_t cols,
                 T* out) const {
    if (count == 0) return;
    H5Id filespace(H5Dget_space(d), H5Sclose);
    const hsize_t start[2] = {first, 0}, counts[2] = {count, cols};
    H5Id memspace(H5Screate_simple(cols == 1 ? 1 : 2, counts, nullptr), H5Sclose);
    if (!filespace.ok() || !memspace.ok() ||
        H5Sselect_hyperslab(filespace.get(), H5S_SELECT_SET, start, nullptr, counts, nullptr) < 0 ||
        H5Dread(d, mem_type, memspace.get(), filespace.get(), H5P_DEFAULT, out) < 0)
      fail("cannot read dataset '" + name + "'");
  }

  /// A whole 1-D (cols = 1) or 2-D [rows, cols] dataset of class `cls`, read as `mem_type`.
  template <class T>
  std::vector<T> dataset(hid_t file, const std::string& name, hid_t mem_type, H5T_class_t cls,
                         hsize_t cols) const {
    hsize_t rows = 0;
    H5Id d = open_dataset(file, name, cls, sizeof(T), cols, rows);
    std::vector<T> v(static_cast<std::size_t>(rows * cols));
    read_rows(d.get(), name, mem_type, 0, rows, cols, v.data());
    return v;
  }

 private:
  /// One fixed-length string of `type` in `space`, no longer than the file, read by `read`.
  template <class Read>
  std::string fixed_string(const std::string& what, hid_t type, hid_t space, Read read) const {
    if (type < 0 || H5Tget_class(type) != H5T_STRING || H5Tis_variable_str(type) != 0)
      fail(what + " is not a fixed-length string");
    const std::size_t size = H5Tget_size(type);
    if (size == 0 || size > file_bytes_ || space < 0 || H5Sget_simple_extent_npoints(space) != 1)
      fail(what + " has an impossible size");
    std::vector<char> buf(size + 1, '\0');
    H5Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
    if (!mem.ok() || H5Tset_size(mem.get(), size) < 0 || H5Tset_strpad(mem.get(), H5Tget_strpad(type)) < 0 ||
        H5Tset_cset(mem.get(), H5Tget_cset(type)) < 0 || read(mem.get(), buf.data()) < 0)
      fail("cannot read " + what);
    return std::string(buf.data(), strnlen(buf.data(), size));
  }

  std::string path_;
  std::uint64_t file_bytes_;
};

bool all_finite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

}  // namespace

std::uint64_t fnv1a64(const void* data, std::size_t bytes, std::uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t k = 0; k < bytes; ++k) {
    h ^= p[k];
    h *= 1099511628211ull;
  }
  return h;
}

std::string previous_checkpoint_path(const std::string& path) {
  const std::string ext = ".h5";
  if (path.size() > ext.size() && path.compare(path.size() - ext.size(), ext.size(), ext) == 0)
    return path.substr(0, path.size() - ext.size()) + ".prev.h5";
  return path + ".prev";
}

void write_checkpoint(const std::string& path, const Checkpoint& c, MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  const bool root = rank == 0;
  const std::string tmp = path + ".tmp";
  Writer w(tmp, comm);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);

  // Where this rank's rows go: node rows from node_first (contiguous blocks in rank order), the
  // broken pairs and the history values after those of the ranks before. Rank 0's metadata.
  const auto it = c.extras.find(kBondHistoryExtra);
  static const std::vector<double> kNone;
  const std::vector<double>& history = it == c.extras.end() ? kNone : it->second;
  long long mine[3] = {static_cast<long long>(c.displacement.size() / 3), static_cast<long long>(c.broken.size() / 2),
                       static_cast<long long>(history.size())};
  long long before[3] = {0, 0, 0}, total[3] = {0, 0, 0};
  MPI_Exscan(mine, before, 3, MPI_LONG_LONG, MPI_SUM, comm);
  if (root) before[0] = before[1] = before[2] = 0;
  MPI_Allreduce(mine, total, 3, MPI_LONG_LONG, MPI_SUM, comm);
  long long counters[8] = {c.format_version, c.nodes, c.ordered_bonds, c.step, c.stage, c.stage_step, c.ranks,
                           static_cast<long long>(c.scene_hash)};
  double reals[2] = {c.time, c.initial_total_energy};
  unsigned long long reference[2] = {c.has_reference_hash ? 1ull : 0ull, c.reference_hash};
  MPI_Bcast(counters, 8, MPI_LONG_LONG, 0, comm);
  MPI_Bcast(reference, 2, MPI_UNSIGNED_LONG_LONG, 0, comm);
  MPI_Bcast(reals, 2, MPI_DOUBLE, 0, comm);
  // The history dataset exists when any rank has a part (possibly empty: no bond has one yet).
  int has_history = it != c.extras.end(), any_history = 0;
  MPI_Allreduce(&has_history, &any_history, 1, MPI_INT, MPI_MAX, comm);
  has_history = any_history;
  int dashpots = c.has_dashpot_velocity, any_dashpots = 0;
  MPI_Allreduce(&dashpots, &any_dashpots, 1, MPI_INT, MPI_MAX, comm);
  {
    std::string wrong;
    if (c.displacement.size() != c.velocity.size() || c.displacement.size() % 3 != 0 || c.broken.size() % 2 != 0 ||
        (any_dashpots && c.dashpot_velocity.size() != c.velocity.size()))
      wrong = "the node or bond arrays have impossible sizes";
    else if (c.node_first != before[0] || total[0] != counters[1])
      wrong = "the ranks' node rows are not contiguous blocks of all " + std::to_string(counters[1]) + " nodes";
    wrong = agree_on_message(wrong, comm);
    if (!wrong.empty()) throw Error("cannot write checkpoint '" + tmp + "': " + wrong);
  }
  const std::string scene = bcast_string(c.scene, comm), version = bcast_string(c.peridrive_version, comm),
                    revision = bcast_string(c.git_revision, comm);
  // The extras' names and sizes (rank 0's; the history is written in parts below).
  std::string listing;
  if (root)
    for (const auto& [name, values] : c.extras)
      if (name != kBondHistoryExtra) listing += name + '\n' + std::to_string(values.size()) + '\n';
  listing = bcast_string(listing, comm);
  std::vector<std::pair<std::string, hsize_t>> extras;
  {
    std::istringstream in(listing);
    for (std::string name, size; std::getline(in, name) && std::getline(in, size);)
      extras.push_back({name, static_cast<hsize_t>(std::stoull(size))});
  }

  {
    H5Id fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose), fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
    w.agree(fcpl.ok() && fapl.ok() && H5Pset_userblock(fcpl.get(), kCheckpointHeaderBytes) >= 0 &&
                H5Pset_fapl_mpio(fapl.get(), comm, MPI_INFO_NULL) >= 0,
            "the file's properties");
    w.create(fcpl.get(), fapl.get());
    const hid_t f = w.file();
    w.scalar_attr<int>(f, "format_version", H5T_NATIVE_INT, static_cast<int>(counters[0]));
    w.string_attr(f, "peridrive_version", version);
    w.string_attr(f, "git_revision", revision);
    w.string_dataset(f, "scene", scene);
    w.scalar_attr<std::uint64_t>(f, "scene_hash", H5T_NATIVE_UINT64, static_cast<std::uint64_t>(counters[7]));
    w.scalar_attr<long long>(f, "nodes", H5T_NATIVE_LLONG, counters[1]);
    w.scalar_attr<long long>(f, "ordered_bonds", H5T_NATIVE_LLONG, counters[2]);
    w.scalar_attr<long long>(f, "step", H5T_NATIVE_LLONG, counters[3]);
    w.scalar_attr<double>(f, "time", H5T_NATIVE_DOUBLE, reals[0]);
    w.scalar_attr<long long>(f, "stage", H5T_NATIVE_LLONG, counters[4]);
    w.scalar_attr<long long>(f, "stage_step", H5T_NATIVE_LLONG, counters[5]);
    w.scalar_attr<double>(f, "initial_total_energy", H5T_NATIVE_DOUBLE, reals[1]);
    w.scalar_attr<int>(f, "ranks", H5T_NATIVE_INT, static_cast<int>(counters[6]));
    if (reference[0])
      w.scalar_attr<std::uint64_t>(f, "reference_hash", H5T_NATIVE_UINT64, static_cast<std::uint64_t>(reference[1]));
    {
      H5Id g = w.group(f, "/state");
      const auto n = static_cast<hsize_t>(mine[0]), first = static_cast<hsize_t>(before[0]),
                 all = static_cast<hsize_t>(total[0]);
      w.rows(g.get(), "displacement", H5T_NATIVE_DOUBLE, c.displacement.data(), first, n, all, 3);
      w.rows(g.get(), "velocity", H5T_NATIVE_DOUBLE, c.velocity.data(), first, n, all, 3);
      if (any_dashpots)
        w.rows(g.get(), "dashpot_velocity", H5T_NATIVE_DOUBLE, c.dashpot_velocity.data(), first, n, all, 3);
    }
    {
      H5Id g = w.group(f, "/bonds");
      static_assert(sizeof(long long) == sizeof(std::int64_t));
      w.rows(g.get(), "broken", H5T_NATIVE_INT64, c.broken.data(), static_cast<hsize_t>(before[1]),
             static_cast<hsize_t>(mine[1]), static_cast<hsize_t>(total[1]), 2);
    }
    {
      H5Id g = w.group(f, "/tallies");
      const auto ranks = static_cast<hsize_t>(counters[6]);
      w.root_dataset(g.get(), "dissipated", H5T_NATIVE_DOUBLE, c.dissipated, ranks, 1);
      w.root_dataset(g.get(), "damping_work", H5T_NATIVE_DOUBLE, c.damping_work, ranks, 1);
      w.root_dataset(g.get(), "external_work", H5T_NATIVE_DOUBLE, c.external_work, ranks, 1);
      w.root_dataset(g.get(), "newly_broken", H5T_NATIVE_INT64, c.newly_broken, ranks, 1);
      w.root_dataset(g.get(), "owner_hash", H5T_NATIVE_UINT64, c.owner_hash, ranks, 1);
    }
    {
      H5Id g = w.group(f, "/extras");
      // Created in name order, as a std::map of all of them would be.
      bool history_done = has_history == 0;
      for (const auto& [name, size] : extras) {
        if (!history_done && std::string(kBondHistoryExtra) < name) {
          w.rows(g.get(), kBondHistoryExtra, H5T_NATIVE_DOUBLE, history.data(), static_cast<hsize_t>(before[2]),
                 static_cast<hsize_t>(mine[2]), static_cast<hsize_t>(total[2]), 1);
          history_done = true;
        }
        w.root_dataset(g.get(), name.c_str(), H5T_NATIVE_DOUBLE, root ? c.extras.at(name) : kNone, size, 1);
      }
      if (!history_done)
        w.rows(g.get(), kBondHistoryExtra, H5T_NATIVE_DOUBLE, history.data(), static_cast<hsize_t>(before[2]),
               static_cast<hsize_t>(mine[2]), static_cast<hsize_t>(total[2]), 1);
    }
    w.close();
  }

  // Rank 0: the header (hash of everything HDF5 wrote, streamed), flushed to disk before the
  // renames make it current.
  std::string error;
  if (root) {
    try {
      std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(tmp.c_str(), "r+b"), &std::fclose);
      if (!f) throw Error("cannot reopen checkpoint '" + tmp + "': " + errno_text());
      std::uint64_t size = 0;
      bool io_error = false;
      const std::uint64_t h = hash_tail(f.get(), kCheckpointHeaderBytes, size, io_error);
      if (io_error) throw Error("cannot read back checkpoint '" + tmp + "': " + errno_text());
      std::string header = std::string(kMagic) + "format_version: " + std::to_string(counters[0]) +
                           "\nfile_bytes: " + std::to_string(size) + "\nfnv1a64: " + hex64(h) + "\n";
      header.resize(kCheckpointHeaderBytes, '\0');
      if (std::fseek(f.get(), 0, SEEK_SET) != 0 ||
          std::fwrite(header.data(), 1, header.size(), f.get()) != header.size() || std::fflush(f.get()) != 0 ||
          ::fsync(fileno(f.get())) != 0)
        throw Error("cannot write checkpoint '" + tmp + "': " + errno_text());
      f.reset();
      std::error_code ec;
      if (std::filesystem::exists(path, ec)) {
        const std::string prev = previous_checkpoint_path(path);
        if (std::rename(path.c_str(), prev.c_str()) != 0)
          throw Error("cannot rename '" + path + "' to '" + prev + "': " + errno_text());
      }
      if (std::rename(tmp.c_str(), path.c_str()) != 0)
        throw Error("cannot rename '" + tmp + "' to '" + path + "': " + errno_text());
      fsync_dir(path);
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  error = agree_on_message(error, comm);
  if (!error.empty()) throw Error(error);
}

std::uint64_t check_checkpoint_file(const std::string& path, bool hash) {
  const auto fail = [&](const std::string& what) -> void {
    throw InputError("checkpoint '" + path + "': " + what);
  };
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) fail("no such file");
  if (!std::filesystem::is_regular_file(path, ec)) fail("not a regular file");
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) fail("cannot open: " + errno_text());
  char header[kCheckpointHeaderBytes + 1] = {0};
  const std::size_t got = std::fread(header, 1, kCheckpointHeaderBytes, f.get());
  const std::size_t magic = sizeof kMagic - 1;
  if (got < magic || std::memcmp(header, kMagic, magic) != 0)
    fail("not a peridrive checkpoint (the file does not start with the checkpoint header)");
  if (got < kCheckpointHeaderBytes) fail("truncated: " + std::to_string(got) + " bytes, shorter than the header");
  // Strict parse of the three header lines; the rest of the block must be NUL.
  int version = -1;
  unsigned long long bytes = 0;
  char hash_text[17] = {0};
  int used = 0;
  const char* body = header + magic;
  if (std::sscanf(body, "format_version: %d\n%n", &version, &used) != 1 || used == 0)
    fail("damaged header (no format_version line)");
  if (version != kCheckpointFormatVersion)
    fail("format version " + std::to_string(version) + "; this peridrive reads version " +
         std::to_string(kCheckpointFormatVersion));
  body += used;
  used = 0;
  if (std::sscanf(body, "file_bytes: %llu\n%n", &bytes, &used) != 1 || used == 0)
    fail("damaged header (no file_bytes line)");
  body += used;
  used = 0;
  if (std::sscanf(body, "fnv1a64: %16[0-9a-f]\n%n", hash_text, &used) != 1 || used == 0 ||
      std::strlen(hash_text) != 16)
    fail("damaged header (no fnv1a64 line)");
  body += used;
  for (const char* p = body; p < header + kCheckpointHeaderBytes; ++p)
    if (*p != '\0') fail("damaged header (unexpected bytes after the fnv1a64 line)");
  std::uint64_t size = 0, h = 0;
  if (hash) {
    bool io_error = false;
    h = hash_tail(f.get(), kCheckpointHeaderBytes, size, io_error);
    if (io_error) fail("cannot read: " + errno_text());
  } else {
    const auto s = std::filesystem::file_size(path, ec);
    if (ec) fail("cannot read: " + ec.message());
    size = static_cast<std::uint64_t>(s);
  }
  if (size < bytes) fail("truncated: " + std::to_string(size) + " bytes, the header says " + std::to_string(bytes));
  if (size > bytes) fail("damaged: " + std::to_string(size) + " bytes, the header says " + std::to_string(bytes));
  if (hash && hex64(h) != hash_text)
    fail("damaged: checksum mismatch (fnv1a64 " + hex64(h) + ", the header says " + hash_text +
         "); the file was modified or corrupted after it was written");
  return size;
}

namespace {

/// The checkpoint file opened for reading by this process alone (serial driver).
H5Id open_for_reading(const Reader& r, const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  H5Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) r.fail("HDF5 cannot open it");
  return file;
}

}  // namespace

Checkpoint read_checkpoint_metadata(const std::string& path, std::uint64_t size) {
  // The bytes are those written: now HDF5 may parse them. Checks stay strict regardless.
  const Reader r(path, size);
  const H5Id file = open_for_reading(r, path);
  const hid_t f = file.get();
  Checkpoint c;
  c.path = path;
  c.file_bytes = size;
  c.arrays = false;
  c.format_version = r.scalar_attr<int>(f, "format_version", H5T_NATIVE_INT, H5T_INTEGER);
  if (c.format_version != kCheckpointFormatVersion)
    r.fail("format version " + std::to_string(c.format_version) + " in the HDF5 attributes; this peridrive reads version " +
           std::to_string(kCheckpointFormatVersion));
  c.peridrive_version = r.string_attr(f, "peridrive_version");
  c.git_revision = r.string_attr(f, "git_revision");
  // Checkpoints written before the scene outgrew attributes hold it as one.
  c.scene = H5Lexists(f, "scene", H5P_DEFAULT) > 0 ? r.string_dataset(f, "scene") : r.string_attr(f, "scene");
  c.scene_hash = r.scalar_attr<std::uint64_t>(f, "scene_hash", H5T_NATIVE_UINT64, H5T_INTEGER);
  if (fnv1a64(c.scene.data(), c.scene.size()) != c.scene_hash) r.fail("the stored scene does not match its hash");
  c.nodes = r.scalar_attr<long long>(f, "nodes", H5T_NATIVE_LLONG, H5T_INTEGER);
  c.ordered_bonds = r.scalar_attr<long long>(f, "ordered_bonds", H5T_NATIVE_LLONG, H5T_INTEGER);
  c.step = r.scalar_attr<long long>(f, "step", H5T_NATIVE_LLONG, H5T_INTEGER);
  c.time = r.scalar_attr<double>(f, "time", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  c.stage = r.scalar_attr<long long>(f, "stage", H5T_NATIVE_LLONG, H5T_INTEGER);
  c.stage_step = r.scalar_attr<long long>(f, "stage_step", H5T_NATIVE_LLONG, H5T_INTEGER);
  c.initial_total_energy = r.scalar_attr<double>(f, "initial_total_energy", H5T_NATIVE_DOUBLE, H5T_FLOAT);
  c.ranks = r.scalar_attr<int>(f, "ranks", H5T_NATIVE_INT, H5T_INTEGER);
  c.has_reference_hash = H5Aexists(f, "reference_hash") > 0;  // (absent in older files)
  if (c.has_reference_hash)
    c.reference_hash = r.scalar_attr<std::uint64_t>(f, "reference_hash", H5T_NATIVE_UINT64, H5T_INTEGER);
  if (c.nodes <= 0 || c.ordered_bonds < 0 || c.step < 0 || c.stage < 0 || c.stage_step < 0 ||
      c.stage_step > c.step || !std::isfinite(c.time) || c.time < 0 || c.ranks < 1 ||
      !std::isfinite(c.initial_total_energy))
    r.fail("inconsistent run counters (nodes, bonds, step, time, stage or ranks out of range)");

  hsize_t rows_u = 0, rows_v = 0, pairs = 0;
  r.open_dataset(f, "/state/displacement", H5T_FLOAT, sizeof(double), 3, rows_u);
  r.open_dataset(f, "/state/velocity", H5T_FLOAT, sizeof(double), 3, rows_v);
  if (rows_u != static_cast<std::uint64_t>(c.nodes) || rows_v != static_cast<std::uint64_t>(c.nodes))
    r.fail("state arrays do not hold " + std::to_string(c.nodes) + " nodes");
  if (H5Lexists(f, "/state/dashpot_velocity", H5P_DEFAULT) > 0) {  // runs with bond dashpots
    hsize_t rows_w = 0;
    r.open_dataset(f, "/state/dashpot_velocity", H5T_FLOAT, sizeof(double), 3, rows_w);
    if (rows_w != static_cast<std::uint64_t>(c.nodes))
      r.fail("state arrays do not hold " + std::to_string(c.nodes) + " nodes");
    c.has_dashpot_velocity = true;
  }
  r.open_dataset(f, "/bonds/broken", H5T_INTEGER, sizeof(std::int64_t), 2, pairs);
  if (2 * static_cast<std::uint64_t>(pairs) > static_cast<std::uint64_t>(c.ordered_bonds))
    r.fail("more broken bonds than bonds");
  c.broken_pairs = static_cast<std::int64_t>(pairs);

  c.dissipated = r.dataset<double>(f, "/tallies/dissipated", H5T_NATIVE_DOUBLE, H5T_FLOAT, 1);
  c.damping_work = r.dataset<double>(f, "/tallies/damping_work", H5T_NATIVE_DOUBLE, H5T_FLOAT, 1);
  c.external_work = r.dataset<double>(f, "/tallies/external_work", H5T_NATIVE_DOUBLE, H5T_FLOAT, 1);
  c.newly_broken = r.dataset<std::int64_t>(f, "/tallies/newly_broken", H5T_NATIVE_INT64, H5T_INTEGER, 1);
  c.owner_hash = r.dataset<std::uint64_t>(f, "/tallies/owner_hash", H5T_NATIVE_UINT64, H5T_INTEGER, 1);
  const auto ranks = static_cast<std::size_t>(c.ranks);
  if (c.dissipated.size() != ranks || c.damping_work.size() != ranks || c.external_work.size() != ranks ||
      c.newly_broken.size() != ranks || c.owner_hash.size() != ranks)
    r.fail("tallies do not hold " + std::to_string(c.ranks) + " ranks");
  if (!all_finite(c.dissipated) || !all_finite(c.damping_work) || !all_finite(c.external_work))
    r.fail("non-finite energy tallies");
  std::int64_t newly = 0;
  for (std::int64_t x : c.newly_broken) {
    if (x < 0 || x > c.ordered_bonds - newly) r.fail("broken-bond tallies out of range");
    newly += x;
  }

  H5Id extras(H5Gopen2(f, "/extras", H5P_DEFAULT), H5Gclose);
  if (!extras.ok()) r.fail("missing group '/extras'");
  H5G_info_t info;
  if (H5Gget_info(extras.get(), &info) < 0 || info.nlinks > kMaxExtras) r.fail("unreadable group '/extras'");
  for (hsize_t k = 0; k < info.nlinks; ++k) {
    char name[256] = {0};
    const ssize_t len = H5Lget_name_by_idx(extras.get(), ".", H5_INDEX_NAME, H5_ITER_INC, k, name, sizeof name, H5P_DEFAULT);
    if (len <= 0 || len >= static_cast<ssize_t>(sizeof name)) r.fail("unreadable name in '/extras'");
    const std::string full = std::string("/extras/") + name;
    if (std::string(name) == kBondHistoryExtra) {  // read per rank (read_checkpoint_history)
      hsize_t values = 0;
      r.open_dataset(f, full, H5T_FLOAT, sizeof(double), 1, values);
      c.history_values = static_cast<std::int64_t>(values);
      continue;
    }
    c.extras[name] = r.dataset<double>(f, full, H5T_NATIVE_DOUBLE, H5T_FLOAT, 1);
  }
  return c;
}

void read_checkpoint_nodes(const Checkpoint& meta, std::int64_t first, std::int64_t count, std::vector<double>& u,
                           std::vector<double>& v, std::vector<double>* w) {
  const Reader r(meta.path, meta.file_bytes);
  if (first < 0 || count < 0 || first + count > meta.nodes) r.fail("node rows out of range");
  const H5Id file = open_for_reading(r, meta.path);
  hsize_t rows = 0;
  u.assign(3 * static_cast<std::size_t>(count), 0.0);
  v.assign(3 * static_cast<std::size_t>(count), 0.0);
  {
    H5Id d = r.open_dataset(file.get(), "/state/displacement", H5T_FLOAT, sizeof(double), 3, rows);
    if (rows != static_cast<hsize_t>(meta.nodes)) r.fail("state arrays do not hold " + std::to_string(meta.nodes) + " nodes");
    r.read_rows(d.get(), "/state/displacement", H5T_NATIVE_DOUBLE, first, count, 3, u.data());
  }
  {
    H5Id d = r.open_dataset(file.get(), "/state/velocity", H5T_FLOAT, sizeof(double), 3, rows);
    if (rows != static_cast<hsize_t>(meta.nodes)) r.fail("state arrays do not hold " + std::to_string(meta.nodes) + " nodes");
    r.read_rows(d.get(), "/state/velocity", H5T_NATIVE_DOUBLE, first, count, 3, v.data());
  }
  if (w) w->clear();
  if (w && meta.has_dashpot_velocity) {
    w->assign(3 * static_cast<std::size_t>(count), 0.0);
    H5Id d = r.open_dataset(file.get(), "/state/dashpot_velocity", H5T_FLOAT, sizeof(double), 3, rows);
    if (rows != static_cast<hsize_t>(meta.nodes)) r.fail("state arrays do not hold " + std::to_string(meta.nodes) + " nodes");
    r.read_rows(d.get(), "/state/dashpot_velocity", H5T_NATIVE_DOUBLE, first, count, 3, w->data());
    if (!all_finite(*w)) r.fail("non-finite dashpot velocity");
  }
  if (!all_finite(u) || !all_finite(v)) r.fail("non-finite displacement or velocity");
}

std::vector<std::int64_t> read_checkpoint_broken(const Checkpoint& meta,
                                                 const std::function<bool(std::int64_t, std::int64_t)>& keep) {
  const Reader r(meta.path, meta.file_bytes);
  const H5Id file = open_for_reading(r, meta.path);
  hsize_t rows = 0;
  H5Id d = r.open_dataset(file.get(), "/bonds/broken", H5T_INTEGER, sizeof(std::int64_t), 2, rows);
  if (2 * static_cast<std::uint64_t>(rows) > static_cast<std::uint64_t>(meta.ordered_bonds))
    r.fail("more broken bonds than bonds");
  std::vector<std::int64_t> kept, chunk;
  std::int64_t pi = -1, pj = -1;
  for (hsize_t at = 0; at < rows; at += kChunkRows) {
    const hsize_t n = std::min(kChunkRows, rows - at);
    chunk.resize(2 * static_cast<std::size_t>(n));
    r.read_rows(d.get(), "/bonds/broken", H5T_NATIVE_INT64, at, n, 2, chunk.data());
    for (std::size_t k = 0; k < chunk.size(); k += 2) {
      const std::int64_t i = chunk[k], j = chunk[k + 1];
      const std::uint64_t row = at + k / 2;
      if (i < 0 || i >= j || j >= meta.nodes) r.fail("broken bond " + std::to_string(row) + " is not a pair i < j of nodes");
      if (row > 0 && !(pi < i || (pi == i && pj < j))) r.fail("broken bonds are not sorted and unique");
      pi = i;
      pj = j;
      if (keep(i, j)) kept.insert(kept.end(), {i, j});
    }
  }
  return kept;
}

std::vector<double> read_checkpoint_history(const Checkpoint& meta, std::size_t width,
                                            const std::function<bool(std::int64_t)>& keep) {
  const Reader r(meta.path, meta.file_bytes);
  std::vector<double> kept;
  if (meta.history_values == 0) return kept;
  if (width < 2 || meta.history_values % static_cast<std::int64_t>(width) != 0)
    r.fail("the bond history holds " + std::to_string(meta.history_values) + " values, not whole rows of (i, j) and " +
           std::to_string(static_cast<long long>(width) - 2) + " values");
  const H5Id file = open_for_reading(r, meta.path);
  const std::string name = std::string("/extras/") + kBondHistoryExtra;
  hsize_t values = 0;
  H5Id d = r.open_dataset(file.get(), name, H5T_FLOAT, sizeof(double), 1, values);
  if (values != static_cast<hsize_t>(meta.history_values)) r.fail("the bond history changed size");
  const hsize_t rows = values / width;
  std::vector<double> chunk;
  double pi = -1, pj = -1;
  const double n = static_cast<double>(meta.nodes);
  for (hsize_t at = 0; at < rows; at += kChunkRows) {
    const hsize_t m = std::min(kChunkRows, rows - at);
    chunk.resize(static_cast<std::size_t>(m) * width);
    r.read_rows(d.get(), name, H5T_NATIVE_DOUBLE, at * width, m * width, 1, chunk.data());
    for (std::size_t k = 0; k < chunk.size(); k += width) {
      const double i = chunk[k], j = chunk[k + 1];
      if (!(i >= 0 && i < n && j >= 0 && j < n) || i != std::floor(i) || j != std::floor(j))
        r.fail("bond history row " + std::to_string(at + k / width) + " does not name two nodes");
      if (!std::all_of(chunk.begin() + k + 2, chunk.begin() + k + width, [](double x) { return std::isfinite(x); }))
        r.fail("non-finite bond history");
      if (at + k > 0 && !(pi < i || (pi == i && pj < j))) r.fail("the bond history is not sorted by bond");
      pi = i;
      pj = j;
      if (keep(static_cast<std::int64_t>(i))) kept.insert(kept.end(), chunk.begin() + k, chunk.begin() + k + width);
    }
  }
  return kept;
}

Checkpoint read_checkpoint(const std::string& path) {
  const std::uint64_t size = check_checkpoint_file(path, true);
  Checkpoint c = read_checkpoint_metadata(path, size);
  read_checkpoint_nodes(c, 0, c.nodes, c.displacement, c.velocity, &c.dashpot_velocity);
  c.broken = read_checkpoint_broken(c, [](std::int64_t, std::int64_t) { return true; });
  if (c.history_values > 0) {  // the values as stored (their row width is the law's)
    const Reader r(path, size);
    const H5Id file = open_for_reading(r, path);
    c.extras[kBondHistoryExtra] =
        r.dataset<double>(file.get(), std::string("/extras/") + kBondHistoryExtra, H5T_NATIVE_DOUBLE, H5T_FLOAT, 1);
  }
  c.arrays = true;
  return c;
}

}  // namespace peri
