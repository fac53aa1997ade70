#include "peri/io/output.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <cstdlib>
#include <iomanip>
#include <iterator>
#include <sstream>

#include "peri/core/build_info.hpp"
#include "peri/core/error.hpp"

namespace peri {
namespace {

void check_h5(herr_t status, const char* what) {
  if (status < 0) throw Error(std::string("HDF5 call failed: ") + what);
}

hid_t check_id(hid_t id, const char* what) {
  if (id < 0) throw Error(std::string("HDF5 call failed: ") + what);
  return id;
}

void string_attribute(hid_t obj, const char* name, const std::string& value) {
  hid_t type = check_id(H5Tcopy(H5T_C_S1), "H5Tcopy");
  check_h5(H5Tset_size(type, std::max<std::size_t>(value.size(), 1)), "H5Tset_size");
  hid_t space = check_id(H5Screate(H5S_SCALAR), "H5Screate");
  hid_t attr = check_id(H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT), name);
  check_h5(H5Awrite(attr, type, value.empty() ? " " : value.c_str()), name);
  H5Aclose(attr);
  H5Sclose(space);
  H5Tclose(type);
}

template <class T>
void scalar_attribute(hid_t obj, const char* name, hid_t type, T value) {
  hid_t space = check_id(H5Screate(H5S_SCALAR), "H5Screate");
  hid_t attr = check_id(H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT), name);
  check_h5(H5Awrite(attr, type, &value), name);
  H5Aclose(attr);
  H5Sclose(space);
}

/// A text of any length as a scalar string dataset (an attribute lives in its object's header,
/// which holds at most 64 KB; a resolved scene can be larger). Collective; rank 0 writes it.
void text_dataset(hid_t loc, const char* name, const std::string& value, bool writer) {
  hid_t type = check_id(H5Tcopy(H5T_C_S1), "H5Tcopy");
  check_h5(H5Tset_size(type, std::max<std::size_t>(value.size(), 1)), "H5Tset_size");
  check_h5(H5Tset_strpad(type, H5T_STR_NULLPAD), "H5Tset_strpad");
  check_h5(H5Tset_cset(type, H5T_CSET_UTF8), "H5Tset_cset");
  hid_t space = check_id(H5Screate(H5S_SCALAR), "H5Screate");
  hid_t dset = check_id(H5Dcreate2(loc, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), name);
  if (writer) check_h5(H5Dwrite(dset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, value.empty() ? "" : value.c_str()), name);
  H5Dclose(dset);
  H5Sclose(space);
  H5Tclose(type);
}

std::string frame_name(int k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "/frames/%06d", k);
  return buf;
}

}  // namespace

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
    if (!out) throw Error("cannot write '" + tmp + "': " + std::strerror(errno));
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw Error("cannot rename '" + tmp + "' to '" + path + "': " + std::strerror(errno));
}

FrameWriter::FrameWriter(const std::string& dir, const std::string& stem, const Domain& domain,
                         State& state, const std::string& resolved_scene, bool write_velocity,
                         std::int64_t resume_step)
    : dir_(dir), stem_(stem), domain_(domain), state_(state), write_velocity_(write_velocity) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors are reported by our checks
  hid_t fapl = check_id(H5Pcreate(H5P_FILE_ACCESS), "H5Pcreate");
  check_h5(H5Pset_fapl_mpio(fapl, state.comm(), MPI_INFO_NULL), "H5Pset_fapl_mpio");
  const std::string path = dir + "/" + stem + ".h5";
  if (resume_step >= 0) {
    if (reopen(path, fapl, resume_step) || salvage(path, fapl, resume_step, resolved_scene)) {
      H5Pclose(fapl);
      if (domain_.rank == 0) write_xdmf();
      return;
    }
    if (domain_.rank == 0)
      std::fprintf(stderr, "peridrive: note: '%s' cannot be continued; starting it afresh at step %lld\n",
                   path.c_str(), static_cast<long long>(resume_step));
  }
  file_ = create(path, fapl, resolved_scene);
  H5Pclose(fapl);
}

