// The readers of the scene's sections: from the located YAML tree (overrides applied) to the
// Scene structs, every value validated where it is read (located_yaml.hpp's conventions).
#pragma once
#include <string>

#include "peri/scene/located_yaml.hpp"

namespace peri::scene_detail {

/// Body `name` of the scene (bodies.<name>), with the materials read before it (read_body.cpp).
Body read_body(const std::string& name, const Value& v, const std::vector<Material>& materials);

/// The scene in `root`, validated.
Scene read_scene(const Context& ctx, const YAML::Node& root, const std::string& file);

}  // namespace peri::scene_detail
