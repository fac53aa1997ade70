#include "peri/io/run_dir.hpp"

#include <fcntl.h>
#include <hdf5.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <sstream>

#include "peri/core/error.hpp"
#include "peri/core/hdf5.hpp"
#include "peri/scene/scene.hpp"

namespace peri {
namespace {

/// `s` from `root` to every rank of `comm`. Collective.
void broadcast(std::string& s, int root, MPI_Comm comm) {
  long long n = static_cast<long long>(s.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, root, comm);
  s.resize(static_cast<std::size_t>(n));
  for (long long at = 0; at < n;) {  // in pieces that fit an int count
    const int piece = static_cast<int>(std::min<long long>(n - at, 1 << 30));
    MPI_Bcast(s.data() + at, piece, MPI_CHAR, root, comm);
    at += piece;
  }
}

bool regular_file(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

/// One line of text: control characters become spaces.
std::string one_line(std::string s) {
  for (char& ch : s)
    if (static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f) ch = ' ';
  return s;
}

/// The value of "key: value" in a lock file's text, or "".
std::string field(const std::string& text, const std::string& key) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key + ": ", 0) == 0) return line.substr(key.size() + 2);
  return "";
}

/// The scene `text` as check_restart compares it: resolved, with the parts a resume may change
/// (progress and checkpoint cadence) set alike. InputError if it is no valid scene.
std::string physics_of(const std::string& text, const std::string& where) {
  Scene s = parse_scene(text, where);
  s.output.progress_seconds = 0;
  s.output.checkpoint_every_steps = 0;
  s.output.checkpoint_every_seconds = 0;
  return emit_scene(s);
}

/// Where two resolved scenes first differ, as "line N is 'a' there and 'b' in <b_name>".
std::string first_difference(const std::string& a, const std::string& b, const std::string& b_name) {
  std::istringstream sa(a), sb(b);
  std::string la, lb;
  for (int line = 1;; ++line) {
    const bool ga = static_cast<bool>(std::getline(sa, la)), gb = static_cast<bool>(std::getline(sb, lb));
    if (!ga) la.clear();
    if (!gb) lb.clear();
    if (!ga || !gb || la != lb)
      return "resolved scene line " + std::to_string(line) + " is '" + la + "' there and '" + lb + "' in " + b_name;
  }
}

/// The resolved scene of an HDF5 file (frames.h5): its /scene dataset, or in files written before
/// the scene moved there, its root attribute "scene"; false if neither can be read.
bool hdf5_scene_record(const std::string& path, std::string& scene) {
  H5E_auto2_t func = nullptr;
  void* data = nullptr;
  H5Eget_auto2(H5E_DEFAULT, &func, &data);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // a damaged file is no record: no HDF5 error stack
  bool ok = false;
  {
    const H5Id file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    const bool as_dataset = file.ok() && H5Lexists(file.get(), "scene", H5P_DEFAULT) > 0;
    const H5Id object = !file.ok()  ? H5Id()
                        : as_dataset ? H5Id(H5Dopen2(file.get(), "scene", H5P_DEFAULT), H5Dclose)
                                     : H5Id(H5Aopen(file.get(), "scene", H5P_DEFAULT), H5Aclose);
    const H5Id type = !object.ok()  ? H5Id()
                      : as_dataset ? H5Id(H5Dget_type(object.get()), H5Tclose)
                                   : H5Id(H5Aget_type(object.get()), H5Tclose);
    if (type.ok() && H5Tget_class(type.get()) == H5T_STRING && H5Tis_variable_str(type.get()) == 0) {
      const std::size_t size = H5Tget_size(type.get());
      if (size > 0 && size <= kMaxSceneFileBytes) {
        std::string buf(size + 1, '\0');  // room for the terminator after a null-padded text
        const H5Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
        H5Tset_size(mem.get(), size + 1);
        H5Tset_cset(mem.get(), H5Tget_cset(type.get()));  // (no conversion between character sets)
        ok = (as_dataset ? H5Dread(object.get(), mem.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data())
                         : H5Aread(object.get(), mem.get(), buf.data())) >= 0;
        scene.assign(buf.c_str());  // up to the first NUL
      }
    }
  }
  H5Eset_auto2(H5E_DEFAULT, func, data);
  return ok;
}

}  // namespace

const std::vector<std::string>& run_file_names() {
  static const std::vector<std::string> names = {
      "scene.resolved.yaml", "frames.h5",         "frames.xdmf",         "series.csv",
      "tips.csv",            "summary.json",      "FAILED",              "checkpoint.h5",
      "checkpoint.prev.h5",  "checkpoint.h5.tmp", "frames.h5.salvage",   "scene.resolved.yaml.tmp",
      "frames.xdmf.tmp",     "series.csv.tmp",    "summary.json.tmp",    "FAILED.tmp",
      "quasistatic.csv",     "frames_surface.xdmf", "frames_surface.xdmf.tmp"};
  return names;
}