hid_t FrameWriter::create(const std::string& path, hid_t fapl, const std::string& resolved_scene) {
  const Domain& domain = domain_;
  State& state = state_;
  hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  if (file < 0) throw Error("cannot create HDF5 file '" + path + "'");
  string_attribute(file, "peridrive_version", version());
  string_attribute(file, "git_revision", git_revision());
  text_dataset(file, "scene", resolved_scene, domain.rank == 0);
  scalar_attribute<long long>(file, "nodes", H5T_NATIVE_LLONG, domain.global_nodes);
  scalar_attribute<int>(file, "ranks", H5T_NATIVE_INT, domain.ranks);
  hid_t mesh = check_id(H5Gcreate2(file, "/mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "/mesh");
  write_dataset(mesh, "reference_position", state.to_natural(domain.X.data(), 3), 3);
  std::vector<double> body(domain.owned);
  for (std::int32_t i = 0; i < domain.owned; ++i) body[i] = domain.body[i];
  write_dataset(mesh, "body", state.to_natural(body.data(), 1), 1);
  write_dataset(mesh, "volume", state.to_natural(domain.volume.data(), 1), 1);
  write_connectivity(mesh);
  H5Gclose(mesh);
  hid_t frames = check_id(H5Gcreate2(file, "/frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "/frames");
  H5Gclose(frames);
  check_h5(H5Fflush(file, H5F_SCOPE_GLOBAL), "H5Fflush");
  return file;
}

bool FrameWriter::reopen(const std::string& path, hid_t fapl, std::int64_t resume_step) {
  // Collective: every rank makes the same metadata calls and reaches the same verdict.
  std::error_code ec;
  int exists = domain_.rank == 0 && std::filesystem::is_regular_file(path, ec);
  MPI_Bcast(&exists, 1, MPI_INT, 0, state_.comm());
  if (!exists) return false;
  file_ = H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl);
  if (file_ < 0) return false;
  bool ok = H5Lexists(file_, "/mesh", H5P_DEFAULT) > 0 && H5Lexists(file_, "/frames", H5P_DEFAULT) > 0;
  hid_t frames = ok ? H5Gopen2(file_, "/frames", H5P_DEFAULT) : -1;
  H5G_info_t info;
  ok = ok && frames >= 0 && H5Gget_info(frames, &info) >= 0;
  // Every frame readable first (a partly written one: salvage()); then those after the step go.
  std::vector<std::string> after;
  for (hsize_t k = 0; ok && k < info.nlinks; ++k) {
    const std::string name = frame_name(static_cast<int>(k));
    hid_t g = H5Lexists(file_, name.c_str(), H5P_DEFAULT) > 0 ? H5Gopen2(file_, name.c_str(), H5P_DEFAULT) : -1;
    long long step = -1;
    double time = 0;
    ok = g >= 0;
    if (ok) {
      hid_t a = H5Aopen(g, "step", H5P_DEFAULT), b = H5Aopen(g, "time", H5P_DEFAULT);
      ok = a >= 0 && b >= 0 && H5Aread(a, H5T_NATIVE_LLONG, &step) >= 0 && H5Aread(b, H5T_NATIVE_DOUBLE, &time) >= 0;
      if (a >= 0) H5Aclose(a);
      if (b >= 0) H5Aclose(b);
      H5Gclose(g);
    }
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
  for (std::size_t k = 0; ok && k < after.size(); ++k) ok = H5Ldelete(file_, after[k].c_str(), H5P_DEFAULT) >= 0;
  if (frames >= 0) H5Gclose(frames);
  // Files written before the mesh held its cells get them now: the XDMF names them.
  if (ok && H5Lexists(file_, "/mesh/connectivity", H5P_DEFAULT) <= 0) {
    hid_t mesh = H5Gopen2(file_, "/mesh", H5P_DEFAULT);
    ok = mesh >= 0;
    if (ok) write_connectivity(mesh);
    if (mesh >= 0) H5Gclose(mesh);
  }
  ok = ok && H5Fflush(file_, H5F_SCOPE_GLOBAL) >= 0;
  if (!ok) {
    H5Fclose(file_);
    file_ = -1;
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
  hid_t old = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
  if (old < 0) return false;
  // Each frame's datasets and their components per node.
  std::vector<std::pair<const char*, int>> names = {
      {"position", 3}, {"displacement", 3}, {"damage", 1}, {"strain_energy_density", 1}};
  if (write_velocity_) names.push_back({"velocity", 3});
  const hsize_t begin = static_cast<hsize_t>(state_.natural_begin()), count = static_cast<hsize_t>(state_.natural_count());
  const std::string tmp = path + ".salvage";
  hid_t fresh = create(tmp, fapl, resolved_scene);
  std::vector<double> slice;
  int kept = 0;
  for (;; ++kept) {
    const std::string name = frame_name(kept);
    // The frame's group, step and time, and its datasets with the right shape: readable on every rank?
    long long step = -1;
    double time = 0;
    hid_t g = H5Lexists(old, name.c_str(), H5P_DEFAULT) > 0 ? H5Gopen2(old, name.c_str(), H5P_DEFAULT) : -1;
    int ok = g >= 0;
    if (ok) {
      hid_t a = H5Aopen(g, "step", H5P_DEFAULT), b = H5Aopen(g, "time", H5P_DEFAULT);
      ok = a >= 0 && b >= 0 && H5Aread(a, H5T_NATIVE_LLONG, &step) >= 0 && H5Aread(b, H5T_NATIVE_DOUBLE, &time) >= 0 &&
           step <= resume_step;
      if (a >= 0) H5Aclose(a);
      if (b >= 0) H5Aclose(b);
    }
    for (std::size_t d = 0; ok && d < names.size(); ++d) {
      hid_t ds = H5Dopen2(g, names[d].first, H5P_DEFAULT);
      hid_t space = ds >= 0 ? H5Dget_space(ds) : -1;
      hsize_t dims[2] = {0, 0};
      const int rank = space >= 0 ? H5Sget_simple_extent_dims(space, dims, nullptr) : -1;
      const int bs = names[d].second;
      ok = rank == (bs == 1 ? 1 : 2) && dims[0] == static_cast<hsize_t>(domain_.global_nodes) &&
           (bs == 1 || dims[1] == 3);
      if (space >= 0) H5Sclose(space);
      if (ds >= 0) H5Dclose(ds);
    }
    int all = 0;
    MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, state_.comm());
    if (!all) {
      if (g >= 0) H5Gclose(g);
      break;
    }
    hid_t to = check_id(H5Gcreate2(fresh, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), name.c_str());
    scalar_attribute<long long>(to, "step", H5T_NATIVE_LLONG, step);
    scalar_attribute<double>(to, "time", H5T_NATIVE_DOUBLE, time);
    for (std::size_t d = 0; d < names.size(); ++d) {
      const int bs = names[d].second;
      hid_t ds = check_id(H5Dopen2(g, names[d].first, H5P_DEFAULT), names[d].first);
      hid_t filespace = check_id(H5Dget_space(ds), "H5Dget_space");
      hsize_t start[2] = {begin, 0}, counts[2] = {count, static_cast<hsize_t>(bs)};
      check_h5(H5Sselect_hyperslab(filespace, H5S_SELECT_SET, start, nullptr, counts, nullptr), "hyperslab");
      hid_t memspace = check_id(H5Screate_simple(bs == 1 ? 1 : 2, counts, nullptr), "memspace");
      hid_t dxpl = check_id(H5Pcreate(H5P_DATASET_XFER), "dxpl");
      check_h5(H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE), "H5Pset_dxpl_mpio");
      slice.resize(static_cast<std::size_t>(count) * bs);
      check_h5(H5Dread(ds, H5T_NATIVE_DOUBLE, memspace, filespace, dxpl, slice.data()), names[d].first);
      H5Pclose(dxpl);
      H5Sclose(memspace);
      H5Sclose(filespace);
      H5Dclose(ds);
      write_dataset(to, names[d].first, slice.data(), bs);
    }
    H5Gclose(to);
    H5Gclose(g);
    times_.push_back(time);
    steps_.push_back(step);
  }
  H5Fclose(old);
  check_h5(H5Fflush(fresh, H5F_SCOPE_GLOBAL), "H5Fflush");
  H5Fclose(fresh);
  char msg[512] = {0};
  if (domain_.rank == 0 && std::rename(tmp.c_str(), path.c_str()) != 0)
    std::snprintf(msg, sizeof msg, "cannot rename '%s' to '%s': %s", tmp.c_str(), path.c_str(), std::strerror(errno));
  MPI_Bcast(msg, sizeof msg, MPI_CHAR, 0, state_.comm());
  if (msg[0]) throw Error(msg);
  file_ = check_id(H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl), path.c_str());
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

FrameWriter::~FrameWriter() {
  if (file_ >= 0) H5Fclose(file_);
}

void FrameWriter::write_connectivity(hid_t mesh) {
  // One vertex cell per node, numbered in natural order: readers that build cells from the
  // topology (ParaView's Xdmf3 readers, meshio) then see every node.
  std::vector<std::int64_t> cells(static_cast<std::size_t>(state_.natural_count()));
  for (std::size_t k = 0; k < cells.size(); ++k) cells[k] = state_.natural_begin() + static_cast<std::int64_t>(k);
  write_dataset(mesh, "connectivity", cells.data(), 1, H5T_NATIVE_INT64);
}

void FrameWriter::write_dataset(hid_t group, const char* name, const void* slice, int bs, hid_t type) {
  const hsize_t n = static_cast<hsize_t>(domain_.global_nodes);
  hsize_t dims[2] = {n, static_cast<hsize_t>(bs)};
  hid_t filespace = check_id(H5Screate_simple(bs == 1 ? 1 : 2, dims, nullptr), "H5Screate_simple");
  hid_t dset = check_id(H5Dcreate2(group, name, type, filespace, H5P_DEFAULT,
                                   H5P_DEFAULT, H5P_DEFAULT), name);
  hsize_t start[2] = {static_cast<hsize_t>(state_.natural_begin()), 0};
  hsize_t count[2] = {static_cast<hsize_t>(state_.natural_count()), static_cast<hsize_t>(bs)};
  check_h5(H5Sselect_hyperslab(filespace, H5S_SELECT_SET, start, nullptr, count, nullptr), "hyperslab");
  hid_t memspace = check_id(H5Screate_simple(bs == 1 ? 1 : 2, count, nullptr), "memspace");
  hid_t dxpl = check_id(H5Pcreate(H5P_DATASET_XFER), "dxpl");
  check_h5(H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE), "H5Pset_dxpl_mpio");
  check_h5(H5Dwrite(dset, type, memspace, filespace, dxpl, slice), name);
  H5Pclose(dxpl);
  H5Sclose(memspace);
  H5Sclose(filespace);
  H5Dclose(dset);
}

void FrameWriter::write(std::int64_t step, double time, const double* u, const double* v,
                        const double* damage, const double* energy_density) {
  const int k = frames();
  const std::string name = frame_name(k);
  hid_t g = check_id(H5Gcreate2(file_, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), name.c_str());
  scalar_attribute<long long>(g, "step", H5T_NATIVE_LLONG, step);
  scalar_attribute<double>(g, "time", H5T_NATIVE_DOUBLE, time);
  const std::size_t n3 = 3 * static_cast<std::size_t>(domain_.owned);
  work_.resize(n3);
  for (std::size_t a = 0; a < n3; ++a) work_[a] = domain_.X[a] + u[a];
  write_dataset(g, "position", state_.to_natural(work_.data(), 3), 3);
  write_dataset(g, "displacement", state_.to_natural(u, 3), 3);
  if (write_velocity_) write_dataset(g, "velocity", state_.to_natural(v, 3), 3);
  write_dataset(g, "damage", state_.to_natural(damage, 1), 1);
  write_dataset(g, "strain_energy_density", state_.to_natural(energy_density, 1), 1);
  H5Gclose(g);
  check_h5(H5Fflush(file_, H5F_SCOPE_GLOBAL), "H5Fflush");
  times_.push_back(time);
  steps_.push_back(step);
  if (domain_.rank == 0) write_xdmf();
}

void FrameWriter::write_xdmf() const {
  const std::string h5 = stem_ + ".h5";
  const long long n = domain_.global_nodes;
  std::ostringstream x;
  x << std::setprecision(17);
  x << "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
    << "<Xdmf Version=\"3.0\">\n <Domain>\n"
    << "  <Grid Name=\"peridrive\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  auto item = [&](const std::string& path, int bs) {
    std::ostringstream s;
    s << "<DataItem Dimensions=\"" << n << (bs == 3 ? " 3" : "")
      << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5 << ":" << path << "</DataItem>";
    return s.str();
  };
  for (std::size_t k = 0; k < times_.size(); ++k) {
    const std::string f = frame_name(static_cast<int>(k));
    x << "   <Grid Name=\"frame" << k << "\" GridType=\"Uniform\">\n"
      << "    <Time Value=\"" << times_[k] << "\"/>\n"
      << "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n << "\" NodesPerElement=\"1\">"
      << "<DataItem Dimensions=\"" << n << "\" NumberType=\"Int\" Precision=\"8\" Format=\"HDF\">" << h5
      << ":/mesh/connectivity</DataItem></Topology>\n"
      << "    <Geometry GeometryType=\"XYZ\">" << item(f + "/position", 3) << "</Geometry>\n"
      << "    <Attribute Name=\"displacement\" AttributeType=\"Vector\" Center=\"Node\">" << item(f + "/displacement", 3) << "</Attribute>\n";
    if (write_velocity_)
      x << "    <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">" << item(f + "/velocity", 3) << "</Attribute>\n";
    x << "    <Attribute Name=\"damage\" AttributeType=\"Scalar\" Center=\"Node\">" << item(f + "/damage", 1) << "</Attribute>\n"
      << "    <Attribute Name=\"strain_energy_density\" AttributeType=\"Scalar\" Center=\"Node\">"
      << item(f + "/strain_energy_density", 1) << "</Attribute>\n"
      << "    <Attribute Name=\"body\" AttributeType=\"Scalar\" Center=\"Node\">" << item("/mesh/body", 1) << "</Attribute>\n"
      << "   </Grid>\n";
  }
  x << "  </Grid>\n </Domain>\n</Xdmf>\n";
  write_text_file(dir_ + "/" + stem_ + ".xdmf", x.str());
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
  if (!out_) throw Error("cannot write '" + path + "': " + std::strerror(errno));
  out_ << std::setprecision(12);
}

void SeriesWriter::write(const EnergyRow& r, const std::string& extra) {
  if (!active_) return;
  out_ << r.step << ',' << r.time << ',' << r.kinetic << ',' << r.strain << ',' << r.external_work
       << ',' << r.dissipated << ',' << r.total() << ',' << r.broken_bonds << (extra.empty() ? "" : ",")
       << extra << '\n';
  out_.flush();
}

}  // namespace peri
