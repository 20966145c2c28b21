// Ply scattering simulation against independent computations: a single straight fiber has closed
// forms (Fresnel reflection averaged over the impact parameter, and the geometric series of
// internal passes with Bravais' effective index), energy bookkeeping on a real ply, exact
// determinism across thread counts.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <functional>

#include "loom/ply_scattering.h"

namespace {

double fresnel(double ci, double eta) {
  double s2 = (1 - ci * ci) / (eta * eta);
  if (s2 >= 1) return 1;
  double ct = std::sqrt(1 - s2);
  double rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
  return 0.5 * (rs * rs + rp * rp);
}

/// Midpoint rule over the impact parameter b in (-1, 1), mean value.
double mean_over_b(const std::function<double(double)>& f, int n = 20000) {
  double s = 0;
  for (int i = 0; i < n; ++i) s += f(-1 + 2 * (i + 0.5) / n);
  return s / n;
}

struct SingleFiber {
  loom::PlyParams p;
  std::vector<loom::Fiber> fibers{loom::Fiber{0, 0, 0}};  // R = 0: a straight fiber on the axis
  SingleFiber() {
    p.fiber_radius = 10;
    p.pitch = 1000;
  }
};

loom::PlySimSettings single_settings(std::vector<double> sigmas) {
  loom::PlySimSettings s;
  s.theta_o_count = 45;
  s.phi_o_count = 72;
  s.rays_per_slice = 200000;
  s.beam_halfwidth = 1;  // the beam spans the whole silhouette
  s.max_events = 100000;
  s.sigmas = std::move(sigmas);
  return s;
}

}  // namespace

TEST(PlyScattering, SingleFiberMatchesClosedForms) {
  SingleFiber sf;
  const double eta = 1.55, r = sf.p.fiber_radius;
  loom::PlyGeometry g(sf.p, sf.fibers);
  const double hit_frac = r / g.bound_radius();
  for (double theta : {0.0, 0.7}) {
    const double sigma_mm = 40;  // 1/mm
    auto s = single_settings({0, sigma_mm});
    auto sl = loom::simulate_ply_slice(g, eta, s, theta, 0, 7);
    // Closed forms over the impact parameter b (hit point x = b r):
    //   cos_i = cos(theta) sqrt(1 - b^2); inside, the longitudinal angle has sin = sin(theta)/eta
    //   and the projected problem has index eta' = sqrt(eta^2 - sin^2 theta) / cos theta (Bravais);
    //   each internal chord is 2 r cos(gamma_t) / cos(theta_t), sin(gamma_t) = b / eta'; every
    //   internal reflection has the entry's Fresnel F, so the absorbed power is
    //   (1 - F)(1 - T) / (1 - F T) with T the chord transmittance.
    const double ct = std::cos(theta), stt = std::sin(theta) / eta, ctt = std::sqrt(1 - stt * stt);
    const double eta_p = std::sqrt(eta * eta - std::sin(theta) * std::sin(theta)) / ct;
    auto F = [&](double b) { return fresnel(ct * std::sqrt(1 - b * b), eta); };
    double refl = hit_frac * mean_over_b(F);
    double absorbed = hit_frac * mean_over_b([&](double b) {
      double sg = b / eta_p, chord = 2 * r * std::sqrt(1 - sg * sg) / ctt;
      double T = std::exp(-sigma_mm * 1e-3 * chord), f = F(b);
      return (1 - f) * (1 - T) / (1 - f * T);
    });
    const auto& e0 = sl.energy[0];
    const auto& e1 = sl.energy[1];
    EXPECT_NEAR(e0.unscattered, 1 - hit_frac, 3e-3) << "theta " << theta;
    EXPECT_NEAR(e0.reflected, refl, 2e-3) << "theta " << theta;
    EXPECT_NEAR(e0.higher_order, hit_frac - refl, 3e-3) << "theta " << theta;
    EXPECT_NEAR(e0.absorbed, 0, 1e-9);
    EXPECT_NEAR(e1.absorbed, absorbed, 3e-3) << "theta " << theta;
    EXPECT_GT(absorbed, 0.05);  // the case is not trivially small

    // A straight cylinder keeps the longitudinal direction: every scattered ray leaves on the
    // cone theta_o = -theta_i, i.e. in that theta_o row of the histogram.
    int row, col;
    loom::ply_sim_bin_of(s, loom::Vec3d{0, std::cos(theta), -std::sin(theta)}, row, col);
    double on_cone = 0, total = 0;
    for (int t = 0; t < s.theta_o_count; ++t)
      for (int p = 0; p < s.phi_o_count; ++p) {
        size_t b = size_t(t) * s.phi_o_count + p;
        double e = (sl.refl[b] + sl.high[b]) * loom::ply_sim_bin_solid_angle(s, t);
        total += e;
        if (t == row) on_cone += e;
      }
    EXPECT_NEAR(total, e0.reflected + e0.higher_order, 1e-4);
    EXPECT_GT(on_cone / total, 0.999) << "theta " << theta;
  }
}

