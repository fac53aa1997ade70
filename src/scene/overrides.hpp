// The --set overrides: KEY=VALUE applied to the scene's YAML tree before validation, list entries
// addressed by index or by name; every key path an override sets is recorded in the Context, so
// that a message about its value reads "--set" instead of a file line.
#pragma once
#include "peri/scene/located_yaml.hpp"

namespace peri::scene_detail {

/// Applies one override to the document tree and records the key paths it set.
void apply_override(YAML::Node& root, const Override& o, Context& ctx);
/// The offset of the first byte of `text` that is not well-formed UTF-8, or npos (document.cpp).
std::size_t first_bad_utf8(const std::string& text);

}  // namespace peri::scene_detail
