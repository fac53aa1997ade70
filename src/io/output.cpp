#include "peri/io/output.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <cstdlib>
#include <iomanip>
#include <iterator>
#include <sstream>

#include "peri/core/build_info.hpp"
#include "peri/core/collective.hpp"
#include "peri/core/error.hpp"
#include "peri/core/hdf5.hpp"

namespace peri {
namespace {

bool g_abandoned = false;  // a frame writer gave up its file (abandoned_output_files)

void check_h5(herr_t status, const char* what) {
  if (status < 0) throw Error(std::string("HDF5 call failed: ") + what);
}

/// The owner of `id`, closed by `close`; Error naming `what` when the call that made it failed.
H5Id owned(hid_t id, herr_t (*close)(hid_t), const char* what) {
  if (id < 0) throw Error(std::string("HDF5 call failed: ") + what);
  return H5Id(id, close);
}

void string_attribute(hid_t obj, const char* name, const std::string& value) {
  const H5Id type = owned(H5Tcopy(H5T_C_S1), H5Tclose, "H5Tcopy");
  check_h5(H5Tset_size(type.get(), std::max<std::size_t>(value.size(), 1)), "H5Tset_size");
  const H5Id space = owned(H5Screate(H5S_SCALAR), H5Sclose, "H5Screate");
  const H5Id attr = owned(H5Acreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose, name);
  check_h5(H5Awrite(attr.get(), type.get(), value.empty() ? " " : value.c_str()), name);
}

template <class T>
void scalar_attribute(hid_t obj, const char* name, hid_t type, T value) {
  const H5Id space = owned(H5Screate(H5S_SCALAR), H5Sclose, "H5Screate");
  const H5Id attr = owned(H5Acreate2(obj, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose, name);
  check_h5(H5Awrite(attr.get(), type, &value), name);
}

/// A text of any length as a scalar string dataset (an attribute lives in its object's header,
/// which holds at most 64 KB; a resolved scene can be larger). Collective; rank 0 writes it.
void text_dataset(hid_t loc, const char* name, const std::string& value, bool writer) {
  const H5Id type = owned(H5Tcopy(H5T_C_S1), H5Tclose, "H5Tcopy");
  check_h5(H5Tset_size(type.get(), std::max<std::size_t>(value.size(), 1)), "H5Tset_size");
  check_h5(H5Tset_strpad(type.get(), H5T_STR_NULLPAD), "H5Tset_strpad");
  check_h5(H5Tset_cset(type.get(), H5T_CSET_UTF8), "H5Tset_cset");
  const H5Id space = owned(H5Screate(H5S_SCALAR), H5Sclose, "H5Screate");
  const H5Id dset =
      owned(H5Dcreate2(loc, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose, name);
  if (writer)
    check_h5(H5Dwrite(dset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, value.empty() ? "" : value.c_str()), name);
}

/// Reads a frame group's step and time attributes; false if either cannot be read.
bool frame_attributes(hid_t group, long long& step, double& time) {
  const H5Id a(H5Aopen(group, "step", H5P_DEFAULT), H5Aclose), b(H5Aopen(group, "time", H5P_DEFAULT), H5Aclose);
  return a.ok() && b.ok() && H5Aread(a.get(), H5T_NATIVE_LLONG, &step) >= 0 &&
         H5Aread(b.get(), H5T_NATIVE_DOUBLE, &time) >= 0;
}

std::string frame_name(int k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "/frames/%06d", k);
  return buf;
}

}  // namespace

bool abandoned_output_files() { return g_abandoned; }
void mark_output_file_abandoned() { g_abandoned = true; }

void make_output_dir(const std::string& dir, MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  char msg[512] = {0};
  if (rank == 0) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) std::snprintf(msg, sizeof msg, "cannot create output directory '%s': %s", dir.c_str(), ec.message().c_str());
  }
  MPI_Bcast(msg, sizeof msg, MPI_CHAR, 0, comm);
  if (msg[0]) throw InputError(msg);
}

void write_text_file(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) {
      const std::string why = std::strerror(errno);
      out.close();
      std::remove(tmp.c_str());
      throw Error("cannot write '" + tmp + "': " + why);
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw Error("cannot rename '" + tmp + "' to '" + path + "': " + std::strerror(errno));
}

