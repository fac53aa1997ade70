// Build provenance, written beside every output (STYLE: provenance).
#pragma once

namespace peri {
const char* git_revision();  ///< `git describe --always --dirty` when the binary was built
const char* version();       ///< project version
}  // namespace peri
