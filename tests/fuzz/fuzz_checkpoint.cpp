// Fuzz target: the checkpoint reader (libFuzzer entry point; replay.cpp drives it from ctest).
// The input is written to a file and opened as a checkpoint: it must be read or refused with
// peri::InputError, never crash, hang or exhaust memory.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "peri/checkpoint.hpp"
#include "peri/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string path = "/tmp/peri-fuzz-checkpoint-" + std::to_string(::getpid()) + ".h5";
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return 0;
  std::fwrite(data, 1, size, f);
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