double frame_bytes(const Output& output, std::int64_t nodes) {
  int values = 0;
  for (const std::string& f : output.fields) values += f == "position" || f == "displacement" || f == "velocity" ? 3 : 1;
  return (output.single_precision ? 4.0 : 8.0) * values * static_cast<double>(nodes) + 65536.0;  // + metadata
}

double mesh_bytes(const Output& output, std::int64_t nodes, std::int64_t triangles) {
  // reference positions, body, volume (doubles), cells (int64), natural ids with a selection; the
  // mesh membranes' triangles (3 int64 each)
  return (8.0 * 5 + 8.0 + (output.selects_nodes() ? 8.0 : 0.0)) * static_cast<double>(nodes) +
         24.0 * static_cast<double>(triangles) + 65536.0;
}

double output_bytes(const Output& output, std::int64_t frames, std::int64_t frame_nodes, std::int64_t nodes, bool mesh,
                    std::int64_t triangles, std::string* parts) {
  const double frame = frame_bytes(output, frame_nodes),
               mesh_part = mesh ? mesh_bytes(output, frame_nodes, triangles) : 0.0;
  // Checkpoints by step count: the current one and the previous, displacement and velocity at
  // least (broken bonds add 16 bytes each).
  const double checkpoints = output.checkpoint_every_steps > 0 ? 2.0 * (48.0 * static_cast<double>(nodes) + 65536.0) : 0.0;
  if (parts) {
    std::ostringstream s;
    s.precision(3);
    s << frames << " frames of " << frame / 1e6 << " MB";
    if (mesh_part > 0) s << ", the mesh " << mesh_part / 1e6 << " MB";
    if (checkpoints > 0) s << ", checkpoints " << checkpoints / 1e6 << " MB";
    *parts = s.str();
  }
  return static_cast<double>(frames) * frame + mesh_part + checkpoints;
}

std::int64_t output_frames(const Output& output, std::int64_t total_steps) {
  return std::clamp<std::int64_t>(output.frames, 1, total_steps + 1);
}

FrameWriter::FrameWriter(const std::string& dir, const std::string& stem, const Domain& domain, State& state,
                         const Output& output)
    : dir_(dir), stem_(stem), domain_(domain), state_(state), output_(output) {
  // The frame nodes of this rank's natural slice: every node_stride-th natural id, in the region.
  const std::int64_t begin = state_.natural_begin(), count = state_.natural_count();
  if (output_.selects_nodes()) {
    const double* X = state_.to_natural(domain_.X.data(), 3);
    for (std::int64_t k = 0; k < count; ++k) {
      if ((begin + k) % output_.node_stride != 0) continue;
      bool inside = true;
      if (output_.region)
        for (int c = 0; c < 3; ++c)
          inside = inside && X[3 * k + c] >= (*output_.region)[0][c] && X[3 * k + c] <= (*output_.region)[1][c];
      if (inside) pick_.push_back(k);
    }
    sel_count_ = static_cast<std::int64_t>(pick_.size());
  } else {
    sel_count_ = count;
  }
  long long mine = sel_count_, before = 0, all = 0;
  MPI_Exscan(&mine, &before, 1, MPI_LONG_LONG, MPI_SUM, state_.comm());
  MPI_Allreduce(&mine, &all, 1, MPI_LONG_LONG, MPI_SUM, state_.comm());
  sel_begin_ = domain_.rank == 0 ? 0 : before;
  sel_total_ = all;
}

