// The checks every bond law of the registry must pass (tests/test_laws.cpp runs them on each
// built-in law, tests/test_linear_spring.cpp on a law defined in that test alone):
//  - the SIMD accelerator and the portable walk give the same bits (forces, energies, flags,
//    tallies), on a membrane grid (runs, boxes, strided and mirrored runs, the rest), a solid
//    block, and irregular ones (a jittered sheet mesh, a jittered point cloud: free rows, which also
//    match the same bonds with family patterns to round-off), intact and breaking;
//  - the coefficient is the energy's gradient, the slope the coefficient's derivative, the SNES
//    tangent's block row the derivative of the forces;
//  - calibration: a small homogeneous strain of a finely resolved body stores the energy of the
//    continuum with the moduli the law reports.
// Shapes a law's scene keys do not accept (a conical influence, eq. 29's linear lambda_0, a kind of
// body) are skipped; each check fails if no shape at all was tested.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "peri/bonds/bonds.hpp"
#include "peri/core/error.hpp"
#include "peri/kernels/forces.hpp"
#include "peri/kernels/tangent.hpp"
#include "peri/models/model.hpp"
#include "peri/partition/domain.hpp"
#include "peri/partition/partition.hpp"
#include "peri/scene/scene.hpp"
#include "jittered_nodes.hpp"

