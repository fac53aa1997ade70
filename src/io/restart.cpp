#include "peri/io/restart.hpp"

#include <unistd.h>
#ifdef __linux__
#include <sys/prctl.h>
#endif

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>

#include "peri/core/collective.hpp"
#include "peri/core/error.hpp"

namespace peri {
namespace {

volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void on_stop_signal(int sig) {
  if (g_stop_signal != 0) {  // second signal: the user insists, end now
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  g_stop_signal = sig;
}

}  // namespace

void install_stop_handlers() {
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  // A file grown past the process's size limit (ulimit -f) fails its write with EFBIG, which the
  // writers report, instead of killing the rank with SIGXFSZ mid-write.
  std::signal(SIGXFSZ, SIG_IGN);
}

int stop_signal() { return g_stop_signal; }

void end_with_launcher() {
#ifdef __linux__
  bool launched = false;
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    launched = launched || std::getenv(v) != nullptr;
  if (!launched) return;
  // The signal comes when the parent dies after this call; a parent that died just before it
  // shows as a changed parent pid (the orphan was adopted by init or a subreaper).
  const pid_t parent = getppid();
  if (prctl(PR_SET_PDEATHSIG, SIGKILL) == 0 && getppid() != parent) std::raise(SIGKILL);
#endif
}

std::vector<std::int64_t> natural_blocks(std::int64_t natural_begin, std::int64_t nodes, MPI_Comm comm) {
  int ranks = 1;
  MPI_Comm_size(comm, &ranks);
  std::vector<std::int64_t> blocks(static_cast<std::size_t>(ranks) + 1, nodes);
  long long mine = natural_begin;
  std::vector<long long> all(ranks);
  MPI_Allgather(&mine, 1, MPI_LONG_LONG, all.data(), 1, MPI_LONG_LONG, comm);
  for (int r = 0; r < ranks; ++r) blocks[r] = all[r];
  return blocks;
}

int natural_block_of(const std::vector<std::int64_t>& blocks, std::int64_t id) {
  // The last rank whose block starts at or before id (empty blocks share a start: the last wins).
  const auto it = std::upper_bound(blocks.begin(), blocks.end() - 1, id);
  return static_cast<int>(it - blocks.begin()) - 1;
}

namespace {

/// Rows of `width` values, each sent to the rank of natural_block_of(its key); returns the rows
/// received. Collective (one all-to-all of counts, one of rows).
template <class T>
std::vector<T> rows_to_blocks(const std::vector<T>& rows, std::size_t width, const std::vector<std::int64_t>& blocks,
                              MPI_Datatype type, MPI_Comm comm) {
  int ranks = 1;
  MPI_Comm_size(comm, &ranks);
  const std::size_t n = rows.size() / width;
  std::vector<int> dest(n);
  std::vector<long long> send(ranks, 0), recv(ranks, 0);
  for (std::size_t k = 0; k < n; ++k) {
    dest[k] = natural_block_of(blocks, static_cast<std::int64_t>(rows[k * width]));
    send[dest[k]] += static_cast<long long>(width);
  }
  MPI_Alltoall(send.data(), 1, MPI_LONG_LONG, recv.data(), 1, MPI_LONG_LONG, comm);
  std::vector<int> sc(ranks), sd(ranks), rc(ranks), rd(ranks);
  long long st = 0, rt = 0;
  for (int r = 0; r < ranks; ++r) {
    sd[r] = static_cast<int>(st);
    rd[r] = static_cast<int>(rt);
    sc[r] = static_cast<int>(send[r]);
    rc[r] = static_cast<int>(recv[r]);
    st += send[r];
    rt += recv[r];
  }
  // (Counts are int in MPI: more than 2^31 values per rank would need a chunked exchange.)
  long long too_many = st > INT32_MAX || rt > INT32_MAX, any = 0;
  MPI_Allreduce(&too_many, &any, 1, MPI_LONG_LONG, MPI_MAX, comm);
  if (any) throw Error("checkpoint: more than 2^31 bond values on one rank");
  std::vector<T> packed(rows.size()), out(static_cast<std::size_t>(rt));
  std::vector<long long> at(sd.begin(), sd.end());
  for (std::size_t k = 0; k < n; ++k) {
    std::copy(rows.begin() + k * width, rows.begin() + (k + 1) * width, packed.begin() + at[dest[k]]);
    at[dest[k]] += static_cast<long long>(width);
  }
  MPI_Alltoallv(packed.data(), sc.data(), sd.data(), type, out.data(), rc.data(), rd.data(), type, comm);
  return out;
}

/// Sort rows of `width` values by their first two.
template <class T>
void sort_rows(std::vector<T>& rows, std::size_t width) {
  const std::size_t n = rows.size() / width;
  std::vector<std::size_t> order(n);
  for (std::size_t k = 0; k < n; ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::make_pair(rows[a * width], rows[a * width + 1]) < std::make_pair(rows[b * width], rows[b * width + 1]);
  });
  std::vector<T> sorted(rows.size());
  for (std::size_t k = 0; k < n; ++k)
    std::copy(rows.begin() + order[k] * width, rows.begin() + (order[k] + 1) * width, sorted.begin() + k * width);
  rows.swap(sorted);
}

}  // namespace

std::vector<std::int64_t> broken_pairs_of_block(const Domain& d, const std::vector<std::int64_t>& blocks,
                                                MPI_Comm comm) {
  // Each broken bond is seen from both ends; the end with the lower natural id reports it.
  std::vector<std::int64_t> mine;
  for (std::int32_t r = 0; r < d.owned; ++r)
    for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b)
      if ((d.bonds.broken[b] & kBrokenFlag) && d.natural[r] < d.natural[d.bonds.neighbor[b]])
        mine.insert(mine.end(), {d.natural[r], d.natural[d.bonds.neighbor[b]]});
  std::vector<std::int64_t> pairs = rows_to_blocks(mine, 2, blocks, MPI_INT64_T, comm);
  sort_rows(pairs, 2);
  return pairs;
}

