// The repeat-averaged closures (average_closures.h, average_fit.h): the table as the shaders
// read it, each closure's albedo, and the fitted closures against the model averaged over a
// lattice of texels of the repeat (independent of the fit's own points and light directions).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "loom/atlas.h"
#include "loom/average_fit.h"
#include "loom/evaluator.h"
#include "loom/atlas_bsdf.h"
#include "test_util.h"

using namespace loom::shading;

namespace {

constexpr int kTheta = LOOM_AVERAGE_THETA, kPhi = LOOM_AVERAGE_PHI,
              kPanels = LOOM_AVERAGE_PANELS;

/// A table whose texel (column j, row of side s, panel p, cos row i) holds a value known in
/// closed form: channel c = 1000 s + 100 p + 10 i + j + c / 10 (the wrap column repeats j = 0).
loom::Image known_table() {
  loom::Image t(kPhi + 1, 2 * kPanels * kTheta, 4);
  for (int s = 0; s < 2; ++s)
    for (int p = 0; p < kPanels; ++p)
      for (int i = 0; i < kTheta; ++i)
        for (int j = 0; j <= kPhi; ++j)
          for (int c = 0; c < 4; ++c)
            t.px(j, (s * kPanels + p) * kTheta + i)[c] =
                float(1000 * s + 100 * p + 10 * i + (j % kPhi) + 0.1 * c);
  return t;
}

vec3 view(double cos_t, double phi, bool back) {
  const double s = std::sqrt(1 - cos_t * cos_t);
  return vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(back ? -cos_t : cos_t));
}

}  // namespace

TEST(AverageClosures, TheShadersReadTheFittedViewsAndInterpolateBetweenThem) {
  const loom::Image t = known_table();
  const double dphi = 2 * M_PI / kPhi;
  for (bool back : {false, true})
    for (int i : {1, 3, kTheta - 2})
      for (int j : {0, 4, kPhi - 1}) {
        const double c = double(i) / (kTheta - 1);
        // On a fitted view: that texel, in each panel (weight RGB, alpha).
        const loom::AverageClosures a = loom::read_average_closures(t, view(c, j * dphi, back));
        const float base = float(1000 * back + 10 * i + j);
        for (int p = 0; p < kPanels; ++p) {
          for (size_t ch = 0; ch < 3; ++ch)
            EXPECT_NEAR(a.w[size_t(p)][ch], base + 100 * p + 0.1f * ch, 1e-3) << back << i << j;
          EXPECT_NEAR(a.alpha[size_t(p)], base + 100 * p + 0.3f, 1e-3);
        }
        // Half way to the next azimuth (wrapping to column 0 after the last) and a quarter to
        // the next cos theta row: bilinear, never another side or panel.
        const double c2 = (i + 0.25) / (kTheta - 1);
        const loom::AverageClosures m =
            loom::read_average_closures(t, view(c2, (j + 0.5) * dphi, back));
        const double next_j = j + 1 < kPhi ? j + 1 : 0;
        EXPECT_NEAR(m.w[0][0], 1000 * back + 10 * (i + 0.25) + 0.5 * (j + next_j), 2e-3)
            << back << i << j;
      }
}

namespace {

double mean_rgb(const std::array<float, 3>& f) { return (f[0] + f[1] + f[2]) / 3.0; }

/// The averaged closures and the model averaged over the repeat at view wo, for lights on both
/// sides (one sun, as a render of a swatch of many repeats sees them): mean relative error of f
/// (the mean of RGB, as a render's mean) over the lit lights, and the same for a Lambertian pair
/// (diffuse and translucent carrying the model's albedo on each side), the fit's baseline.
struct Versus {
  double fit = 0, lambert = 0;
  int lit = 0;
};
Versus against_model(const loom::Atlas& a, vec3 wo) {
  const loom::Image& table = a.map("average_closures");
  std::vector<vec3> lights;
  for (int k = 0; k < 12; ++k)
    for (double z : {0.95, 0.7, 0.4, -0.4, -0.7, -0.95}) {
      const double phi = (k + 0.37) * 2 * M_PI / 12, r = std::sqrt(1 - z * z);
      lights.push_back(vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)));
    }
  // The model (each tier's own evaluator) over every texel of a lattice of at most 64 x 64 over
  // the repeat (all of a small map; the fit used 16 jittered points), each read as the shaders
  // read it (AtlasBsdf), and its albedo on each side for the Lambertian baseline (f cos = A
  // |cos| / pi).
  std::vector<double> model(lights.size());
  double up = 0, down = 0;
  const loom::AtlasBsdf bsdf(a, loom::Evaluator::Model);
  const loom::Image& ref = a.map("ply_frame");
  const int sx = std::max(1, ref.width / 64), sy = std::max(1, ref.height / 64);
  int n = 0;
  for (int iy = 0; iy < ref.height; iy += sy)
    for (int ix = 0; ix < ref.width; ix += sx, ++n) {
      const auto f = bsdf.at((ix + 0.5f) / ref.width, (iy + 0.5f) / ref.height, wo);
      for (size_t k = 0; k < lights.size(); ++k) model[k] += mean_rgb(f(lights[k]));
    }
  for (size_t k = 0; k < lights.size(); ++k) {
    model[k] /= n * std::fabs(lights[k].z);  // f
    (lights[k].z * wo.z > 0 ? up : down) += model[k] / lights.size() * 4 * M_PI *
                                               std::fabs(lights[k].z);
  }
  Versus v;
  for (size_t k = 0; k < lights.size(); ++k) {
    if (model[k] < 1e-4) continue;
    const double c = std::fabs(lights[k].z);
    const double f = mean_rgb(loom::average_closures_eval(table, wo, lights[k])) / c;
    const double lam = (lights[k].z * wo.z > 0 ? up : down) / M_PI;
    v.fit += std::fabs(f - model[k]) / model[k];
    v.lambert += std::fabs(lam - model[k]) / model[k];
    ++v.lit;
  }
  v.fit /= v.lit, v.lambert /= v.lit;
  return v;
}

}  // namespace