std::string read_input_file(const std::string& path, std::size_t limit, std::string& text) {
  // O_NONBLOCK: opening a FIFO with no writer returns at once instead of waiting for one.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK);
  if (fd < 0) return std::strerror(errno);
  struct stat st;
  std::string error;
  if (::fstat(fd, &st) != 0) error = std::strerror(errno);
  else if (S_ISDIR(st.st_mode)) error = "is a directory";
  else if (!S_ISREG(st.st_mode))
    error = std::string("not a regular file (") +
            (S_ISCHR(st.st_mode) ? "a character device" : S_ISBLK(st.st_mode) ? "a block device"
             : S_ISFIFO(st.st_mode) ? "a FIFO" : S_ISSOCK(st.st_mode) ? "a socket" : "a special file") + ")";
  const std::string too_large = "larger than " + std::to_string(limit >> 20) + " MiB";
  if (error.empty() && static_cast<unsigned long long>(st.st_size) > limit)
    error = too_large + " (" + std::to_string(static_cast<long long>(st.st_size)) + " bytes)";
  text.clear();
  char buf[1 << 16];
  while (error.empty()) {  // to the end, which a file that grows or a /proc file may not report in st_size
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) error = std::strerror(errno);
    if (n <= 0) break;
    if (text.size() + static_cast<std::size_t>(n) > limit) error = too_large;
    else text.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  if (!error.empty()) text.clear();
  return error;
}

OutputDirLock::OutputDirLock(const std::string& dir, const std::string& command, MPI_Comm comm) : dir_(dir) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::string error, warning;
  if (rank == 0) {
    error = acquire(command, warning);
    if (!warning.empty()) std::fprintf(stderr, "peridrive: warning: %s\n", warning.c_str());
    if (!error.empty()) release();  // no destructor runs for a constructor that throws
  }
  broadcast(error, 0, comm);
  if (!error.empty()) throw InputError(error);
}