// This rank's bonds whose history is not all zero: rows (natural i, natural j, the values).
static std::vector<double> own_history_rows(const Domain& d) {
  const int s = d.bonds.history_stride;
  std::vector<double> mine;
  for (std::int32_t r = 0; r < d.owned; ++r)
    for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b) {
      const double* h = d.bonds.history.data() + b * s;
      if (std::all_of(h, h + s, [](double x) { return x == 0.0; })) continue;
      mine.push_back(static_cast<double>(d.natural[r]));
      mine.push_back(static_cast<double>(d.natural[d.bonds.neighbor[b]]));
      mine.insert(mine.end(), h, h + s);
    }
  return mine;
}

std::vector<double> history_rows_of_block(const Domain& d, const std::vector<std::int64_t>& blocks, MPI_Comm comm) {
  const int s = d.bonds.history_stride;
  const std::vector<double> mine = own_history_rows(d);
  std::vector<double> rows = rows_to_blocks(mine, 2 + static_cast<std::size_t>(s), blocks, MPI_DOUBLE, comm);
  sort_rows(rows, 2 + static_cast<std::size_t>(s));
  return rows;
}

std::int64_t apply_broken_pairs(Domain& d, const std::vector<std::int64_t>& pairs) {
  const std::size_t np = pairs.size() / 2;
  const auto less = [&](std::size_t k, std::pair<std::int64_t, std::int64_t> key) {
    return pairs[2 * k] < key.first || (pairs[2 * k] == key.first && pairs[2 * k + 1] < key.second);
  };
  std::int64_t found = 0;
  for (std::int32_t r = 0; r < d.owned; ++r) {
    const std::int64_t i = d.natural[r];
    for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b) {
      const std::int64_t j = d.natural[d.bonds.neighbor[b]];
      const std::pair<std::int64_t, std::int64_t> key{std::min(i, j), std::max(i, j)};
      std::size_t lo = 0, hi = np;  // first pair not less than key
      while (lo < hi) {
        const std::size_t mid = lo + (hi - lo) / 2;
        if (less(mid, key)) lo = mid + 1;
        else hi = mid;
      }
      const bool hit = lo < np && pairs[2 * lo] == key.first && pairs[2 * lo + 1] == key.second;
      // Bit 0 from the file; a lattice's other bits (cut by a pre-crack, unbreakable) are the
      // setup's, which knows them from the scene.
      d.bonds.broken[b] = static_cast<std::uint8_t>((d.bonds.broken[b] & ~kBrokenFlag) | (hit ? kBrokenFlag : 0));
      found += hit;
    }
  }
  d.bonds.summarize_rows();
  return found;
}