void FrameWriter::start(const std::string& resolved_scene, std::int64_t resume_step) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors are reported by our checks
  const H5Id fapl = owned(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, "H5Pcreate");
  check_h5(H5Pset_fapl_mpio(fapl.get(), state_.comm(), MPI_INFO_NULL), "H5Pset_fapl_mpio");
  {
    // A small metadata cache (1-2 MB, HDF5's default grows to 32 MB): each frame adds a group and
    // its datasets' headers, and every collective flush walks the whole cache, so with the default
    // a run's flushes cost more with every frame (fiber_long_range, 280 nodes, 8000 frames, one
    // rank: 50 s, of which 35% in H5C_apply_candidate_list and H5C_set_slist_enabled; 24 s with
    // this). Large frames are not slower (the default scene: the same time, the same frames).
    H5AC_cache_config_t mdc;
    mdc.version = H5AC__CURR_CACHE_CONFIG_VERSION;
    check_h5(H5Pget_mdc_config(fapl.get(), &mdc), "H5Pget_mdc_config");
    mdc.set_initial_size = 1;
    mdc.initial_size = 1 << 20;
    mdc.min_size = 1 << 20;
    mdc.max_size = 2 << 20;
    check_h5(H5Pset_mdc_config(fapl.get(), &mdc), "H5Pset_mdc_config");
  }
  const std::string path = dir_ + "/" + stem_ + ".h5";
  if (resume_step >= 0) {
    if (reopen(path, fapl.get(), resume_step) || salvage(path, fapl.get(), resume_step, resolved_scene)) {
      if (domain_.rank == 0) write_xdmf(true);
      return;
    }
    std::error_code ec;  // (a resume into a new directory has no file to continue: no note)
    if (domain_.rank == 0 && std::filesystem::exists(path, ec))
      std::fprintf(stderr, "peridrive: note: '%s' cannot be continued; starting it afresh at step %lld\n",
                   path.c_str(), static_cast<long long>(resume_step));
  }
  file_ = create(path, fapl.get(), resolved_scene);
}

const void* FrameWriter::select(const double* slice, int bs, bool single) {
  const std::size_t n = static_cast<std::size_t>(sel_count_) * bs;
  const double* from = slice;
  if (output_.selects_nodes()) {
    selected_.resize(n);
    for (std::size_t k = 0; k < pick_.size(); ++k)
      for (int c = 0; c < bs; ++c) selected_[k * bs + c] = slice[pick_[k] * bs + c];
    from = selected_.data();
  }
  if (!single) return from;
  selected_single_.resize(n);
  for (std::size_t a = 0; a < n; ++a) selected_single_[a] = static_cast<float>(from[a]);
  return selected_single_.data();
}

