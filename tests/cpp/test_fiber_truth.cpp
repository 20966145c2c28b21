// The fiber-level ground truth (fiber_truth.h) against an independent computation: a row of
// parallel straight fibers lit across their axes is a two-dimensional problem (every path stays
// in the plane normal to the fibers), traced here through a periodic row of circles with every
// Fresnel branch followed deterministically and the impact parameter integrated by quadrature.
// Then the white furnace on a real fabric, determinism, and the command line's refusals.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <tuple>
#include <vector>

#include "loom/fiber_truth.h"
#include "loom/spec.h"
#include "fiber_row.h"
#include "test_util.h"

namespace {

using loom::test::Row;
using loom::test::row_curves;

// ---- The independent two-dimensional trace (y across the fibers, z up) ----

/// Fresnel's unpolarised reflectance in the angle form (Born and Wolf): n1 sin a = n2 sin b.
double fresnel_angles(double cos_a, double n1, double n2) {
  const double a = std::acos(std::clamp(cos_a, 0.0, 1.0));
  const double sb = n1 / n2 * std::sin(a);
  if (sb >= 1) return 1;
  const double b = std::asin(sb);
  if (a < 1e-9) return std::pow((n1 - n2) / (n1 + n2), 2);
  const double rs = std::sin(a - b) / std::sin(a + b), rp = std::tan(a - b) / std::tan(a + b);
  return 0.5 * (rs * rs + rp * rp);
}

struct Out2 {
  std::array<double, 3> up{}, down{};
};

/// Follows a ray outside the circles, (y, z) along unit (dy, dz), with weights w, to depth.
void trace2(const Row& row, double y, double z, double dy, double dz, std::array<double, 3> w,
            int depth, Out2& out);

/// Inside circle k's centre cy: walls until every branch has left (each branch traced on).
void inside2(const Row& row, double cy, double y, double z, double dy, double dz,
             std::array<double, 3> w, int depth, Out2& out) {
  if (depth > 40 || w[0] + w[1] + w[2] < 1e-9) return;
  // exit: |p + t d - c| = r, the larger root
  const double py = y - cy, pz = z;
  const double b = py * dy + pz * dz, c = py * py + pz * pz - row.r * row.r;
  const double t = -b + std::sqrt(std::max(b * b - c, 0.0));
  if (!std::isfinite(t)) return;  // a grazing path of measure zero, numerically lost
  for (int k = 0; k < 3; ++k) w[size_t(k)] *= std::exp(-row.sigma[size_t(k)] * t);
  const double qy = y + dy * t, qz = z + dz * t;
  const double ny = (qy - cy) / row.r, nz = qz / row.r;  // outward
  const double ci = dy * ny + dz * nz;
  const double F = fresnel_angles(ci, row.ior, 1.0);
  const double ry = dy - 2 * ci * ny, rz = dz - 2 * ci * nz;
  std::array<double, 3> wr = w, wt = w;
  for (int k = 0; k < 3; ++k) wr[size_t(k)] *= F, wt[size_t(k)] *= 1 - F;
  inside2(row, cy, qy, qz, ry, rz, wr, depth + 1, out);
  if (F < 1) {  // Snell: tangential component scaled by the index ratio
    const double ty = dy - ci * ny, tz = dz - ci * nz;  // tangential part of d
    const double sy = ty * row.ior, sz = tz * row.ior;
    const double s2 = sy * sy + sz * sz;
    const double cn = std::sqrt(std::max(1 - s2, 0.0));
    trace2(row, qy, qz, sy + cn * ny, sz + cn * nz, wt, depth + 1, out);
  }
}

void trace2(const Row& row, double y, double z, double dy, double dz, std::array<double, 3> w,
            int depth, Out2& out) {
  if (depth > 40 || w[0] + w[1] + w[2] < 1e-9) return;
  // Circles the ray can meet before it leaves the slab |z| <= r for good.
  double t_slab = 1e7;
  if (dz > 0) t_slab = (row.r - z) / dz;
  if (dz < 0) t_slab = (-row.r - z) / dz;
  t_slab = std::max(t_slab, 0.0);
  const double y_end = y + dy * std::min(t_slab, 1e7);
  const double lo = std::min(y, y_end) - row.r, hi = std::max(y, y_end) + row.r;
  long k0 = long(std::floor((lo - row.yc) / row.period)), k1 = long(std::ceil((hi - row.yc) / row.period));
  k1 = std::min(k1, k0 + 200000);
  double best = 1e300, best_c = 0;
  for (long k = k0; k <= k1; ++k) {
    const double cy = row.yc + double(k) * row.period;
    const double py = y - cy, pz = z;
    const double b = py * dy + pz * dz, c = py * py + pz * pz - row.r * row.r;
    const double disc = b * b - c;
    if (disc <= 0) continue;
    const double t = -b - std::sqrt(disc);
    if (t > 1e-7 && t < best) best = t, best_c = cy;
  }
  if (best == 1e300) {
    auto& o = dz > 0 ? out.up : out.down;
    for (int k = 0; k < 3; ++k) o[size_t(k)] += w[size_t(k)];
    return;
  }
  const double qy = y + dy * best, qz = z + dz * best;
  const double ny = (qy - best_c) / row.r, nz = qz / row.r;
  const double ci = -(dy * ny + dz * nz);
  const double F = fresnel_angles(ci, 1.0, row.ior);
  std::array<double, 3> wr = w, wt = w;
  for (int k = 0; k < 3; ++k) wr[size_t(k)] *= F, wt[size_t(k)] *= 1 - F;
  trace2(row, qy, qz, dy + 2 * ci * ny, dz + 2 * ci * nz, wr, depth + 1, out);
  const double ty = dy + ci * ny, tz = dz + ci * nz;  // tangential part of d
  const double sy = ty / row.ior, sz = tz / row.ior;
  const double cn = std::sqrt(std::max(1 - sy * sy - sz * sz, 0.0));
  inside2(row, best_c, qy, qz, sy - cn * ny, sz - cn * nz, wt, depth + 1, out);
}

/// The row's reflectance and transmittance for light falling straight down, averaged over a
/// period of launch positions (midpoint rule over the circle's shadow; the rest passes).
Out2 row_expected(const Row& row, int n) {
  Out2 sum;
  for (int i = 0; i < n; ++i) {
    const double b = -row.r + (i + 0.5) * 2 * row.r / n;
    trace2(row, row.yc + b, row.r + 1, 0, -1, {1, 1, 1}, 0, sum);
  }
  Out2 out;
  const double hit = 2 * row.r / row.period;
  for (size_t k = 0; k < 3; ++k) {
    out.up[k] = hit * sum.up[k] / n;
    out.down[k] = (1 - hit) + hit * sum.down[k] / n;
  }
  return out;
}

TEST(FiberTruth, RowOfFibersMatchesTwoDimensionalTrace) {
  // White, black and mid-absorbing channels; 1/3 of the light meets a fiber.
  const Row row{10.0, 60.0, 30.0, {0.0, 1.0, 0.02}, 1.55};
  const auto curves = row_curves(row, 40.0);
  loom::FiberMaterial m;
  m.ior = row.ior;
  m.sigma_per_um = row.sigma;
  loom::FiberTruthScene scene(curves, {0}, {m}, {0.0, 0.0, 40.0, row.period});
  loom::TruthSettings s;
  s.rays = 400000;
  s.res = 8;
  const auto r = scene.trace({0, 0, 1}, s);
  const Out2 e = row_expected(row, 20000);
  for (size_t k = 0; k < 3; ++k) {
    SCOPED_TRACE(k);
    EXPECT_NEAR(r.reflect[k], e.up[k], 4 * r.reflect_se[k] + 1e-4);
    EXPECT_NEAR(r.transmit[k], e.down[k], 4 * r.transmit_se[k] + 1e-4);
  }
  // The light that met no fiber is the gap's share exactly in expectation.
  EXPECT_NEAR(r.direct, 1 - 2 * row.r / row.period, 4 * std::sqrt(2.0 / 9 / s.rays));
  EXPECT_LT(r.truncated, 1e-4);
  // The white channel keeps all of it; the black one loses what enters a fiber.
  EXPECT_NEAR(r.reflect[0] + r.transmit[0], 1.0, 1e-12);
  EXPECT_NEAR(r.absorbed[0], 0.0, 1e-12);
  EXPECT_GT(r.absorbed[1], 0.25);
  // The tally integrates to what left: each hemisphere's bins to its fraction (res even: the
  // rows split at cos theta_o = 0).
  std::array<double, 3> up{}, down{};
  const double dw = 4 * M_PI / (s.res * s.res);
  for (int row_i = 0; row_i < s.res; ++row_i)
    for (int col = 0; col < s.res; ++col)
      for (size_t k = 0; k < 3; ++k)
        (row_i >= s.res / 2 ? up : down)[k] +=
            r.density[(size_t(row_i) * s.res + size_t(col)) * 3 + k] * dw;
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(up[k], r.reflect[k], 1e-5);
    EXPECT_NEAR(down[k] + r.direct, r.transmit[k], 1e-5);  // the delta is not in the tally
  }
}