namespace peri::law_checks {

/// A material of a law (the inside of a YAML flow map), with the shapes to test it in.
struct Sample {
  std::string law;       ///< the registry's name of the law the material calibrates to
  std::string material;  ///< the law's keys; critical values break bonds at strains of about 0.5%
  std::string linear;    ///< critical_stretch_at_horizon for eq. (29)'s linear lambda_0 ("": none)
};

/// Irregular node sets of the grids' sizes (spacing 1 mm): a 20 x 15 sheet of nodes each moved by
/// up to 0.3 spacings, two triangles per square, and a 16 x 17 x 6 block of points moved likewise
/// (jittered_nodes.hpp). Their rows have no family pattern (FamilyPatterns' free rows).
inline std::string jittered_file(bool solid) {
  return solid ? fixtures::write_jittered_cloud("peri_law_checks_cloud.csv", 16, 17, 6, 0.3, 3)
               : fixtures::write_jittered_sheet("peri_law_checks_sheet.msh", 20, 15, 0.3, 3);
}

/// The sample's scene: a membrane grid sheet or a solid grid block, or (`irregular`) the jittered
/// sheet mesh (whole weights) or point cloud (partial-volume weights) of the same size and spacing.
inline std::string scene_text(const std::string& material, bool solid, bool irregular = false) {
  std::string body;
  if (irregular)
    body = solid ? "  b: {kind: solid, material: m, points: \"" + jittered_file(true) +
                       "\", spacing: 0.001, horizon: 0.003015}\n"
                 : "  s: {material: m, mesh: \"" + jittered_file(false) + "\", thickness: 0.0005, spacing: 0.001}\n";
  else
    body = solid ? "  b: {kind: solid, material: m, origin: [0, 0, 0], size: [0.016, 0.017, 0.006], spacing: 0.001, "
                   "horizon: 0.003015, quadrature: taper}\n"
                 : "  s: {material: m, origin: [0, 0, 0], size: [0.020, 0.015], thickness: 0.0005, spacing: 0.001, "
                   "quadrature: partial_area}\n";
  return "name: law-test\nmaterials:\n  m: {" + material + "}\nbodies:\n" + body + "stages:\n  - {name: r, steps: 1}\n";
}

/// The material with the variant's shape: conical influence, linear lambda_0 (if the sample has one).
inline std::string variant_material(const Sample& s, bool conical, bool linear) {
  std::string material = s.material;
  if (conical) material += ", influence: conical";
  if (linear) material += ", critical_stretch_at_horizon: " + s.linear;
  return material;
}

/// A one-body scene on one rank: nodes, the domain of all of them, the body's law.
struct Body {
  Nodes nodes;
  Domain d;
  BondLaw law;
  std::vector<std::int32_t> rows;
  Body(const std::string& material, bool solid, bool irregular = false) {
    const Scene scene = parse_scene(scene_text(material, solid, irregular), "law-test");
    nodes = discretize(scene);
    law = calibrate(scene.materials[0], nodes.bodies[0], "law-test");
    const CellList cells(nodes, reach(nodes.bodies[0]));
    d = build_domain(scene, nodes, cells, partition_from_parts(nodes, std::vector<int>(nodes.size(), 0), 1), 0);
    for (std::int32_t i = 0; i < d.owned; ++i) rows.push_back(i);
  }
  BondView view(const double* x, std::uint8_t* broken) const {
    return BondView{d.X.data(), nullptr, d.volume.data(), d.bonds.offsets.data(), d.bonds.neighbor.data(),
                    broken, &d.bonds.patterns, x, d.local()};
  }
};

/// The body, or nullptr where the law's scene keys or body kinds refuse this shape.
inline std::unique_ptr<Body> body_if_accepted(const std::string& material, bool solid, bool irregular = false) {
  try {
    return std::make_unique<Body>(material, solid, irregular);
  } catch (const InputError&) {
    return nullptr;
  }
}

// Random displacements (strains up to about 1%: bonds break), then larger ones on the damaged
// state; each call by the accelerator (entry.forces) and the portable walk (entry.portable_forces)
// from the same flags: forces, energy density, flags and tallies the same bits.
inline void simd_and_portable_loops_give_the_same_bits(const Sample& s) {
  int tested = 0, irregular_tested = 0;
  for (int variant = 0; variant < 16; ++variant) {
    const bool solid = variant & 1, conical = variant & 2, linear = variant & 4, irregular = variant & 8;
    if (linear && s.linear.empty()) continue;
    const std::unique_ptr<Body> body = body_if_accepted(variant_material(s, conical, linear), solid, irregular);
    if (!body) continue;
    ++tested;
    ASSERT_EQ(body->law.name(), s.law);
    const Domain& d = body->d;
    irregular_tested += irregular;
    if (irregular) {  // every row free (no family pattern), within 10 bytes per bond
      EXPECT_EQ(d.bonds.patterns.patterns(), 0) << "variant " << variant;
      EXPECT_EQ(d.bonds.patterns.free_weight.empty(), !solid) << "variant " << variant;
      EXPECT_LE(d.bonds.bytes_per_bond(), 10.0) << "variant " << variant;
    }
    const std::size_t n = static_cast<std::size_t>(d.local());
    std::mt19937 rng(11 + variant);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    std::vector<double> u(3 * n), x(3 * n);
    std::vector<std::uint8_t> flags_fast(d.bonds.broken.size(), 0), flags_walk(flags_fast);
    const RowBlocks plan_fast = plan_rows(body->view(x.data(), flags_fast.data()), body->rows.data(), body->rows.size());
    const RowBlocks plan_walk = plan_rows(body->view(x.data(), flags_walk.data()), body->rows.data(), body->rows.size());
    std::int64_t broken = 0;
    for (int call = 0; call < 4; ++call) {
      const double amplitude = call < 2 ? 4e-6 : 1e-5;
      for (double& c : u) c = amplitude * U(rng);
      current_positions(d.X.data(), u.data(), 0, d.local(), d.local(), x.data());
      const bool energy = call % 2 == 0;
      std::vector<double> f_fast(3 * n, 0.0), f_walk(3 * n, 0.0), e_fast(n, 0.0), e_walk(n, 0.0);
      BondView v_fast = body->view(x.data(), flags_fast.data()), v_walk = body->view(x.data(), flags_walk.data());
      v_fast.energy_density = e_fast.data();
      v_walk.energy_density = e_walk.data();
      BondTally t_fast, t_walk;
      const LawEntry& entry = body->law.entry();
      entry.forces(body->law.constants(), v_fast, plan_fast, f_fast.data(), energy, t_fast);
      entry.portable_forces(body->law.constants(), v_walk, plan_walk, f_walk.data(), energy, t_walk);
      const std::string where = "variant " + std::to_string(variant) + " call " + std::to_string(call);
      EXPECT_EQ(std::memcmp(f_fast.data(), f_walk.data(), f_fast.size() * sizeof(double)), 0) << where;
      EXPECT_EQ(flags_fast, flags_walk) << where;
      EXPECT_EQ(t_fast.newly_broken, t_walk.newly_broken) << where;
      EXPECT_EQ(t_fast.dissipated, t_walk.dissipated) << where;
      EXPECT_EQ(t_fast.strain_energy, t_walk.strain_energy) << where;
      if (energy) EXPECT_EQ(e_fast, e_walk) << where;
      if (irregular && call == 0) {
        // Free rows against the same bonds with a family pattern per row (the representation they
        // replace: |xi|^2 rounded, 1/|xi| a square root and a division): the same forces to
        // round-off.
        PatternBuilder builder;
        std::vector<double> xi2, measure;
        for (std::int32_t i = 0; i < d.owned; ++i) {
          xi2.clear();
          measure.clear();
          for (std::int64_t b = d.bonds.offsets[i]; b < d.bonds.offsets[i + 1]; ++b) {
            // (The weight from the quadrature itself, as the domain's neighbour search takes it.)
            const std::int32_t j = d.bonds.neighbor[b];
            double e[3];
            reference_offset(body->nodes.bodies[0], &d.X[3 * static_cast<std::size_t>(i)],
                             &d.X[3 * static_cast<std::size_t>(j)], e);
            xi2.push_back(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
            const float w = static_cast<float>(quadrature_weight(body->nodes.bodies[0], e));
            measure.push_back(static_cast<double>(w) * d.volume[j]);
          }
          builder.add_row(xi2, measure, body->nodes.bodies[0].horizon);
        }
        const FamilyPatterns patterned = builder.finish();
        std::vector<std::uint8_t> flags_ref(d.bonds.broken.size(), 0);
        BondView v_ref = body->view(x.data(), flags_ref.data());
        v_ref.patterns = &patterned;
        std::vector<double> f_ref(3 * n, 0.0);
        BondTally t_ref;
        entry.portable_forces(body->law.constants(), v_ref, plan_rows(v_ref, body->rows.data(), body->rows.size()),
                              f_ref.data(), false, t_ref);
        double fmax = 0, diff = 0;
        for (std::size_t k = 0; k < f_ref.size(); ++k) {
          fmax = std::max(fmax, std::fabs(f_ref[k]));
          diff = std::max(diff, std::fabs(f_ref[k] - f_fast[k]));
        }
        // (The patterns' rounding of |xi|^2, 2^-46 relative, reaches the membrane law's coefficient
        // g wV/|xi|^2 (1 - r^2) divided by the strain: about 1e-11 of the largest force here.)
        EXPECT_LE(diff, 1e-10 * fmax) << where;
        EXPECT_EQ(t_ref.newly_broken, t_fast.newly_broken) << where;
      }
      broken += t_fast.newly_broken;
    }
    EXPECT_GT(broken, 0) << "variant " << variant << ": no bond broke, the failure path went untested";
  }
  EXPECT_GT(tested, 0) << s.law << ": no shape accepted";
  EXPECT_GT(irregular_tested, 0) << s.law << ": no irregular body accepted";
}

// f / y = (dw/dy) / y for intact bonds, over compression and tension, for every shape.
inline void coefficient_is_the_energy_gradient_and_slope_its_derivative(const Sample& s) {
  int tested = 0;
  for (int variant = 0; variant < 4; ++variant) {
    const bool conical = variant & 1, linear = variant & 2;
    if (linear && s.linear.empty()) continue;
    const std::unique_ptr<Body> body = body_if_accepted(variant_material(s, conical, linear), false);
    if (!body) continue;
    ++tested;
    const BondLaw law = body->law.intact();
    const double delta = law.horizon();
    for (double xi : {0.3 * delta, 0.7 * delta, 0.95 * delta})
      for (double lambda : {0.6, 0.9, 0.999, 1.003, 1.1, 1.5, 2.5}) {
        const double xi2 = xi * xi, y = lambda * xi, h = 1e-6 * y;
        const double dw = (law.energy(xi2, (y + h) * (y + h)) - law.energy(xi2, (y - h) * (y - h))) / (2 * h);
        const double k = law.coefficient(xi2, y * y);
        EXPECT_NEAR(k * y, dw, 1e-6 * std::fabs(dw) + 1e-12 * std::fabs(law.coefficient(xi2, 4 * xi2)) * xi)
            << "variant " << variant << " xi/delta " << xi / delta << " lambda " << lambda;
        const double y2 = y * y, h2 = 1e-6 * y2;
        const double dk = (law.coefficient(xi2, y2 + h2) - law.coefficient(xi2, y2 - h2)) / (2 * h2);
        EXPECT_NEAR(law.slope(xi2, y2), dk, 1e-5 * std::fabs(dk) + 1e-9 * std::fabs(k) / y2)
            << "variant " << variant << " xi/delta " << xi / delta << " lambda " << lambda;
      }
  }
  EXPECT_GT(tested, 0) << s.law << ": no shape accepted";
}

// The SNES tangent's block row of an interior node against central differences of the force
// densities: K_ij = -d(V_i F_i)/du_j, at a deformed state (strains about 10%, intact law).
inline void tangent_row_is_the_derivative_of_the_forces(const Sample& s) {
  const Body body(s.material, false);
  const BondLaw law = body.law.intact();
  const Domain& d = body.d;
  const std::size_t n = static_cast<std::size_t>(d.local());
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<double> u(3 * n), x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    u[3 * i] = 0.1 * d.X[3 * i] + 2e-5 * U(rng);
    u[3 * i + 1] = -0.03 * d.X[3 * i + 1] + 2e-5 * U(rng);
    u[3 * i + 2] = 2e-5 * U(rng);
  }
  std::vector<std::uint8_t> flags(d.bonds.broken.size(), 0);
  const std::int32_t row = static_cast<std::int32_t>(7 * 20 + 10);  // an interior node of the 20 x 15 grid
  auto force_of_row = [&](std::vector<double>& uu) {
    current_positions(d.X.data(), uu.data(), 0, d.local(), d.local(), x.data());
    std::vector<double> f(3 * n, 0.0);
    BondTally t;
    bond_forces(law, body.view(x.data(), flags.data()), &row, 1, f.data(), false, t);
    return std::vector<double>{f[3 * row], f[3 * row + 1], f[3 * row + 2]};
  };
  current_positions(d.X.data(), u.data(), 0, d.local(), d.local(), x.data());
  std::vector<std::int32_t> cols;
  std::vector<double> blocks;
  row_tangent(law, body.view(x.data(), flags.data()), row, cols, blocks);
  const std::size_t stride = 3 * cols.size();
  double largest = 0;
  for (double b : blocks) largest = std::max(largest, std::fabs(b));
  double worst = 0;
  for (std::size_t k = 0; k < cols.size(); ++k)
    for (int c = 0; c < 3; ++c) {
      std::vector<double> up = u, um = u;
      const double h = 1e-9;
      up[3 * cols[k] + c] += h;
      um[3 * cols[k] + c] -= h;
      const std::vector<double> fp = force_of_row(up), fm = force_of_row(um);
      for (int a = 0; a < 3; ++a) {
        const double fd = -(fp[a] - fm[a]) / (2 * h) * d.volume[row];
        worst = std::max(worst, std::fabs(blocks[a * stride + 3 * k + c] - fd));
      }
    }
  EXPECT_GT(largest, 0) << s.law;
  EXPECT_LT(worst, 1e-6 * largest) << s.law << ": " << cols.size() << " columns";
}

// Energy density (eq. 5) of an interior node of a uniform grid under the homogeneous deformation
// diag(l1, l2, l3).
inline double energy_density(const BondLaw& law, const BodyGeometry& g, double l1, double l2, double l3) {
  const double dx = g.spacing;
  const int M = static_cast<int>(std::ceil(g.horizon / dx)) + 1;
  const bool solid = g.traits.dimension == 3;
  const double cell = solid ? dx * dx * dx : g.cell_area * g.thickness;
  double W = 0;
  for (int k = solid ? -M : 0; k <= (solid ? M : 0); ++k)
    for (int j = -M; j <= M; ++j)
      for (int i = -M; i <= M; ++i) {
        if (i == 0 && j == 0 && k == 0) continue;
        const double xi[3] = {i * dx, j * dx, k * dx};
        const double w = quadrature_weight(g, xi);
        if (w == 0) continue;
        const double s2 = xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2];
        const double y2 = l1 * l1 * xi[0] * xi[0] + l2 * l2 * xi[1] * xi[1] + l3 * l3 * xi[2] * xi[2];
        W += 0.5 * law.energy(s2, y2) * w * cell;
      }
  return W;
}