std::vector<double> gather_history_to_root(const Domain& d, MPI_Comm comm) {
  const int s = d.bonds.history_stride;
  const std::vector<double> mine = own_history_rows(d);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &ranks);
  const long long n = static_cast<long long>(mine.size());
  std::vector<long long> counts(ranks);
  MPI_Gather(&n, 1, MPI_LONG_LONG, counts.data(), 1, MPI_LONG_LONG, 0, comm);
  std::vector<int> c32(ranks), displs(ranks, 0);
  long long total = 0;
  for (int r = 0; r < ranks; ++r) {
    if (rank == 0 && total + counts[r] > (1ll << 31) - 1) throw Error("too much bond history for one checkpoint gather");
    c32[r] = static_cast<int>(counts[r]);
    displs[r] = static_cast<int>(total);
    total += counts[r];
  }
  std::vector<double> all(rank == 0 ? total : 0);
  MPI_Gatherv(mine.data(), static_cast<int>(n), MPI_DOUBLE, all.data(), c32.data(), displs.data(), MPI_DOUBLE, 0, comm);
  if (rank != 0) return all;
  const std::size_t width = 2 + static_cast<std::size_t>(s), rows = all.size() / width;
  std::vector<std::size_t> order(rows);
  for (std::size_t k = 0; k < rows; ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::make_pair(all[a * width], all[a * width + 1]) < std::make_pair(all[b * width], all[b * width + 1]);
  });
  std::vector<double> sorted;
  sorted.reserve(all.size());
  for (std::size_t k : order) sorted.insert(sorted.end(), all.begin() + k * width, all.begin() + (k + 1) * width);
  return sorted;
}

std::int64_t apply_history(Domain& d, const std::vector<double>& rows) {
  const int s = d.bonds.history_stride;
  const std::size_t width = 2 + static_cast<std::size_t>(s);
  if (rows.size() % width != 0)
    throw InputError("checkpoint: the bond history holds " + std::to_string(rows.size()) +
                     " values, not whole rows of (i, j) and " + std::to_string(s) + " values");
  std::fill(d.bonds.history.begin(), d.bonds.history.end(), 0.0);
  const std::size_t n = rows.size() / width;
  std::int64_t used = 0;
  for (std::int32_t r = 0; r < d.owned; ++r) {
    const double i = static_cast<double>(d.natural[r]);
    // This row's entries: a range of the sorted rows.
    std::size_t lo = 0, hi = n;
    while (lo < hi) {
      const std::size_t mid = lo + (hi - lo) / 2;
      if (rows[mid * width] < i) lo = mid + 1;
      else hi = mid;
    }
    for (std::size_t k = lo; k < n && rows[k * width] == i; ++k) {
      const double j = rows[k * width + 1];
      for (std::int64_t b = d.bonds.offsets[r]; b < d.bonds.offsets[r + 1]; ++b)
        if (static_cast<double>(d.natural[d.bonds.neighbor[b]]) == j) {
          std::copy(rows.begin() + k * width + 2, rows.begin() + (k + 1) * width, d.bonds.history.begin() + b * s);
          ++used;
          break;
        }
    }
  }
  return used;
}