TEST(FiberTruth, ResultDoesNotDependOnTheThreadCount) {
  const Row row{10.0, 60.0, 30.0, {0.0, 1.0, 0.02}, 1.55};
  loom::FiberMaterial m;
  m.ior = row.ior;
  m.sigma_per_um = row.sigma;
  loom::FiberTruthScene scene(row_curves(row, 40.0), {0}, {m}, {0.0, 0.0, 40.0, row.period});
  loom::TruthSettings s;
  s.rays = 20000;
  s.res = 6;
  const auto a = scene.trace({0.3, -0.2, 0.9}, s);
  loom::TruthResult b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    b = scene.trace({0.3, -0.2, 0.9}, s);
  }
  EXPECT_EQ(a.reflect, b.reflect);
  EXPECT_EQ(a.density, b.density);
  s.seed = 2;
  const auto c = scene.trace({0.3, -0.2, 0.9}, s);
  EXPECT_NE(a.reflect, c.reflect);
}

TEST(FiberTruth, WhiteFabricConservesEnergyFrontAndBack) {
  // The white furnace on a real weave: plain cotton-like yarns, white and non-absorbing.
  auto spec = loom::load_spec("plain");
  ASSERT_TRUE(spec.ok());
  spec.spec.warp.color_linear = spec.spec.weft.color_linear = {1, 1, 1};
  loom::TruthSettings s;
  s.rays = 20000;
  s.res = 8;
  s.min_yarns = 4;
  for (double z : {0.8, -0.6}) {
    SCOPED_TRACE(z);
    const loom::Vec3d wi = loom::normalized({0.3, 0.2, z});
    const auto r = loom::fiber_truth(spec.spec, wi, s);
    for (size_t k = 0; k < 3; ++k) {
      // White through the ply's absorption curve is a sigma near 0, not exactly 0.
      EXPECT_LT(r.absorbed[k], 1e-3);
      EXPECT_NEAR(r.reflect[k] + r.transmit[k] + r.absorbed[k] + r.truncated, 1.0, 1e-9);
      EXPECT_GT(r.reflect[k], 0.05);  // a woven cloth reflects some and lets some through
      EXPECT_GT(r.transmit[k], 0.05);
    }
    EXPECT_LT(r.truncated, 1e-3);
    EXPECT_LT(r.direct, r.transmit[0]);
    EXPECT_GT(r.curves, 100u);
  }
}