// Membranes: equibiaxial W = 2 K e^2 and uniaxial strain W = 3 mu e^2 / 2 (lambda = mu); solids:
// isotropic W = 9 K e^2 / 2; each with the K and mu the law reports for the body.
inline void calibration_stores_the_continuum_energy(const Sample& s) {
  const double e = 1e-4;
  int tested = 0;
  for (bool solid : {false, true}) {
    BodyGeometry g;
    g.traits = find_body_kind(solid ? "solid" : "membrane")->traits;
    g.horizon = 1.0;
    g.spacing = solid ? 0.1 : 1.0 / 24;
    g.thickness = solid ? 0.0 : 1e-3;
    g.cell_area = g.spacing * g.spacing;
    g.quadrature = Quadrature::PartialArea;
    const Scene scene = parse_scene(scene_text(s.material, false), "law-test");
    BondLaw law;
    try {
      law = calibrate(scene.materials[0], g, "law-test");
    } catch (const InputError&) {
      continue;
    }
    ++tested;
    const ElasticConstants k = elastic_constants(law, g, scene.materials[0].density);
    if (solid) {
      EXPECT_NEAR(energy_density(law, g, 1 + e, 1 + e, 1 + e) / (4.5 * k.bulk * e * e), 1.0, 5e-3) << s.law;
    } else {
      EXPECT_NEAR(energy_density(law, g, 1 + e, 1 + e, 1) / (2 * k.bulk * e * e), 1.0, 2e-3) << s.law;
      EXPECT_NEAR(energy_density(law, g, 1 + e, 1, 1) / (1.5 * k.mu * e * e), 1.0, 2e-3) << s.law;
    }
  }
  EXPECT_GT(tested, 0) << s.law << ": no body kind accepted";
}

}  // namespace peri::law_checks
