// Fuzz target: the checkpoint reader (libFuzzer entry point; replay.cpp drives it from ctest).
// The input is written to a file and opened as a checkpoint: it must be read or refused with
// peri::InputError, never crash, hang or exhaust memory.
// With PERI_FUZZ_RESIGN=1 in the environment the header of an input of >= 512 bytes is rewritten
// to match the bytes after it (version 1, length, hash), so that mutated HDF5 data passes the
// checksum and reaches the HDF5-level checks and the HDF5 library itself (defence in depth: what
// a deliberately forged file could do).
#include <unistd.h>

#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "peri/io/checkpoint.hpp"
#include "peri/core/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string path = "/tmp/peri-fuzz-checkpoint-" + std::to_string(::getpid()) + ".h5";
  static const bool resign = std::getenv("PERI_FUZZ_RESIGN") != nullptr;
  std::vector<std::uint8_t> bytes(data, data + size);
  if (resign && size >= peri::kCheckpointHeaderBytes) {
    const std::size_t h = peri::kCheckpointHeaderBytes;
    char header[peri::kCheckpointHeaderBytes] = {0};
    std::snprintf(header, sizeof header, "peridrive checkpoint\nformat_version: 1\nfile_bytes: %zu\nfnv1a64: %016" PRIx64 "\n",
                  size, peri::fnv1a64(data + h, size - h));
    std::memcpy(bytes.data(), header, h);
  }
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return 0;
  std::fwrite(bytes.data(), 1, bytes.size(), f);
  std::fclose(f);
  try {
    const peri::Checkpoint c = peri::read_checkpoint(path);
    // Accepted: the reader's promises hold.
    if (c.displacement.size() != 3 * static_cast<std::size_t>(c.nodes) || c.broken.size() % 2 != 0) std::abort();
  } catch (const peri::InputError&) {
  }
  std::remove(path.c_str());
  return 0;
}
