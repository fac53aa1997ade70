#include "peri/loads/boundaries.hpp"

namespace peri {

Boundaries::Boundaries(const Scene& scene, std::vector<int> node_boundary)
    : scene_(scene), boundary_(std::move(node_boundary)) {
  // Boundary nodes' per-step figures (increment, old velocity, force at the start of the step)
  // are kept for those nodes only: slot s of slot_ for node i, 3 components each.
  slot_.assign(boundary_.size(), -1);
  for (std::size_t i = 0; i < boundary_.size(); ++i)
    if (boundary_[i] >= 0) {
      slot_[i] = static_cast<std::int32_t>(rows_.size());
      rows_.push_back(static_cast<std::int32_t>(i));
    }
  du_.assign(3 * rows_.size(), 0.0);
  v_old_ = du_;
  prev_force_ = du_;
  prev_viscous_ = du_;
  for (const Boundary& b : scene.boundaries) active_.push_back({b.velocity, b.ramp_time});
}

void Boundaries::apply_initial(double* v) const {
  for (std::int32_t i : rows_) {
    const Boundary& b = scene_.boundaries[boundary_[i]];
    for (int c = 0; c < 3; ++c)
      if (b.components[c]) v[3 * i + c] = b.velocity[c] * ramp(0.0, b.ramp_time);
  }
}

void Boundaries::start_stage(const Stage& stage) {
  for (std::size_t b = 0; b < scene_.boundaries.size(); ++b)
    active_[b] = {scene_.boundaries[b].velocity, scene_.boundaries[b].ramp_time};
  for (const BoundaryValue& bv : stage.boundary_velocity)
    for (std::size_t b = 0; b < scene_.boundaries.size(); ++b)
      if (scene_.boundaries[b].name == bv.boundary) active_[b] = {bv.value, 0.0};
}

void Boundaries::quasistatic_targets(const Stage& stage, const Domain& domain, std::vector<std::uint8_t>& constrained,
                                     std::vector<double>& increment) const {
  for (std::int32_t i : rows_) {
    const Boundary& b = scene_.boundaries[boundary_[i]];
    for (int c = 0; c < 3; ++c) {
      if (!b.components[c]) continue;
      const std::size_t k = 3 * static_cast<std::size_t>(i) + c;
      constrained[k] = 1;
      for (const BoundaryValue& bv : stage.displacements)
        if (bv.boundary == b.name) increment[k] = bv.value[c];
      for (int d = 0; d < 3; ++d)
        increment[k] += stage.displacement_gradient[3 * c + d] * (domain.X[3 * i + d] - scene_.initial.center[d]);
    }
  }
}

}  // namespace peri
