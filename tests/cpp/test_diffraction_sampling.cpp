// Gap diffraction at render time (osl/include/loom/diffraction_sampling.h): the sampling image,
// read as the shaders read it, draws direction sums from the distribution it was built for; the
// closures' expectation matches the model's pattern in the arms of the cross; the energy split
// between the sampled lobes and transparent() is the texel's open fraction; the shared helpers'
// limits.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "loom/atlas.h"
#include "loom/bake.h"
#include "loom/diffraction_tables.h"
#include "loom/raywave_bsdf.h"
#include "loom/spec.h"
#include "loom/spectrum.h"
#include "test_util.h"

namespace sh = loom::shading;
using sh::vec3;

namespace {

/// Blender's and OSL's 'Linear' look-up with clamped edges (texel centres at (k + 0.5) / n),
/// written here on its own: what the shaders do with the sampling image.
float linear_lookup(const loom::DiffractionSampling& img, float s, float tv, int c) {
  float px = std::clamp(s * float(img.width) - 0.5f, 0.0f, float(img.width - 1));
  float py = std::clamp(tv * float(img.height) - 0.5f, 0.0f, float(img.height - 1));
  const int x0 = int(px), y0 = int(py);
  const int x1 = std::min(x0 + 1, img.width - 1), y1 = std::min(y0 + 1, img.height - 1);
  const float fx = px - float(x0), fy = py - float(y0);
  auto at = [&](int x, int y) { return img.rgb[(size_t(y) * img.width + x) * 3 + size_t(c)]; };
  return (at(x0, y0) * (1 - fx) + at(x1, y0) * fx) * (1 - fy) +
         (at(x0, y1) * (1 - fx) + at(x1, y1) * fx) * fy;
}

/// The organza's hole (127 x 108 um) with a 10 um beam at preview resolution.
struct Organza {
  loom::DiffractionSettings ds = loom::diffraction_settings(loom::Quality::Preview);
  loom::DiffractionTable table;
  double spot = loom::diffraction_spot_radius(10);
  Organza() {
    const loom::ColourConverter cc;
    table = loom::diffraction_gap_table(127.3, 108.3, 10, loom::spectral_rgb(cc, ds.step_nm), ds);
  }
};

const Organza& organza() {
  static const Organza o;
  return o;
}

TEST(DiffractionSampling, TheImageDrawsTheSamplersDistribution) {
  // Draw direction sums as the shader does (diffraction_split, diffraction_sample_uv,
  // diffraction_cell_row, diffraction_table_s, looked up bilinearly) and histogram them on
  // rectangles in s; the counts follow DiffractionSampler::probability of each rectangle.
  const Organza& o = organza();
  const loom::DiffractionSampling img = loom::diffraction_sampling_table(o.table, o.spot);
  const int size = o.table.size;
  // Rectangles: |s| edges on a geometric grid (fine near the spot, where the mass is), both
  // signs.
  std::vector<double> edges{0.0};
  for (double e = 0.002; e < 2.0; e *= 1.5) edges.push_back(e);
  edges.push_back(2.0);
  std::vector<double> signed_edges;
  for (size_t k = edges.size(); k-- > 1;) signed_edges.push_back(-edges[k]);
  for (double e : edges) signed_edges.push_back(e);
  const int B = int(signed_edges.size()) - 1;
  auto bin = [&](double s) {
    return int(std::upper_bound(signed_edges.begin(), signed_edges.end(), s) -
               signed_edges.begin()) - 1;
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u01(0, 1);
  const int draws = 400000;
  for (int tile : {0, o.table.tiles_x * o.table.tiles_y - 1, o.table.tiles_x - 1}) {
    const int tx = tile % o.table.tiles_x, ty = tile / o.table.tiles_x;
    for (int c = 0; c < 3; ++c) {
      const loom::DiffractionSampler sampler =
          loom::diffraction_sampler(o.table, tx, ty, c, o.spot);
      if (sampler.p_out() < 1e-4) continue;  // (nothing outside the spot to sample)
      std::vector<double> hist(size_t(B) * B, 0.0);
      for (int k = 0; k < draws; ++k) {
        float sgn_x, sgn_y, s, tv;
        const float uy = sh::diffraction_split(u01(rng), sgn_y);
        const float ux = sh::diffraction_split(u01(rng), sgn_x);
        sh::diffraction_sample_uv(uy, 0, tx, ty, o.table.tiles_x, o.table.tiles_y, size, s, tv);
        const float t_y = linear_lookup(img, s, tv, c);
        const int row = sh::diffraction_cell_row(t_y, size);
        sh::diffraction_sample_uv(ux, row, tx, ty, o.table.tiles_x, o.table.tiles_y, size, s, tv);
        const float t_x = linear_lookup(img, s, tv, c);
        const double sx = sgn_x * sh::diffraction_table_s(t_x);
        const double sy = sgn_y * sh::diffraction_table_s(t_y);
        const int bx = std::clamp(bin(sx), 0, B - 1), by = std::clamp(bin(sy), 0, B - 1);
        hist[size_t(by) * B + bx] += 1.0 / draws;
      }
      double tv_dist = 0;
      for (int by = 0; by < B; ++by)
        for (int bx = 0; bx < B; ++bx) {
          const double p = sampler.probability(signed_edges[size_t(bx)], signed_edges[size_t(bx) + 1],
                                               signed_edges[size_t(by)], signed_edges[size_t(by) + 1]);
          tv_dist += 0.5 * std::fabs(hist[size_t(by) * B + bx] - p);
        }
      // Monte Carlo noise alone: about 0.5 sum sqrt(p / draws), below 0.01 here.
      std::printf("tile %d channel %d: p_out %.3f, total variation distance %.4f\n", tile, c,
                  sampler.p_out(), tv_dist);
      EXPECT_LT(tv_dist, 0.03) << "tile " << tile << " channel " << c;
      // The p_out row holds the sampler's power.
      float s, tv;
      sh::diffraction_sample_uv(0.5f, size, tx, ty, o.table.tiles_x, o.table.tiles_y, size, s, tv);
      EXPECT_NEAR(linear_lookup(img, s, tv, c), sampler.p_out(), 1e-6);
    }
  }
}

TEST(DiffractionSampling, ProbabilityIntegratesTheDensity) {
  // probability() is the integral of density() (checked on rectangles away from the axes, where
  // the density is finite) and sums to 1 over the plane.
  const Organza& o = organza();
  const int last = o.table.tiles_x * o.table.tiles_y - 1;
  const loom::DiffractionSampler d =
      loom::diffraction_sampler(o.table, last % o.table.tiles_x, last / o.table.tiles_x, 1, o.spot);
  ASSERT_GT(d.p_out(), 0.05);  // the beam centred on the yarn's edge: much outside the spot
  EXPECT_NEAR(d.probability(-2, 2, -2, 2), 1.0, 1e-9);
  for (auto [x0, y0] : {std::pair{0.05, 0.004}, {0.2, 0.01}, {-0.1, -0.02}, {0.03, 0.03}}) {
    const double w = 0.002;
    double q = 0;
    const int n = 40;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        q += d.density(x0 + (i + 0.5) * w / n, y0 + (j + 0.5) * w / n) * (w / n) * (w / n);
    const double p = d.probability(x0, x0 + w, y0, y0 + w);
    EXPECT_NEAR(q, p, 0.02 * p + 1e-12) << x0 << "," << y0;
  }
}

TEST(DiffractionSampling, SharedHelpers) {
  // Offsets: 0 at the hole's centre (repeat coordinate k / yarns), 1 at the yarn's edge and
  // beyond.
  EXPECT_NEAR(sh::diffraction_gap_offset(0.0f, 4, 0.5f), 0.0f, 1e-6);
  EXPECT_NEAR(sh::diffraction_gap_offset(0.25f, 4, 0.5f), 0.0f, 1e-6);
  EXPECT_NEAR(sh::diffraction_gap_offset(0.03125f, 4, 0.5f), 0.5f, 1e-5);  // a quarter spacing
  EXPECT_EQ(sh::diffraction_gap_offset(0.125f, 4, 0.5f), 1.0f);            // a yarn's centre
  // Tile picks: the upper tile with probability equal to the fraction.
  int upper = 0;
  const int n = 10000;
  for (int k = 0; k < n; ++k) upper += sh::diffraction_tile_pick(0.64f, 4, (k + 0.5f) / n) == 2;
  // o = 0.64 on 4 tiles: coordinate 3 (1 - sqrt(0.36)) = 1.2, tile 2 with probability 0.2.
  EXPECT_NEAR(double(upper) / n, 0.2, 1e-3);
  // Tile k holds offset 1 - (1 - k / 3)^2: the coordinate of that offset is k.
  for (int k = 0; k < 4; ++k)
    EXPECT_NEAR(sh::diffraction_tile_coord(1.0f - (1.0f - k / 3.0f) * (1.0f - k / 3.0f), 4),
                float(k), 1e-5);
  EXPECT_EQ(sh::diffraction_tile_pick(1.0f, 4, 0.0f), 3);
  EXPECT_EQ(sh::diffraction_tile_pick(0.7f, 1, 0.3f), 0);
  EXPECT_EQ(sh::diffraction_tile_pick(float(NAN), 3, 0.3f), 0);
  EXPECT_EQ(sh::diffraction_cell_row(float(NAN), 32), 1);
  EXPECT_EQ(sh::diffraction_cell_row(2.0f, 32), 31);
  // Split: sign and a uniform remainder.
  float sg;
  EXPECT_NEAR(sh::diffraction_split(0.25f, sg), 0.5f, 1e-6);
  EXPECT_EQ(sg, -1.0f);
  EXPECT_NEAR(sh::diffraction_split(0.75f, sg), 0.5f, 1e-6);
  EXPECT_EQ(sg, 1.0f);
  // Light direction: straight through for s = 0; evanescent outside the unit disk.
  vec3 L;
  const vec3 V = sh::normalize(vec3(0.3f, -0.2f, 0.9f));
  ASSERT_TRUE(sh::diffraction_light_direction(V, 0.0f, 0.0f, L));
  EXPECT_NEAR(L.x, -V.x, 1e-6);
  EXPECT_NEAR(L.y, -V.y, 1e-6);
  EXPECT_NEAR(L.z, -V.z, 1e-6);
  EXPECT_FALSE(sh::diffraction_light_direction(V, 1.5f, 0.0f, L));
  // The weight is finite at grazing L and 0 for no power.
  const vec3 graze = sh::normalize(vec3(1.0f, 0.0f, -1e-7f));
  EXPECT_TRUE(std::isfinite(sh::diffraction_lobe_weight(V, graze, 0.3f, 1.0f)));
  EXPECT_EQ(sh::diffraction_lobe_weight(V, L, 0.0f, 1.0f), 0.0f);
}

TEST(DiffractionSampling, ClosuresMatchTheModelInTheArms) {
  // The organza preset (draft) seen along the normal: in a texel of its hole near a weft yarn's
  // edge (the beam partly clipped, x offset 0.95 of the half gap), the closures'
  // expectation follows the model's pattern along the arm (s_x) and across it (s_y), outside the
  // central spot (the lobes' width, LOOM_DIFFRACTION_KERNEL_RAD, blurs the pattern a little). And transparent() plus the sampled power is the open fraction.
  // (Both atlases by the fixture baker: this test only reads them; test_util.h.)
  const auto& dir = loom::test::draft_atlas("white_silk_organza", "raywave");
  const loom::Atlas atlas = loom::load_atlas(dir);
  const loom::RaywaveData d = loom::load_raywave(atlas);
  ASSERT_TRUE(d.diffraction.present);
  const float gx = d.diffraction.gap_fraction[0];
  const float u = 0.95f * 0.5f * gx / float(d.diffraction.yarns[0]);  // the hole at u = 0
  const loom::SurfacePoint p = loom::sample_surface(atlas, u, 0.0f);
  ASSERT_GT(p.gap, 0.5f);
  const vec3 V(0, 0, 1);
  const loom::RaywavePoint pm(d, p, V, loom::Evaluator::Model), pc(d, p, V, loom::Evaluator::Closures);
  const loom::RaywavePoint pnd(d, p, V, loom::Evaluator::Model, false);
  // Across the arm (s_y at fixed s_x), the lobes' width (LOOM_DIFFRACTION_KERNEL_RAD) blurs the
  // pattern, whose own width there is the beam's divergence (lambda / (2 pi w_0), 0.0074 in s
  // for the blue channel): the peak on the axis drops, the energy across the arm stays. So the
  // check is the integral across the arm, at s_x whose kernel window (4 widths) stays clear of
  // the central spot (|s| < 0.033) and of the sampled distribution's blur at its edge, and the
  // peak's drop is reported.
  double worst = 0, worst_peak = 0;
  for (float sx : {0.07f, 0.1f, 0.15f, 0.25f}) {
    double im[3] = {0, 0, 0}, ic[3] = {0, 0, 0};
    const int steps = 80;
    const float half = 0.04f, dsy = 2 * half / steps;
    for (int k = 0; k < steps; ++k) {
      vec3 L;
      ASSERT_TRUE(sh::diffraction_light_direction(V, sx, -half + (k + 0.5f) * dsy, L));
      const auto fm = pm.eval(L), fc = pc.eval(L);
      for (int c = 0; c < 3; ++c) im[c] += fm[size_t(c)] * dsy, ic[c] += fc[size_t(c)] * dsy;
    }
    vec3 L0;
    sh::diffraction_light_direction(V, sx, 0.0f, L0);
    const auto pm0 = pm.eval(L0), pc0 = pc.eval(L0);
    // The diffraction is most of what is measured (without it: the yarns' transmission alone).
    ASSERT_GT(pm0[1], 2 * pnd.eval(L0)[1]) << sx;
    for (int c = 0; c < 3; ++c) {
      worst = std::max(worst, std::fabs(ic[c] / im[c] - 1));
      worst_peak = std::max(worst_peak, 1 - double(pc0[size_t(c)]) / pm0[size_t(c)]);
    }
    std::printf("  s_x %.3f: across the arm model %.4f %.4f %.4f closures %.4f %.4f %.4f\n", sx,
                im[0], im[1], im[2], ic[0], ic[1], ic[2]);
  }
  std::printf("closures vs model across the arms: worst relative difference %.3f; the peak on "
              "the axis drops by up to %.3f\n", worst, worst_peak);
  EXPECT_LT(worst, 0.05);
  // Energy: transparent() keeps the open fraction less the sampled power.
  double sampled = 0;
  for (const auto& cl : pc.closures())
    if (cl.kind == 4) sampled = 1.0 - cl.weight[1] / p.gap;
  EXPECT_GT(sampled, 0.02);
  EXPECT_LT(sampled, 0.5);
  // The non-wave variant: no gap table, delta transmission of the whole open fraction.
  auto delta_spec = loom::preset("white_silk_organza");
  delta_spec["wave"]["diffraction"] = false;
  const loom::Atlas a2 = loom::load_atlas(loom::test::shared_atlas(
      "white_silk_organza-delta-raywave.draft", delta_spec, "draft", loom::test::Baker::Fixture));
  const loom::RaywaveData d2 = loom::load_raywave(a2);
  EXPECT_FALSE(d2.diffraction.present);
  const loom::RaywavePoint pd(d2, loom::sample_surface(a2, u, 0.0f), V, loom::Evaluator::Closures);
  int transparent = 0;
  for (const auto& cl : pd.closures()) {
    if (cl.kind != 4) continue;
    EXPECT_NEAR(cl.weight[1], p.gap, 1e-6);
    ++transparent;
  }
  EXPECT_EQ(transparent, 1);
}

}  // namespace