TEST(AverageFit, TheSurfaceTiersAveragedClosuresMatchTheModelAveragedOverTheRepeat) {
  // The measure (a swatch of many repeats seen straight down, one sun on either side):
  // within 10 % on average over the lights, and closer than a Lambertian of the same albedo.
  const loom::Atlas a = loom::load_atlas(loom::test::draft_atlas("plain", "surface"));
  ASSERT_TRUE(a.manifest.contains("average"));
  for (const vec3 wo : {vec3(0, 0, 1), vec3(0, 0, -1), view(0.6, 0.8, false)}) {
    const Versus v = against_model(a, normalize(wo));
    std::printf("view (%.2f, %.2f, %.2f): fitted %.4f, Lambertian %.4f over %d lights\n", wo.x,
                wo.y, wo.z, v.fit, v.lambert, v.lit);
    EXPECT_GE(v.lit, 40);
    EXPECT_LE(v.fit, 0.10);
    EXPECT_LT(v.fit, v.lambert);
  }
}

TEST(AverageFit, TheRaywaveTiersAveragedClosuresBeatALambertianOfTheSameAlbedo) {
  // The ray-wave tier's averaged BSDF has sharper features (forward transmission, fiber
  // highlights) than four closures carry: measured, not yet within the 10 % (see
  // docs/far.md); what must hold is that the fit is closer to the model than the Lambertian pair.
  const loom::Atlas a = loom::load_atlas(loom::test::draft_atlas("gray_wool_twill", "raywave"));
  for (const vec3 wo : {vec3(0, 0, 1), vec3(0, 0, -1), view(0.6, 0.8, false)}) {
    const Versus v = against_model(a, normalize(wo));
    std::printf("view (%.2f, %.2f, %.2f): fitted %.4f, Lambertian %.4f over %d lights\n", wo.x,
                wo.y, wo.z, v.fit, v.lambert, v.lit);
    EXPECT_GE(v.lit, 40);
    EXPECT_LT(v.fit, v.lambert);
  }
}

TEST(AverageClosures, AlbedoMatchesASphereQuadrature) {
  // albedo(p) integrates each lobe on a quadrature about it (the fit's energy term); against a
  // fine grid over the sphere (800 x 800 cells uniform in theta and phi, so that a narrow lobe
  // at a pole is resolved too), for narrow and wide lobes, on and off the normal.
  const int n = 800;
  for (const float cos_t : {1.0f, 0.6f, 0.2f})
    for (const float a : {0.15f, 0.4f, 1.0f}) {
      loom::AverageClosures p;
      p.alpha = {a, 0.5f * a + 0.1f, a, 0.0f};
      const vec3 V = view(cos_t, 0.7, false);
      const loom::AverageClosureSet s(p, V);
      for (int q = 0; q < loom::kAverageClosures; ++q) {
        double sum = 0;
        for (int i = 0; i < n; ++i) {
          const double th = (i + 0.5) * M_PI / n, z = std::cos(th), r = std::sin(th);
          const double dw = r * (M_PI / n) * (2 * M_PI / n);
          for (int j = 0; j < n; ++j) {
            const double ph = (j + 0.5) * 2 * M_PI / n;
            const vec3 L(float(r * std::cos(ph)), float(r * std::sin(ph)), float(z));
            sum += s.basis(q, L) * dw;
          }
        }
        EXPECT_NEAR(s.albedo(q), sum, 0.01 * std::max(sum, 0.05))
            << "closure " << q << " cos " << cos_t << " alpha " << a;
      }
    }
}