TEST(PlyScattering, EnergyBookkeepingOnAPly) {
  loom::YarnSpec y;  // the default yarn: 40 fibers per ply, migration, IOR 1.55
  auto p = loom::ply_params_from_yarn(y);
  loom::PlyGeometry g(p, loom::make_ply_fibers(p, 0, 0));
  loom::PlySimSettings s;
  s.rays_per_slice = 20000;
  s.sigmas = {0, 10, 100, 1000};
  for (double theta : {0.0, 0.6, -1.2})
    for (double h : {-0.6, 0.0, 0.5}) {
      auto sl = loom::simulate_ply_slice(g, y.ior, s, theta, h, 3);
      const auto& e = sl.energy;
      // sigma = 0: every ray ends in exactly one category with its full weight.
      double sum0 = e[0].reflected + e[0].higher_order + e[0].unscattered + e[0].truncated;
      EXPECT_NEAR(sum0, 1.0, 1e-9) << theta << " " << h;
      EXPECT_GT(e[0].higher_order, 0.05) << "the beam meets fibers: " << theta << " " << h << " "
                                         << e[0].unscattered;
      // The histograms integrate to the same energies (normalisation by bin solid angle).
      double ir = 0, ih = 0;
      const size_t bins = size_t(s.theta_o_count) * s.phi_o_count;
      for (int t = 0; t < s.theta_o_count; ++t)
        for (int q = 0; q < s.phi_o_count; ++q) {
          size_t b = size_t(t) * s.phi_o_count + q;
          ir += sl.refl[b] * loom::ply_sim_bin_solid_angle(s, t);
          ih += sl.high[b] * loom::ply_sim_bin_solid_angle(s, t);
          for (size_t k = 1; k < s.sigmas.size(); ++k)
            EXPECT_LE(sl.high[k * bins + b], sl.high[(k - 1) * bins + b] * (1 + 1e-6) + 1e-12);
        }
      EXPECT_NEAR(ir, e[0].reflected, 1e-5);
      EXPECT_NEAR(ih, e[0].higher_order, 1e-5);
      for (size_t k = 1; k < e.size(); ++k) {
        EXPECT_LT(e[k].higher_order, e[k - 1].higher_order);
        EXPECT_GT(e[k].absorbed, e[k - 1].absorbed);
        EXPECT_EQ(e[k].reflected, e[0].reflected);  // surface reflection never enters a fiber
        double sum = e[k].reflected + e[k].higher_order + e[k].unscattered + e[k].truncated +
                     e[k].absorbed;
        EXPECT_NEAR(sum, 1.0, 1e-9);
      }
    }
}

TEST(PlyScattering, ExtremesStayFinite) {
  loom::YarnSpec y;
  auto p = loom::ply_params_from_yarn(y);
  loom::PlyGeometry g(p, loom::make_ply_fibers(p, 0, 0));
  loom::PlySimSettings s;
  s.rays_per_slice = 2000;
  s.sigmas = {0, 1e9};
  for (double theta : {-M_PI / 2, M_PI / 2, 1.5, -1.55})
    for (double h : {-1.0, 1.0, 0.0}) {
      auto sl = loom::simulate_ply_slice(g, y.ior, s, theta, h, 1);
      for (float v : sl.refl) ASSERT_TRUE(std::isfinite(v));
      for (float v : sl.high) ASSERT_TRUE(std::isfinite(v));
      for (const auto& e : sl.energy) {
        ASSERT_TRUE(std::isfinite(e.absorbed) && std::isfinite(e.higher_order));
        EXPECT_NEAR(e.reflected + e.higher_order + e.unscattered + e.truncated + e.absorbed, 1,
                    1e-9);
      }
      // sigma huge: only paths that never entered a fiber (external reflections off several
      // fibers) survive.
      EXPECT_LE(sl.energy[1].higher_order, sl.energy[0].higher_order);
      EXPECT_LT(sl.energy[1].higher_order, 0.1);
    }
  // Exactly along the axis the beam never meets the ply.
  auto sl = loom::simulate_ply_slice(g, y.ior, s, M_PI / 2, 0, 1);
  EXPECT_EQ(sl.energy[0].unscattered, 1.0);
}

TEST(PlyScattering, DeterministicAcrossThreadCounts) {
  loom::YarnSpec y;
  auto p = loom::ply_params_from_yarn(y);
  loom::PlySimSettings s;
  s.theta_i_count = 3, s.h_count = 3, s.rays_per_slice = 3000;
  loom::PlySimResult a, b;
  tbb::task_arena(1).execute([&] { a = loom::simulate_ply_scattering(p, y.ior, s); });
  tbb::task_arena(2).execute([&] { b = loom::simulate_ply_scattering(p, y.ior, s); });
  ASSERT_EQ(a.slices.size(), b.slices.size());
  for (size_t i = 0; i < a.slices.size(); ++i) {
    EXPECT_EQ(a.slices[i].refl, b.slices[i].refl);
    EXPECT_EQ(a.slices[i].high, b.slices[i].high);
  }
  // A different seed gives a different (but statistically equal) answer.
  s.seed = 2;
  auto c = loom::simulate_ply_scattering(p, y.ior, s);
  EXPECT_NE(a.slices[4].high, c.slices[4].high);
  EXPECT_NEAR(a.slices[4].energy[0].reflected, c.slices[4].energy[0].reflected, 0.02);
}
