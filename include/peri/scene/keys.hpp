// One allowed key of a scene map, as the reader checks it and --describe-keys documents it.
#pragma once
#include <vector>

namespace peri::scene_detail {

/// One allowed key of a map: its name, whether it must be given, and what it is (for the
/// "missing required key" message); and its documentation (scene/describe.hpp): SI unit, default
/// (what an absent key means) and meaning.
struct Key {
  const char* name;
  bool required = false;
  const char* what = "";
  const char* unit = "";
  const char* fallback = "";
  const char* doc = "";
};
using Keys = std::vector<Key>;

/// A box {min, max} (a lattice's breakable box, a network's box, the frames' region).
inline const Keys kBoxKeys = {
    {.name = "min", .required = true, .what = "lower corner [x, y, z], m", .unit = "m", .doc = "lower corner [x, y, z]"},
    {.name = "max", .required = true, .what = "upper corner [x, y, z], m", .unit = "m",
     .doc = "upper corner [x, y, z], >= min in every component (> min for a network's box)"},
};

}  // namespace peri::scene_detail