H5Id FrameWriter::create(const std::string& path, hid_t fapl, const std::string& resolved_scene) {
  const Domain& domain = domain_;
  State& state = state_;
  H5Id file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl), H5Fclose);
  agree(file.ok(), "creating the file");
  string_attribute(file.get(), "peridrive_version", version());
  string_attribute(file.get(), "git_revision", git_revision());
  text_dataset(file.get(), "scene", resolved_scene, domain.rank == 0);
  scalar_attribute<long long>(file.get(), "nodes", H5T_NATIVE_LLONG, domain.global_nodes);
  if (output_.selects_nodes()) scalar_attribute<long long>(file.get(), "frame_nodes", H5T_NATIVE_LLONG, sel_total_);
  scalar_attribute<int>(file.get(), "ranks", H5T_NATIVE_INT, domain.ranks);
  {
    const H5Id mesh = owned(H5Gcreate2(file.get(), "/mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose, "/mesh");
    write_dataset(mesh.get(), "reference_position", select(state.to_natural(domain.X.data(), 3), 3, false), 3);
    std::vector<double> body(domain.owned);
    for (std::int32_t i = 0; i < domain.owned; ++i) body[i] = domain.body[i];
    write_dataset(mesh.get(), "body", select(state.to_natural(body.data(), 1), 1, false), 1);
    write_dataset(mesh.get(), "volume", select(state.to_natural(domain.volume.data(), 1), 1, false), 1);
    write_connectivity(mesh.get());
    if (!triangles_.empty()) {  // (natural ids: a node selection keeps them all; readers map them)
      const hsize_t dims[2] = {triangles_.size(), 3};
      const H5Id space = owned(H5Screate_simple(2, dims, nullptr), H5Sclose, "H5Screate_simple");
      const H5Id dset = owned(H5Dcreate2(mesh.get(), "triangles", H5T_NATIVE_INT64, space.get(), H5P_DEFAULT,
                                         H5P_DEFAULT, H5P_DEFAULT), H5Dclose, "triangles");
      const bool written = domain.rank != 0 ||  // (rank 0 writes them all; a failure stops every rank)
                           H5Dwrite(dset.get(), H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, triangles_.data()) >= 0;
      agree(written, "writing /mesh/triangles");
    }
    if (output_.selects_nodes()) {  // which nodes the frames hold
      std::vector<std::int64_t> ids(pick_.size());
      for (std::size_t k = 0; k < pick_.size(); ++k) ids[k] = state.natural_begin() + pick_[k];
      write_dataset(mesh.get(), "natural_id", ids.data(), 1, H5T_NATIVE_INT64, H5T_NATIVE_INT64);
    }
  }
  owned(H5Gcreate2(file.get(), "/frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose, "/frames");
  check_h5(H5Fflush(file.get(), H5F_SCOPE_GLOBAL), "H5Fflush");
  return file;
}

bool FrameWriter::reopen(const std::string& path, hid_t fapl, std::int64_t resume_step) {
  // Collective: every rank makes the same metadata calls and reaches the same verdict.
  std::error_code ec;
  int exists = domain_.rank == 0 && std::filesystem::is_regular_file(path, ec);
  MPI_Bcast(&exists, 1, MPI_INT, 0, state_.comm());
  if (!exists) return false;
  file_ = H5Id(H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl), H5Fclose);
  if (!file_.ok()) return false;
  const hid_t file = file_.get();
  bool ok = H5Lexists(file, "/mesh", H5P_DEFAULT) > 0 && H5Lexists(file, "/frames", H5P_DEFAULT) > 0;
  H5Id frames = ok ? H5Id(H5Gopen2(file, "/frames", H5P_DEFAULT), H5Gclose) : H5Id();
  H5G_info_t info;
  ok = ok && frames.ok() && H5Gget_info(frames.get(), &info) >= 0;
  // Every frame readable first (a partly written one: salvage()); then those after the step go.
  std::vector<std::string> after;
  for (hsize_t k = 0; ok && k < info.nlinks; ++k) {
    const std::string name = frame_name(static_cast<int>(k));
    const H5Id g = H5Lexists(file, name.c_str(), H5P_DEFAULT) > 0 ? H5Id(H5Gopen2(file, name.c_str(), H5P_DEFAULT), H5Gclose)
                                                                  : H5Id();
    long long step = -1;
    double time = 0;
    ok = g.ok() && frame_attributes(g.get(), step, time);
    if (ok && step <= resume_step && after.empty()) {
      times_.push_back(time);
      steps_.push_back(step);
    } else {
      after.push_back(name);
    }
  }
  int all = ok;
  MPI_Allreduce(MPI_IN_PLACE, &all, 1, MPI_INT, MPI_MIN, state_.comm());
  ok = all;
  for (std::size_t k = 0; ok && k < after.size(); ++k) ok = H5Ldelete(file, after[k].c_str(), H5P_DEFAULT) >= 0;
  frames.close();
  // Files written before the mesh held its cells get them now: the XDMF names them.
  if (ok && H5Lexists(file, "/mesh/connectivity", H5P_DEFAULT) <= 0) {
    const H5Id mesh(H5Gopen2(file, "/mesh", H5P_DEFAULT), H5Gclose);
    ok = mesh.ok();
    if (ok) write_connectivity(mesh.get());
  }
  ok = ok && H5Fflush(file, H5F_SCOPE_GLOBAL) >= 0;
  if (!ok) {
    file_.close();
    times_.clear();
    steps_.clear();
  }
  return ok;
}

bool FrameWriter::salvage(const std::string& path, hid_t fapl, std::int64_t resume_step,
                          const std::string& resolved_scene) {
  // Collective. A run killed while writing a frame can leave that frame's objects half written
  // (HDF5 is not crash-safe): they then can be neither read nor unlinked, and reopen() gives up.
  // The frames before it were flushed whole; they are copied, in order, into a new file that
  // replaces the old one. Every rank reads its own slice of each dataset, as write() wrote it.
  std::error_code ec;
  int exists = domain_.rank == 0 && std::filesystem::is_regular_file(path, ec);
  MPI_Bcast(&exists, 1, MPI_INT, 0, state_.comm());
  if (!exists) return false;
  H5Id old(H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl), H5Fclose);
  if (!old.ok()) return false;
  // Each frame's datasets and their components per node.
  std::vector<std::pair<const char*, int>> names;
  for (const std::string& f : frame_field_names())
    if (output_.has_field(f)) names.push_back({f.c_str(), f == "position" || f == "displacement" || f == "velocity" ? 3 : 1});
  const hsize_t begin = static_cast<hsize_t>(sel_begin_), count = static_cast<hsize_t>(sel_count_);
  const bool single = output_.single_precision;
  const std::string tmp = path + ".salvage";
  H5Id fresh = create(tmp, fapl, resolved_scene);
  std::vector<double> slice;
  int kept = 0;
  for (;; ++kept) {
    const std::string name = frame_name(kept);
    // The frame's group, step and time, and its datasets with the right shape: readable on every rank?
    long long step = -1;
    double time = 0;
    const H5Id g = H5Lexists(old.get(), name.c_str(), H5P_DEFAULT) > 0
                       ? H5Id(H5Gopen2(old.get(), name.c_str(), H5P_DEFAULT), H5Gclose)
                       : H5Id();
    int ok = g.ok() && frame_attributes(g.get(), step, time) && step <= resume_step;
    for (std::size_t d = 0; ok && d < names.size(); ++d) {
      const H5Id ds(H5Dopen2(g.get(), names[d].first, H5P_DEFAULT), H5Dclose);
      const H5Id space = ds.ok() ? H5Id(H5Dget_space(ds.get()), H5Sclose) : H5Id();
      hsize_t dims[2] = {0, 0};
      const int rank = space.ok() ? H5Sget_simple_extent_dims(space.get(), dims, nullptr) : -1;
      const int bs = names[d].second;
      ok = rank == (bs == 1 ? 1 : 2) && dims[0] == static_cast<hsize_t>(sel_total_) &&
           (bs == 1 || dims[1] == 3);
    }
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, state_.comm());
    if (!all) break;
    const H5Id to = owned(H5Gcreate2(fresh.get(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose,
                          name.c_str());
    scalar_attribute<long long>(to.get(), "step", H5T_NATIVE_LLONG, step);
    scalar_attribute<double>(to.get(), "time", H5T_NATIVE_DOUBLE, time);
    for (std::size_t d = 0; d < names.size(); ++d) {
      const int bs = names[d].second;
      {
        const H5Id ds = owned(H5Dopen2(g.get(), names[d].first, H5P_DEFAULT), H5Dclose, names[d].first);
        const H5Id filespace = owned(H5Dget_space(ds.get()), H5Sclose, "H5Dget_space");
        hsize_t start[2] = {begin, 0}, counts[2] = {count, static_cast<hsize_t>(bs)};
        check_h5(H5Sselect_hyperslab(filespace.get(), H5S_SELECT_SET, start, nullptr, counts, nullptr), "hyperslab");
        const H5Id memspace = owned(H5Screate_simple(bs == 1 ? 1 : 2, counts, nullptr), H5Sclose, "memspace");
        const H5Id dxpl = owned(H5Pcreate(H5P_DATASET_XFER), H5Pclose, "dxpl");
        check_h5(H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE), "H5Pset_dxpl_mpio");
        slice.resize(static_cast<std::size_t>(count) * bs);
        check_h5(H5Dread(ds.get(), H5T_NATIVE_DOUBLE, memspace.get(), filespace.get(), dxpl.get(), slice.data()),
                 names[d].first);
      }
      if (single) {
        selected_single_.assign(slice.begin(), slice.end());
        write_dataset(to.get(), names[d].first, selected_single_.data(), bs, H5T_NATIVE_FLOAT, H5T_IEEE_F32LE);
      } else {
        write_dataset(to.get(), names[d].first, slice.data(), bs);
      }
    }
    times_.push_back(time);
    steps_.push_back(step);
  }
  old.close();
  check_h5(H5Fflush(fresh.get(), H5F_SCOPE_GLOBAL), "H5Fflush");
  fresh.close();
  char msg[512] = {0};
  if (domain_.rank == 0 && std::rename(tmp.c_str(), path.c_str()) != 0)
    std::snprintf(msg, sizeof msg, "cannot rename '%s' to '%s': %s", tmp.c_str(), path.c_str(), std::strerror(errno));
  MPI_Bcast(msg, sizeof msg, MPI_CHAR, 0, state_.comm());
  if (msg[0]) throw Error(msg);
  file_ = owned(H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl), H5Fclose, path.c_str());
  if (domain_.rank == 0 && kept > 0)
    std::fprintf(stderr,
                 "peridrive: note: '%s' held a partly written frame (a run stopped while writing it); "
                 "its first %d frames, up to step %lld, were copied into a new file, which continues\n",
                 path.c_str(), kept, static_cast<long long>(resume_step));
  else if (domain_.rank == 0)
    std::fprintf(stderr, "peridrive: note: '%s' cannot be continued; starting it afresh at step %lld\n",
                 path.c_str(), static_cast<long long>(resume_step));
  return true;
}