TEST(FiberTruth, TallyIsReciprocal) {
  // Light paths through dielectric fibers are reversible, so f(A, B) = f(B, A): the tally of
  // light from A at the bin of B, over |cos B|, equals the tally of light from B at the bin of
  // A, over |cos A| (A, B and C at bin centres, so that the bins' averaging is alike on both
  // sides; the cosines differ by 29 % and 57 %, so a tally that is not f |cos theta_o| fails).
  // White fibers (no absorption), the plain weave's tile of 2 x 2 yarns; 4 standard errors of
  // the two bins' counts plus 5 % for the bins' averaging of a curved f.
  auto spec = loom::load_spec("plain");
  ASSERT_TRUE(spec.ok());
  spec.spec.warp.color_linear = spec.spec.weft.color_linear = {1, 1, 1};
  const auto scene = loom::make_truth_scene(spec.spec, 2);
  loom::TruthSettings s;
  s.rays = 400000;
  s.res = 12;
  auto centre = [&](int row, int col) {
    const double z = -1 + (row + 0.5) * 2 / s.res, r = std::sqrt(1 - z * z);
    const double phi = -M_PI + (col + 0.5) * 2 * M_PI / s.res;
    return loom::Vec3d{r * std::cos(phi), r * std::sin(phi), z};
  };
  const int A[2] = {9, 2}, B[2] = {10, 7}, C[2] = {0, 5};  // A, B above; C below
  const loom::Vec3d a = centre(A[0], A[1]), b = centre(B[0], B[1]), c = centre(C[0], C[1]);
  const auto ta = scene->trace(a, s), tb = scene->trace(b, s), tc = scene->trace(c, s);
  auto at = [&](const loom::TruthResult& t, const int bin[2]) {
    return double(t.density[(size_t(bin[0]) * s.res + size_t(bin[1])) * 3 + 1]);
  };
  const double dw = 4 * M_PI / (s.res * s.res);
  for (const auto& [t1, t2, x1, x2, b1, b2] :
       {std::tuple{&ta, &tb, a, b, A, B}, std::tuple{&ta, &tc, a, c, A, C}}) {
    const double f12 = at(*t1, b2) / std::fabs(x2.z), f21 = at(*t2, b1) / std::fabs(x1.z);
    // A bin's tally is (hits / rays) / dw: its standard error is about sqrt(hits) / rays / dw.
    const double se12 = std::sqrt(at(*t1, b2) * dw / double(s.rays)) / dw / std::fabs(x2.z);
    const double se21 = std::sqrt(at(*t2, b1) * dw / double(s.rays)) / dw / std::fabs(x1.z);
    EXPECT_GT(f12, 0.0);
    EXPECT_NEAR(f12, f21, 4 * std::hypot(se12, se21) + 0.05 * std::max(f12, f21))
        << "light from z " << x1.z << " towards z " << x2.z;
  }
}

