// The built-in body kinds, one module each (this folder); the registry lists them
// (src/geometry/body_kinds.cpp).
#pragma once
#include "peri/scene/body_kind.hpp"

namespace peri::kinds {

BodyKind membrane_kind();
BodyKind solid_kind();
BodyKind lattice_kind();
BodyKind fiber_kind();
BodyKind sphere_kind();

/// The quadrature key of grid bodies (membranes, solids).
const scene_detail::Key& quadrature_key();

}  // namespace peri::kinds