std::string OutputDirLock::acquire(const std::string& command, std::string& warning) {
  std::string dir = dir_;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  // The directory and its missing parents, made one by one (outermost first) so that a run refused
  // later can remove exactly those it made.
  std::vector<std::string> missing;
  struct stat st;
  for (std::filesystem::path p = dir; !p.empty(); p = p.parent_path()) {
    if (::stat(p.c_str(), &st) == 0) {
      if (p == std::filesystem::path(dir) && !S_ISDIR(st.st_mode))
        return "output directory '" + dir_ + "' exists and is not a directory";
      break;
    }
    missing.push_back(p.string());
    if (p == p.parent_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (::mkdir(it->c_str(), 0777) == 0) created_.push_back(*it);
    else if (errno != EEXIST || ::stat(it->c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
      return "cannot create output directory '" + dir_ + "': " + std::strerror(errno);
  }
  path_ = dir + "/" + kLockFileName;
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int fd = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd < 0)
      return "cannot write in output directory '" + dir_ + "': " + std::strerror(errno) + " (creating " +
             kLockFileName + ")";
    int rc;
    while ((rc = ::flock(fd, LOCK_EX | LOCK_NB)) != 0 && errno == EINTR) {}
    if (rc != 0 && errno == EWOULDBLOCK) {
      char buf[4096];
      const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
      ::close(fd);
      const std::string text(buf, n > 0 ? static_cast<std::size_t>(n) : 0);
      const std::string pid = field(text, "pid"), host = field(text, "host");
      std::string holder = pid.empty() ? "its holder has written no name into " + path_
                                       : "pid " + pid + " on host " + host + ", started " + field(text, "started") +
                                             ", command: " + field(text, "command");
      return "output directory '" + dir_ + "' is in use by another run (" + holder +
             "); one run writes into a directory at a time: wait for it to end or choose another --out";
    }
    if (rc != 0) {
      // No flock on this file system: the run goes on without the lock.
      warning = "output directory '" + dir_ + "' cannot be locked (flock: " + std::strerror(errno) +
                "); running without the lock: make sure no other run writes into it";
      ::close(fd);
      ::unlink(path_.c_str());
      return "";
    }
    // Locked. A holder that released its lock removed the file first: a lock on an unlinked (or
    // replaced) file protects nothing, so it is taken again on the file now at the path.
    struct stat held, now;
    if (::fstat(fd, &held) != 0 || ::stat(path_.c_str(), &now) != 0 || held.st_dev != now.st_dev ||
        held.st_ino != now.st_ino) {
      ::close(fd);
      continue;
    }
    char host[256] = {0};
    ::gethostname(host, sizeof host - 1);
    char started[64] = {0};
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    ::localtime_r(&t, &tm);
    std::strftime(started, sizeof started, "%Y-%m-%d %H:%M:%S %z", &tm);
    const std::string text = "peridrive output directory lock (held while the file is flock'ed)\nhost: " +
                             one_line(host) + "\npid: " + std::to_string(::getpid()) + "\nstarted: " + started +
                             "\ncommand: " + one_line(command) + "\n";
    if (::ftruncate(fd, 0) != 0 ||
        ::pwrite(fd, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size())) {
      const std::string why = std::strerror(errno);
      ::unlink(path_.c_str());
      ::close(fd);
      return "cannot write in output directory '" + dir_ + "': " + why + " (writing " + kLockFileName + ")";
    }
    fd_ = fd;
    return "";
  }
  return "cannot lock output directory '" + dir_ + "': its lock file keeps being replaced";
}

OutputDirLock::~OutputDirLock() { release(); }

void OutputDirLock::release() {
  if (fd_ >= 0) {
    ::unlink(path_.c_str());  // before the release: a process that opened it then finds it replaced
    ::close(fd_);
    fd_ = -1;
  }
  for (auto it = created_.rbegin(); it != created_.rend(); ++it)
    if (::rmdir(it->c_str()) != 0) break;  // not empty: the run wrote into it
  created_.clear();
}

std::vector<std::string> check_resume_dir(const std::string& dir, const Checkpoint& c,
                                          const std::string& checkpoint_file, MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::string error;
  std::vector<std::string> later;
  if (rank == 0) {
    const std::string refused = "cannot resume into output directory '" + dir + "': ";
    const std::string advice =
        "; resume into that run's own directory, or into a new or empty one (--out)";
    const std::string theirs = "checkpoint '" + checkpoint_file + "'";
    try {
      const std::string want = physics_of(c.scene, checkpoint_file + ": scene");
      std::vector<std::string> held;
      for (const std::string& name : run_file_names())
        if (regular_file(dir + "/" + name)) held.push_back(name);
      int records = 0;
      // Each record of a scene: its file name and text (a file that cannot be read is no record,
      // except scene.resolved.yaml, which is written whole or not at all).
      auto compare = [&](const std::string& name, const std::string& text) {
        ++records;
        std::string mine;
        try {
          mine = physics_of(text, dir + "/" + name);
        } catch (const InputError& e) {
          error = refused + "its " + name + " is not a scene of a run (" + e.what() + ")" + advice;
          return;
        }
        if (mine != want)
          error = refused + "it holds another run: " + dir + "/" + name + ": " + first_difference(mine, want, theirs) +
                  advice;
      };
      std::error_code ec;
      const std::string resolved = dir + "/scene.resolved.yaml";
      if (regular_file(resolved)) {
        std::string text;
        const std::string why = read_input_file(resolved, kMaxSceneFileBytes, text);
        if (!why.empty()) error = refused + "cannot read " + resolved + ": " + why;
        else compare("scene.resolved.yaml", text);
      }
      std::string scene;
      if (error.empty() && regular_file(dir + "/frames.h5") && hdf5_scene_record(dir + "/frames.h5", scene))
        compare("frames.h5", scene);
      for (const char* name : {"checkpoint.h5", "checkpoint.prev.h5"}) {
        const std::string path = dir + "/" + name;
        if (!error.empty() || !regular_file(path) || std::filesystem::equivalent(path, checkpoint_file, ec)) continue;
        try {
          // (Its metadata: the arrays stay in the file.)
          const Checkpoint other = read_checkpoint_metadata(path, check_checkpoint_file(path, true));
          compare(name, other.scene);
          if (other.step > c.step) later.push_back(path);
        } catch (const Error&) {  // damaged or foreign: the resume's own checkpoints replace it
        }
      }
      if (error.empty() && records == 0 && !held.empty()) {
        std::string list;
        for (const std::string& name : held) list += (list.empty() ? "" : ", ") + name;
        error = refused + "it holds files of a run (" + list +
                ") but no readable record of that run's scene (scene.resolved.yaml, frames.h5 or a checkpoint) to "
                "show that it is the checkpoint's" + advice;
      }
    } catch (const std::exception& e) {
      if (error.empty()) error = refused + e.what();
    }
  }
  broadcast(error, 0, comm);
  if (!error.empty()) throw InputError(error);
  return later;
}

}  // namespace peri