TEST(FiberTruthCli, PrintsJsonAndRefusesBadInput) {
  namespace fs = std::filesystem;
  const std::string exe = loom::test::bake_exe();
  std::string out;
  // The light in the cloth's plane, an unknown image format: exit 2, the option named.
  int rc = loom::test::run(exe + " eval truth --spec plain --wi 1,0,0 2>&1", &out);
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("--wi"), std::string::npos) << out;
  const fs::path bad = loom::test::scratch("truth.nope");
  rc = loom::test::run(exe + " eval truth --spec plain --wi 0,0,1 --out " + bad.string() + " 2>&1", &out);
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("--out"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(bad));
  rc = loom::test::run(exe + " eval truth --spec plain --wi 0,0,1 --rays 0 2>&1", &out);
  EXPECT_NE(rc, 0) << out;
  // A small run: JSON with the fractions, and the tally written as an image.
  const fs::path exr = loom::test::scratch("truth.exr");
  rc = loom::test::run(exe + " eval truth --spec plain --wi 0,0,1 --rays 2000 --res 4 "
                             "--min-yarns 2 --out " + exr.string(), &out);
  ASSERT_EQ(rc, 0) << out;
  const auto j = nlohmann::json::parse(out);
  for (const char* key : {"reflect", "transmit", "absorbed", "reflect_se"})
    EXPECT_EQ(j.at(key).size(), 3u) << key;
  const double sum = j["reflect"][1].get<double>() + j["transmit"][1].get<double>() +
                     j["absorbed"][1].get<double>() + j["truncated"].get<double>();
  EXPECT_NEAR(sum, 1.0, 1e-9);
  // The preset's yarn is red (sRGB 0.62, 0.12, 0.10): its fibers absorb blue and green far
  // more than red, so the light that leaves is red too (the same rays in every channel: the
  // difference is the absorption alone, not noise).
  for (const char* key : {"reflect", "transmit"})
    EXPECT_GT(j[key][0].get<double>(), 1.2 * j[key][2].get<double>()) << key;
  EXPECT_TRUE(fs::exists(exr));
}

}  // namespace
