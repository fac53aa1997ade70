// Run directories: one writer per output directory (a lock held by rank 0 for the whole run), a
// resume kept to a directory that holds the checkpoint's own run, and input files read with
// limits (regular files of bounded size: no directory, device or FIFO is read).
#pragma once
#include <mpi.h>

#include <cstddef>
#include <string>
#include <vector>

#include "peri/io/checkpoint.hpp"

namespace peri {

/// Largest scene file read (and largest scene.resolved.yaml compared on resume).
inline constexpr std::size_t kMaxSceneFileBytes = 64u << 20;

/// Name of the lock file in an output directory.
inline constexpr const char* kLockFileName = ".peridrive.lock";

/// Every file a run writes in its output directory, temporaries included (simulation.cpp,
/// output.cpp and checkpoint.cpp name them). A fresh run removes them all before it writes.
const std::vector<std::string>& run_file_names();

/// Read the regular file `path` whole into `text` if it holds at most `limit` bytes. Returns ""
/// on success, else what is wrong: the system's error text, "is a directory", "not a regular
/// file (a character device)" and the like, or "larger than ... MiB". Never blocks on a FIFO and
/// never reads a device. Local to the calling process.
std::string read_input_file(const std::string& path, std::size_t limit, std::string& text);

/// The output directory's lock, taken before anything in the directory is touched and held until
/// destruction (the end of the run). Collective: rank 0 creates the directory (and missing
/// parents) and holds an exclusive flock on DIR/.peridrive.lock, which names its holder (host,
/// pid, start time, command line). InputError on every rank, naming the directory, when it cannot
/// be created or written in, and naming the holder when another live process holds the lock. A
/// lock file left by a dead process is taken over silently (the kernel released its flock). On a
/// file system without flock (some NFS and Lustre mounts) the run goes on unlocked after a
/// warning on stderr.
class OutputDirLock {
 public:
  OutputDirLock(const std::string& dir, const std::string& command, MPI_Comm comm);
  /// Rank 0: removes the lock file, releases the lock, and removes the directories it created if
  /// they are still empty (a run refused during setup leaves nothing behind).
  ~OutputDirLock();
  OutputDirLock(const OutputDirLock&) = delete;
  OutputDirLock& operator=(const OutputDirLock&) = delete;

 private:
  std::string acquire(const std::string& command, std::string& warning);  // rank 0; "" or the error
  void release();  // rank 0

  std::string dir_, path_;
  int fd_ = -1;
  std::vector<std::string> created_;  // directories made here, outermost first
};

/// Whether `dir` may take the outputs of a run resumed from `c` (read from `checkpoint_file`): a
/// directory that holds none of run_file_names() (new, empty, or only other files), or one whose
/// every record of a scene (scene.resolved.yaml, the scene dataset of frames.h5, checkpoint.h5,
/// checkpoint.prev.h5) is the checkpoint's scene up to output.progress_seconds and
/// output.checkpoint_every_* (the parts a resume may change). An unreadable frames.h5 or
/// checkpoint is no record (the resume replaces it). Anything else raises InputError on every
/// rank naming the directory and the file that differs, before anything in `dir` is changed.
/// Returns, on rank 0, the checkpoints in `dir` of a later step than c's: they describe steps whose
/// frames the resume drops, and go once its outputs are open. Checked on rank 0, verdict broadcast.
/// Collective.
std::vector<std::string> check_resume_dir(const std::string& dir, const Checkpoint& c,
                                          const std::string& checkpoint_file, MPI_Comm comm);

}  // namespace peri