FrameWriter::~FrameWriter() { list_unlisted_frames(true); }

void FrameWriter::list_unlisted_frames(bool warn) const noexcept {
  if (domain_.rank != 0 || xdmf_listed_ == times_.size()) return;
  try {
    write_xdmf(true);
  } catch (const std::exception& e) {
    if (warn) std::fprintf(stderr, "peridrive: warning: %s\n", e.what());
  }
}

void FrameWriter::write_connectivity(hid_t mesh) {
  // One vertex cell per frame node, numbered in the file's order: readers that build cells from
  // the topology (ParaView's Xdmf3 readers, meshio) then see every node.
  std::vector<std::int64_t> cells(static_cast<std::size_t>(sel_count_));
  for (std::size_t k = 0; k < cells.size(); ++k) cells[k] = sel_begin_ + static_cast<std::int64_t>(k);
  write_dataset(mesh, "connectivity", cells.data(), 1, H5T_NATIVE_INT64, H5T_NATIVE_INT64);
}

void FrameWriter::write_dataset(hid_t group, const char* name, const void* data, int bs, hid_t mem_type,
                                hid_t file_type) {
  hsize_t dims[2] = {static_cast<hsize_t>(sel_total_), static_cast<hsize_t>(bs)};
  const H5Id filespace = owned(H5Screate_simple(bs == 1 ? 1 : 2, dims, nullptr), H5Sclose, "H5Screate_simple");
  // Creating and writing a dataset are collective: every rank learns of a failure on any, and all
  // stop at the same call (a full disk is seen by the ranks whose data did not fit).
  const H5Id dset(H5Dcreate2(group, name, file_type, filespace.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
  agree(dset.ok(), std::string("creating dataset ") + name);
  hsize_t start[2] = {static_cast<hsize_t>(sel_begin_), 0};
  hsize_t count[2] = {static_cast<hsize_t>(sel_count_), static_cast<hsize_t>(bs)};
  check_h5(H5Sselect_hyperslab(filespace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), "hyperslab");
  const H5Id memspace = owned(H5Screate_simple(bs == 1 ? 1 : 2, count, nullptr), H5Sclose, "memspace");
  const H5Id dxpl = owned(H5Pcreate(H5P_DATASET_XFER), H5Pclose, "dxpl");
  check_h5(H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE), "H5Pset_dxpl_mpio");
  agree(H5Dwrite(dset.get(), mem_type, memspace.get(), filespace.get(), dxpl.get(), data) >= 0,
        std::string("writing dataset ") + name);
}

double FrameWriter::frame_bytes() const { return peri::frame_bytes(output_, sel_total_); }

// Why a write may have failed on this rank beyond a full disk: the file size limit (ulimit -f).
std::string FrameWriter::local_reason() const {
  struct rlimit lim;
  if (getrlimit(RLIMIT_FSIZE, &lim) != 0 || lim.rlim_cur == RLIM_INFINITY) return "";
  std::error_code ec;
  const auto size = std::filesystem::file_size(dir_ + "/" + stem_ + ".h5", ec);
  if (ec || static_cast<double>(size) + frame_bytes() < static_cast<double>(lim.rlim_cur)) return "";
  return ": the file reached this process's file size limit (ulimit -f) of " + std::to_string(lim.rlim_cur) + " bytes";
}

void FrameWriter::agree(bool ok, const std::string& what) {
  const std::string verdict = agree_on_message(ok ? "" : what + " failed" + local_reason(), state_.comm());
  if (verdict.empty()) return;
  // HDF5 1.10 may crash closing a file whose MPI-IO writes failed: the run ends without closing
  // it (the frames before are whole on disk: each was flushed).
  file_.abandon();
  g_abandoned = true;
  list_unlisted_frames(false);  // (the message below promises it)
  const double free = free_bytes(dir_);
  std::string why = dir_ + "/" + stem_ + ".h5: " + verdict;
  if (free >= 0 && free < frame_bytes())
    why += "; no space left: the file system holding '" + dir_ + "' has " + std::to_string(static_cast<long long>(free)) +
           " bytes free, a frame takes about " + std::to_string(static_cast<long long>(frame_bytes()));
  else if (free >= 0)
    why += "; the file system holding '" + dir_ + "' has " + std::to_string(static_cast<long long>(free)) + " bytes free";
  throw RuntimeFailure(frames() > 0 ? why + "; " + stem_ + ".xdmf lists the frames written before it" : why);
}

void FrameWriter::write(std::int64_t step, double time, const double* u, const double* v,
                        const double* damage, const double* energy_density) {
  const int k = frames();
  const std::string name = frame_name(k);
  const std::string frame = "the frame of step " + std::to_string(step) + ": ";
  {
    // Room for the frame first, decided on rank 0 for all (a full disk stops the run here, with
    // the file whole).
    double free = -1;
    if (domain_.rank == 0) free = free_bytes(dir_);
    MPI_Bcast(&free, 1, MPI_DOUBLE, 0, state_.comm());
    if (free >= 0 && free < frame_bytes()) {
      list_unlisted_frames(false);  // (the message below promises it; the XDMF is small)
      throw RuntimeFailure(dir_ + "/" + stem_ + ".h5: no space left for the frame of step " + std::to_string(step) +
                           ": it takes about " + std::to_string(static_cast<long long>(frame_bytes())) +
                           " bytes and the file system holding '" + dir_ + "' has " +
                           std::to_string(static_cast<long long>(free)) + " free; " + stem_ +
                           ".xdmf lists the frames written before it");
    }
    const H5Id g(H5Gcreate2(file_.get(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    agree(g.ok(), frame + "creating group " + name);
    scalar_attribute<long long>(g.get(), "step", H5T_NATIVE_LLONG, step);
    scalar_attribute<double>(g.get(), "time", H5T_NATIVE_DOUBLE, time);
    const bool single = output_.single_precision;
    const hid_t mem = single ? H5T_NATIVE_FLOAT : H5T_NATIVE_DOUBLE, file = single ? H5T_IEEE_F32LE : H5T_NATIVE_DOUBLE;
    auto field = [&](const char* name, const double* owned, int bs) {
      if (output_.has_field(name)) write_dataset(g.get(), name, select(state_.to_natural(owned, bs), bs, single), bs, mem, file);
    };
    if (output_.has_field("position")) {
      const std::size_t n3 = 3 * static_cast<std::size_t>(domain_.owned);
      work_.resize(n3);
      for (std::size_t a = 0; a < n3; ++a) work_[a] = domain_.X[a] + u[a];
      field("position", work_.data(), 3);
    }
    field("displacement", u, 3);
    field("velocity", v, 3);
    field("damage", damage, 1);
    field("strain_energy_density", energy_density, 1);
  }
  agree(H5Fflush(file_.get(), H5F_SCOPE_GLOBAL) >= 0, frame + "flushing");
  times_.push_back(time);
  steps_.push_back(step);
  if (domain_.rank == 0) write_xdmf(false);
}

void FrameWriter::write_xdmf(bool always) const {
  const double now = MPI_Wtime();
  if (!always && times_.size() > kXdmfEveryFrame && now - xdmf_written_at_ < kXdmfSeconds) return;
  write_xdmf_file(stem_ + ".xdmf", false);
  // The mesh membranes' triangles over the same frames (every node written: the triangles'
  // natural ids are the frames' node order).
  if (!triangles_.empty() && !output_.selects_nodes()) write_xdmf_file(stem_ + "_surface.xdmf", true);
  xdmf_written_at_ = now;
  xdmf_listed_ = times_.size();
}

std::string FrameWriter::xdmf_grid(std::size_t k, bool surface) const {
  const std::string h5 = stem_ + ".h5";
  const long long n = sel_total_;
  std::ostringstream x;
  x << std::setprecision(17);
  auto item = [&](const std::string& path, int bs, int precision) {
    std::ostringstream s;
    s << "<DataItem Dimensions=\"" << n << (bs == 3 ? " 3" : "") << "\" NumberType=\"Float\" Precision=\""
      << precision << "\" Format=\"HDF\">" << h5 << ":" << path << "</DataItem>";
    return s.str();
  };
  const int field_precision = output_.single_precision ? 4 : 8;
  const std::string f = frame_name(static_cast<int>(k));
  x << "   <Grid Name=\"frame" << k << "\" GridType=\"Uniform\">\n"
    << "    <Time Value=\"" << times_[k] << "\"/>\n";
  if (surface)
    x << "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"" << triangles_.size() << "\">"
      << "<DataItem Dimensions=\"" << triangles_.size() << " 3\" NumberType=\"Int\" Precision=\"8\" Format=\"HDF\">"
      << h5 << ":/mesh/triangles</DataItem></Topology>\n";
  else
    x << "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n << "\" NodesPerElement=\"1\">"
      << "<DataItem Dimensions=\"" << n << "\" NumberType=\"Int\" Precision=\"8\" Format=\"HDF\">" << h5
      << ":/mesh/connectivity</DataItem></Topology>\n";
  x << "    <Geometry GeometryType=\"XYZ\">"
    << (output_.has_field("position") ? item(f + "/position", 3, field_precision) : item("/mesh/reference_position", 3, 8))
    << "</Geometry>\n";
  for (const std::string& name : frame_field_names()) {
    if (name == "position" || !output_.has_field(name)) continue;
    const bool vector = name == "displacement" || name == "velocity";
    x << "    <Attribute Name=\"" << name << "\" AttributeType=\"" << (vector ? "Vector" : "Scalar")
      << "\" Center=\"Node\">" << item(f + "/" + name, vector ? 3 : 1, field_precision) << "</Attribute>\n";
  }
  x << "    <Attribute Name=\"body\" AttributeType=\"Scalar\" Center=\"Node\">" << item("/mesh/body", 1, 8)
    << "</Attribute>\n"
    << "   </Grid>\n";
  return x.str();
}

void FrameWriter::write_xdmf_file(const std::string& name, bool surface) const {
  // The frames' entries, generated once each (a resume that dropped frames starts them again).
  std::string& grids = xdmf_grids_[surface];
  std::size_t& cached = xdmf_cached_[surface];
  if (cached > times_.size()) grids.clear(), cached = 0;
  for (; cached < times_.size(); ++cached) grids += xdmf_grid(cached, surface);
  std::string text =
      "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n<Xdmf Version=\"3.0\">\n <Domain>\n"
      "  <Grid Name=\"peridrive\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  text.reserve(text.size() + grids.size() + 64);
  text += grids;
  text += "  </Grid>\n </Domain>\n</Xdmf>\n";
  write_text_file(dir_ + "/" + name, text);
}

std::string rows_up_to(const std::string& path, const std::string& header, std::int64_t step) {
  std::ifstream in(path, std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string kept = header;
  std::size_t start = text.compare(0, header.size(), header) == 0 ? header.size() : text.size();
  for (std::size_t nl; (nl = text.find('\n', start)) != std::string::npos; start = nl + 1) {
    if (std::strtoll(text.c_str() + start, nullptr, 10) > step) break;
    kept.append(text, start, nl + 1 - start);
  }
  return kept;
}

SeriesWriter::SeriesWriter(const std::string& path, bool active, const std::string& extra_columns,
                           std::int64_t resume_step)
    : active_(active) {
  if (!active_) return;
  const std::string header =
      "step,time,kinetic_energy,strain_energy,external_work,dissipated_energy,total_energy,broken_bonds" +
      std::string(extra_columns.empty() ? "" : ",") + extra_columns + "\n";
  if (resume_step >= 0) {
    write_text_file(path, rows_up_to(path, header, resume_step));
    out_.open(path, std::ios::app);
  } else {
    out_.open(path, std::ios::trunc);
    out_ << header;
  }
  out_ << std::setprecision(12);  // (a file that cannot be written shows in good(): RunOutput reports it)
}

bool SeriesWriter::good() const { return !active_ || static_cast<bool>(out_); }

void SeriesWriter::write(const EnergyRow& r, const std::string& extra) {
  if (!active_) return;
  out_ << r.step << ',' << r.time << ',' << r.kinetic << ',' << r.strain << ',' << r.external_work
       << ',' << r.dissipated << ',' << r.total() << ',' << r.broken_bonds << (extra.empty() ? "" : ",")
       << extra << '\n';
  out_.flush();
}

}  // namespace peri
