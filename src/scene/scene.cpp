// The Scene's own lookups. Reading a scene: document.cpp (loading), overrides.cpp (--set),
// readers.cpp (validation into these structs) on located_yaml.hpp and schema.hpp; writing it:
// emit.cpp.
#include "peri/scene/scene.hpp"

#include <algorithm>
#include <cmath>

#include "peri/scene/located_yaml.hpp"

namespace peri {

using scene_detail::join;

const Material& Scene::material(const std::string& material_name) const {
  const int i = material_index(material_name);
  if (i < 0) {
    std::vector<std::string> defined;
    for (const Material& m : materials) defined.push_back(m.name);
    throw InputError("no material named '" + material_name + "'; defined: " + join(defined));
  }
  return materials[static_cast<std::size_t>(i)];
}

/// Position of the material in `materials`, or -1 if there is none of that name.
int Scene::material_index(const std::string& material_name) const {
  for (std::size_t i = 0; i < materials.size(); ++i)
    if (materials[i].name == material_name) return static_cast<int>(i);
  return -1;
}

double Crack::slit_distance(const double* x) const {
  double ab[3], ax[3], t = 0, len2 = 0;
  for (int c = 0; c < 3; ++c) {
    ab[c] = to[c] - from[c];
    ax[c] = x[c] - from[c];
    t += ax[c] * ab[c];
    len2 += ab[c] * ab[c];
  }
  t = len2 > 0 ? std::clamp(t / len2, 0.0, 1.0) : 0.0;
  double d2 = 0;
  for (int c = 0; c < 3; ++c) d2 += (ax[c] - t * ab[c]) * (ax[c] - t * ab[c]);
  return std::sqrt(d2);
}

bool Scene::released_later(const std::string& crack) const {
  for (const Stage& st : stages)
    for (const std::string& c : st.cracks)
      if (c == crack) return true;
  return false;
}

}  // namespace peri
