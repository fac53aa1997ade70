#include "peri/output.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <cstdlib>
#include <iomanip>
#include <iterator>
#include <sstream>

#include "peri/build_info.hpp"
#include "peri/error.hpp"

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
    if (reopen(path, fapl, resume_step)) {
      H5Pclose(fapl);
      if (domain_.rank == 0) write_xdmf();
      return;
    }
    if (domain_.rank == 0)
      std::fprintf(stderr, "peridrive: note: '%s' cannot be continued; starting it afresh at step %lld\n",
                   path.c_str(), static_cast<long long>(resume_step));
  }
  file_ = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  H5Pclose(fapl);
  if (file_ < 0) throw Error("cannot create HDF5 file '" + path + "'");
  string_attribute(file_, "peridrive_version", version());
  string_attribute(file_, "git_revision", git_revision());
  string_attribute(file_, "scene", resolved_scene);
  scalar_attribute<long long>(file_, "nodes", H5T_NATIVE_LLONG, domain.global_nodes);
  scalar_attribute<int>(file_, "ranks", H5T_NATIVE_INT, domain.ranks);
  hid_t mesh = check_id(H5Gcreate2(file_, "/mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "/mesh");
  write_dataset(mesh, "reference_position", state.to_natural(domain.X.data(), 3), 3);
  std::vector<double> body(domain.owned);
  for (std::int32_t i = 0; i < domain.owned; ++i) body[i] = domain.body[i];
  write_dataset(mesh, "body", state.to_natural(body.data(), 1), 1);
  write_dataset(mesh, "volume", state.to_natural(domain.volume.data(), 1), 1);
  H5Gclose(mesh);
  hid_t frames = check_id(H5Gcreate2(file_, "/frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "/frames");
  H5Gclose(frames);
  check_h5(H5Fflush(file_, H5F_SCOPE_GLOBAL), "H5Fflush");
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
    if (ok && step <= resume_step) {
      times_.push_back(time);
      steps_.push_back(step);
    } else {
      ok = H5Ldelete(file_, name.c_str(), H5P_DEFAULT) >= 0;  // a frame after the checkpoint, or partial
    }
  }
  if (frames >= 0) H5Gclose(frames);
  ok = ok && H5Fflush(file_, H5F_SCOPE_GLOBAL) >= 0;
  if (!ok) {
    H5Fclose(file_);
    file_ = -1;
    times_.clear();
    steps_.clear();
  }
  return ok;
}

FrameWriter::~FrameWriter() {
  if (file_ >= 0) H5Fclose(file_);
}

void FrameWriter::write_dataset(hid_t group, const char* name, const double* slice, int bs) {
  const hsize_t n = static_cast<hsize_t>(domain_.global_nodes);
  hsize_t dims[2] = {n, static_cast<hsize_t>(bs)};
  hid_t filespace = check_id(H5Screate_simple(bs == 1 ? 1 : 2, dims, nullptr), "H5Screate_simple");
  hid_t dset = check_id(H5Dcreate2(group, name, H5T_NATIVE_DOUBLE, filespace, H5P_DEFAULT,
                                   H5P_DEFAULT, H5P_DEFAULT), name);
  hsize_t start[2] = {static_cast<hsize_t>(state_.natural_begin()), 0};
  hsize_t count[2] = {static_cast<hsize_t>(state_.natural_count()), static_cast<hsize_t>(bs)};
  check_h5(H5Sselect_hyperslab(filespace, H5S_SELECT_SET, start, nullptr, count, nullptr), "hyperslab");
  hid_t memspace = check_id(H5Screate_simple(bs == 1 ? 1 : 2, count, nullptr), "memspace");
  hid_t dxpl = check_id(H5Pcreate(H5P_DATASET_XFER), "dxpl");
  check_h5(H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE), "H5Pset_dxpl_mpio");
  check_h5(H5Dwrite(dset, H5T_NATIVE_DOUBLE, memspace, filespace, dxpl, slice), name);
  H5Pclose(dxpl);
  H5Sclose(memspace);
  H5Sclose(filespace);
  H5Dclose(dset);
}

void FrameWriter::write(std::int64_t step, double time, const double* u, const double* v,
                        const double* damage) {
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
      << "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n << "\" NodesPerElement=\"1\"/>\n"
      << "    <Geometry GeometryType=\"XYZ\">" << item(f + "/position", 3) << "</Geometry>\n"
      << "    <Attribute Name=\"displacement\" AttributeType=\"Vector\" Center=\"Node\">" << item(f + "/displacement", 3) << "</Attribute>\n";
    if (write_velocity_)
      x << "    <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">" << item(f + "/velocity", 3) << "</Attribute>\n";
    x << "    <Attribute Name=\"damage\" AttributeType=\"Scalar\" Center=\"Node\">" << item(f + "/damage", 1) << "</Attribute>\n"
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