std::uint64_t ownership_hash(const Domain& d) {
  return fnv1a64(d.natural.data(), sizeof(std::int64_t) * static_cast<std::size_t>(d.owned));
}

std::uint64_t reference_geometry_hash(const Domain& d, MPI_Comm comm) {
  // Per node a word-wise mix (a multiply and two shifts per 64-bit word: cheap at 10^8 nodes) of
  // its natural id and the bits of X, Y, Z and its measure; the nodes' values summed.
  const auto mix = [](std::uint64_t h, std::uint64_t word) {
    h = (h ^ word) * 0x9e3779b97f4a7c15ull;
    return h ^ (h >> 29);
  };
  std::uint64_t mine = 0, all = 0;
  for (std::int32_t l = 0; l < d.owned; ++l) {
    const std::size_t at = 3 * static_cast<std::size_t>(l);
    const double node[4] = {d.X[at], d.X[at + 1], d.X[at + 2], d.volume[l]};
    std::uint64_t h = mix(0x243f6a8885a308d3ull, static_cast<std::uint64_t>(d.natural[l]));
    for (const double v : node) {
      std::uint64_t bits = 0;
      std::memcpy(&bits, &v, sizeof bits);
      h = mix(h, bits);
    }
    h *= 0xbf58476d1ce4e5b9ull;  // (a finalizer, so that the sum mixes every bit)
    mine += h ^ (h >> 31);       // (modulo 2^64: the same sum in any order)
  }
  MPI_Allreduce(&mine, &all, 1, MPI_UINT64_T, MPI_SUM, comm);
  return all;
}

std::shared_ptr<const Checkpoint> load_checkpoint(const std::string& path, MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  const auto verdict = [&](const std::function<void()>& work) {
    std::string error;
    try {
      work();
    } catch (const Error& e) {
      error = e.what();
    } catch (const std::exception& e) {  // e.g. std::bad_alloc
      error = "checkpoint '" + path + "': cannot be read: " + e.what();
    }
    error = agree_on_message(error, comm);
    if (!error.empty()) throw InputError(error);
  };
  // First the bytes: every rank checks the header and the length of the file it sees, rank 0
  // alone the hash (streamed: no rank holds the file). Only then does HDF5 parse anything.
  std::uint64_t size = 0;
  verdict([&] { size = check_checkpoint_file(path, rank == 0); });
  std::shared_ptr<Checkpoint> c;
  verdict([&] { c = std::make_shared<Checkpoint>(read_checkpoint_metadata(path, size)); });
  return c;
}

void store_checkpoint(const std::string& path, const Checkpoint& c, MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::string error;
  try {
    write_checkpoint(path, c, comm);  // collective: a failure is thrown on every rank alike
  } catch (const std::exception& e) {
    error = e.what();
    if (rank == 0) {
      // The previous checkpoint stays current; the partial one goes (it would hold the space).
      std::remove((path + ".tmp").c_str());
      const std::string dir = std::filesystem::path(path).parent_path().string();
      const double free = free_bytes(dir.empty() ? "." : dir);
      if (free >= 0)
        error += "; the file system holding it has " + std::to_string(static_cast<long long>(free)) +
                 " bytes free; the previous checkpoint, if any, is kept";
    }
  }
  const std::string verdict = agree_on_message(error, comm);
  if (!verdict.empty()) throw RuntimeFailure(verdict);
}

std::string resolve_resume_path(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_directory(path, ec)) return path;
  const std::string current = path + "/checkpoint.h5";
  if (std::filesystem::exists(current, ec)) return current;
  const std::string prev = previous_checkpoint_path(current);
  if (std::filesystem::exists(prev, ec)) return prev;
  return current;  // read_checkpoint reports that it does not exist
}

}  // namespace peri
