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

#include "peri/core/error.hpp"
#include "peri/core/hdf5.hpp"

namespace peri {
namespace {

constexpr char kMagic[] = "peridrive checkpoint\n";
constexpr std::size_t kMaxExtras = 4096;

// ------------------------------------------------------------------------------------------------
// Writing

struct Writer {
  std::string path;
  void check(bool ok, const std::string& what) const {
    if (!ok) throw Error("cannot write checkpoint '" + path + "': HDF5 failed at " + what);
  }
  void string_attr(hid_t obj, const char* name, const std::string& value) const {
    H5Id type(H5Tcopy(H5T_C_S1), H5Tclose);
    check(type.ok() && H5Tset_size(type.get(), std::max<std::size_t>(value.size(), 1)) >= 0, name);
    H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
    H5Id attr(H5Acreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    check(attr.ok(), name);
    const std::string padded = value.empty() ? std::string(1, '\0') : value;
    check(H5Awrite(attr.get(), type.get(), padded.data()) >= 0, name);
  }
  /// A text of any length (an attribute is limited to the 64 KB of its object's header).
  void string_dataset(hid_t obj, const char* name, const std::string& value) const {
    H5Id type(H5Tcopy(H5T_C_S1), H5Tclose);
    check(type.ok() && H5Tset_size(type.get(), std::max<std::size_t>(value.size(), 1)) >= 0 &&
              H5Tset_strpad(type.get(), H5T_STR_NULLPAD) >= 0 && H5Tset_cset(type.get(), H5T_CSET_UTF8) >= 0,
          name);
    H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
    H5Id d(H5Dcreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
    check(d.ok(), name);
    const std::string padded = value.empty() ? std::string(1, '\0') : value;
    check(H5Dwrite(d.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, padded.data()) >= 0, name);
  }
  template <class T>
  void scalar_attr(hid_t obj, const char* name, hid_t type, T value) const {
    H5Id space(H5Screate(H5S_SCALAR), H5Sclose);
    H5Id attr(H5Acreate2(obj, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    check(attr.ok() && H5Awrite(attr.get(), type, &value) >= 0, name);
  }
  template <class T>
  void dataset(hid_t group, const char* name, hid_t type, const std::vector<T>& v, hsize_t cols) const {
    const hsize_t dims[2] = {static_cast<hsize_t>(v.size() / cols), cols};
    H5Id space(H5Screate_simple(cols == 1 ? 1 : 2, dims, nullptr), H5Sclose);
    check(space.ok(), name);
    H5Id d(H5Dcreate2(group, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
    check(d.ok(), name);
    const T dummy{};
    check(H5Dwrite(d.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.empty() ? &dummy : v.data()) >= 0, name);
  }
  H5Id group(hid_t file, const char* name) const {
    H5Id g(H5Gcreate2(file, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    check(g.ok(), name);
    return g;
  }
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

  /// A 1-D (cols = 1) or 2-D [rows, cols] dataset of class `cls`, read as `mem_type`.
  template <class T>
  std::vector<T> dataset(hid_t file, const std::string& name, hid_t mem_type, H5T_class_t cls,
                         hsize_t cols) const {
    H5Id d(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
    if (!d.ok()) fail("missing dataset '" + name + "'");
    H5Id type(H5Dget_type(d.get()), H5Tclose);
    H5Id space(H5Dget_space(d.get()), H5Sclose);
    if (!type.ok() || H5Tget_class(type.get()) != cls || H5Tget_size(type.get()) != sizeof(T) || !space.ok())
      fail("dataset '" + name + "' has the wrong type");
    const int rank = H5Sget_simple_extent_ndims(space.get());
    hsize_t dims[2] = {0, 0};
    if (rank != (cols == 1 ? 1 : 2) || H5Sget_simple_extent_dims(space.get(), dims, nullptr) != rank ||
        (cols != 1 && dims[1] != cols))
      fail("dataset '" + name + "' has the wrong shape");
    // Never allocate more than the file could hold (a forged shape must not exhaust memory).
    if (dims[0] > file_bytes_ / sizeof(T) / cols) fail("dataset '" + name + "' is larger than the file");
    std::vector<T> v(static_cast<std::size_t>(dims[0] * cols));
    if (!v.empty() && H5Dread(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
      fail("cannot read dataset '" + name + "'");
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

void write_checkpoint(const std::string& path, const Checkpoint& c) {
  const std::string tmp = path + ".tmp";
  const Writer w{tmp};
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  {
    H5Id fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
    w.check(fcpl.ok() && H5Pset_userblock(fcpl.get(), kCheckpointHeaderBytes) >= 0, "user block");
    H5Id file(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, fcpl.get(), H5P_DEFAULT), H5Fclose);
    if (!file.ok()) throw Error("cannot create checkpoint '" + tmp + "'");
    const hid_t f = file.get();
    w.scalar_attr<int>(f, "format_version", H5T_NATIVE_INT, c.format_version);
    w.string_attr(f, "peridrive_version", c.peridrive_version);
    w.string_attr(f, "git_revision", c.git_revision);
    w.string_dataset(f, "scene", c.scene);
    w.scalar_attr<std::uint64_t>(f, "scene_hash", H5T_NATIVE_UINT64, c.scene_hash);
    w.scalar_attr<long long>(f, "nodes", H5T_NATIVE_LLONG, c.nodes);
    w.scalar_attr<long long>(f, "ordered_bonds", H5T_NATIVE_LLONG, c.ordered_bonds);
    w.scalar_attr<long long>(f, "step", H5T_NATIVE_LLONG, c.step);
    w.scalar_attr<double>(f, "time", H5T_NATIVE_DOUBLE, c.time);
    w.scalar_attr<long long>(f, "stage", H5T_NATIVE_LLONG, c.stage);
    w.scalar_attr<long long>(f, "stage_step", H5T_NATIVE_LLONG, c.stage_step);
    w.scalar_attr<double>(f, "initial_total_energy", H5T_NATIVE_DOUBLE, c.initial_total_energy);
    w.scalar_attr<int>(f, "ranks", H5T_NATIVE_INT, c.ranks);
    {
      H5Id g = w.group(f, "/state");
      w.dataset(g.get(), "displacement", H5T_NATIVE_DOUBLE, c.displacement, 3);
      w.dataset(g.get(), "velocity", H5T_NATIVE_DOUBLE, c.velocity, 3);
    }
    {
      H5Id g = w.group(f, "/bonds");
      static_assert(sizeof(long long) == sizeof(std::int64_t));
      w.dataset(g.get(), "broken", H5T_NATIVE_INT64, c.broken, 2);
    }
    {
      H5Id g = w.group(f, "/tallies");
      w.dataset(g.get(), "dissipated", H5T_NATIVE_DOUBLE, c.dissipated, 1);
      w.dataset(g.get(), "damping_work", H5T_NATIVE_DOUBLE, c.damping_work, 1);
      w.dataset(g.get(), "external_work", H5T_NATIVE_DOUBLE, c.external_work, 1);
      w.dataset(g.get(), "newly_broken", H5T_NATIVE_INT64, c.newly_broken, 1);
      w.dataset(g.get(), "owner_hash", H5T_NATIVE_UINT64, c.owner_hash, 1);
    }
    {
      H5Id g = w.group(f, "/extras");
      for (const auto& [name, values] : c.extras) w.dataset(g.get(), name.c_str(), H5T_NATIVE_DOUBLE, values, 1);
    }
    if (!file.close()) throw Error("cannot close checkpoint '" + tmp + "'");
  }
  // Header: hash of everything HDF5 wrote, then flush to disk before the rename makes it current.
  {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(tmp.c_str(), "r+b"), &std::fclose);
    if (!f) throw Error("cannot reopen checkpoint '" + tmp + "': " + errno_text());
    std::uint64_t size = 0;
    bool io_error = false;
    const std::uint64_t h = hash_tail(f.get(), kCheckpointHeaderBytes, size, io_error);
    if (io_error) throw Error("cannot read back checkpoint '" + tmp + "': " + errno_text());
    std::string header = std::string(kMagic) + "format_version: " + std::to_string(c.format_version) +
                         "\nfile_bytes: " + std::to_string(size) + "\nfnv1a64: " + hex64(h) + "\n";
    header.resize(kCheckpointHeaderBytes, '\0');
    if (std::fseek(f.get(), 0, SEEK_SET) != 0 ||
        std::fwrite(header.data(), 1, header.size(), f.get()) != header.size() || std::fflush(f.get()) != 0 ||
        ::fsync(fileno(f.get())) != 0)
      throw Error("cannot write checkpoint '" + tmp + "': " + errno_text());
  }
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    const std::string prev = previous_checkpoint_path(path);
    if (std::rename(path.c_str(), prev.c_str()) != 0)
      throw Error("cannot rename '" + path + "' to '" + prev + "': " + errno_text());
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw Error("cannot rename '" + tmp + "' to '" + path + "': " + errno_text());
  fsync_dir(path);
}

Checkpoint read_checkpoint(const std::string& path) {
  const auto fail = [&](const std::string& what) -> void {
    throw InputError("checkpoint '" + path + "': " + what);
  };
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) fail("no such file");
  if (!std::filesystem::is_regular_file(path, ec)) fail("not a regular file");
  std::uint64_t size = 0;
  {
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
    bool io_error = false;
    const std::uint64_t h = hash_tail(f.get(), kCheckpointHeaderBytes, size, io_error);
    if (io_error) fail("cannot read: " + errno_text());
    if (size < bytes)
      fail("truncated: " + std::to_string(size) + " bytes, the header says " + std::to_string(bytes));
    if (size > bytes)
      fail("damaged: " + std::to_string(size) + " bytes, the header says " + std::to_string(bytes));
    if (hex64(h) != hash_text)
      fail("damaged: checksum mismatch (fnv1a64 " + hex64(h) + ", the header says " + hash_text +
           "); the file was modified or corrupted after it was written");
  }

  // The bytes are those written: now HDF5 may parse them. Checks stay strict regardless.
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const Reader r(path, size);
  H5Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) r.fail("HDF5 cannot open it");
  const hid_t f = file.get();
  Checkpoint c;
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
  if (c.nodes <= 0 || c.ordered_bonds < 0 || c.step < 0 || c.stage < 0 || c.stage_step < 0 ||
      c.stage_step > c.step || !std::isfinite(c.time) || c.time < 0 || c.ranks < 1 ||
      !std::isfinite(c.initial_total_energy))
    r.fail("inconsistent run counters (nodes, bonds, step, time, stage or ranks out of range)");

  c.displacement = r.dataset<double>(f, "/state/displacement", H5T_NATIVE_DOUBLE, H5T_FLOAT, 3);
  c.velocity = r.dataset<double>(f, "/state/velocity", H5T_NATIVE_DOUBLE, H5T_FLOAT, 3);
  const auto n3 = static_cast<std::uint64_t>(c.nodes) * 3;
  if (c.displacement.size() != n3 || c.velocity.size() != n3)
    r.fail("state arrays do not hold " + std::to_string(c.nodes) + " nodes");
  if (!all_finite(c.displacement) || !all_finite(c.velocity)) r.fail("non-finite displacement or velocity");

  c.broken = r.dataset<std::int64_t>(f, "/bonds/broken", H5T_NATIVE_INT64, H5T_INTEGER, 2);
  if (static_cast<std::uint64_t>(c.broken.size()) > static_cast<std::uint64_t>(c.ordered_bonds))
    r.fail("more broken bonds than bonds");
  for (std::size_t k = 0; k < c.broken.size(); k += 2) {
    const std::int64_t i = c.broken[k], j = c.broken[k + 1];
    if (i < 0 || i >= j || j >= c.nodes) r.fail("broken bond " + std::to_string(k / 2) + " is not a pair i < j of nodes");
    if (k > 0 && !(c.broken[k - 2] < i || (c.broken[k - 2] == i && c.broken[k - 1] < j)))
      r.fail("broken bonds are not sorted and unique");
  }

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
    c.extras[name] = r.dataset<double>(f, std::string("/extras/") + name, H5T_NATIVE_DOUBLE, H5T_FLOAT, 1);
  }
  return c;
}

}  // namespace peri
