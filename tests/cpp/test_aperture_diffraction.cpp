// Gaussian-beam aperture diffraction (Eq. S.34, S.35): the closed form against direct quadrature,
// its limits, Parseval, the extremes; the RGB tables against an independent spectral sum.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <complex>

#include "loom/aperture_diffraction.h"
#include "loom/diffraction_tables.h"
#include "loom/shading.h"
#include "loom/spectrum.h"
#include "test_util.h"

namespace {

using cd = std::complex<double>;
constexpr double kPi = 3.14159265358979323846;

/// Composite Simpson quadrature of int_a^b exp(-x^2/w^2) exp(-2 pi i f x) dx with n steps.
cd simpson(double a, double b, double f, double w, int n) {
  const double h = (b - a) / n;
  cd sum = 0;
  for (int k = 0; k <= n; ++k) {
    const double x = a + k * h;
    const double wk = (k == 0 || k == n) ? 1 : (k % 2 ? 4 : 2);
    sum += wk * std::exp(-(x / w) * (x / w)) * std::exp(cd(0, -2 * kPi * f * x));
  }
  return sum * h / 3.0;
}

/// J by direct quadrature, written out here independently of the library: infinite or far
/// bounds clipped at 12 w (exp(-144) ~ 3e-63); Simpson at >= 64 steps per beam waist and per
/// period of the phase, and at half that step, combined by one Richardson step (Boole's rule,
/// error O(h^6), about 1e-9 of the integrand's scale here).
cd simpson_J(double a, double b, double f, double w) {
  a = std::max(a, -12 * w), b = std::min(b, 12 * w);
  if (!(a < b)) return 0.0;
  const double h_max = 1.0 / (64.0 * std::max(1.0 / w, std::fabs(f)));
  int n = int(std::ceil((b - a) / h_max));
  n += n % 2;
  n = std::max(n, 2);
  return (16.0 * simpson(a, b, f, w, 2 * n) - simpson(a, b, f, w, n)) / 15.0;
}

TEST(ApertureDiffraction, KMatchesDirectQuadratureOfS34) {
  const double inf = INFINITY;
  const loom::Aperture apertures[] = {
      {-5, 5, -5, 5},    {0, 10, 0, 10},  // Eq. S.36's A_1 and A_2
      {-3, 20, -1, 2},   {2, 2.5, -40, -39.7},  // off-centre, narrow (the quadrature branch)
      {4, inf, -inf, 3}, {-30, 30, -0.01, 0.01}};
  double worst = 0;
  for (const auto& A : apertures)
    for (double w : {2.0, 10.0, 50.0})
      for (double fx : {0.0, 0.013, 0.1, -0.37, 1.0, 2.5})
        for (double fy : {0.0, 0.05, -1.3}) {
          const cd K = loom::aperture_K(A, fx, fy, w);
          const cd Kq = simpson_J(A.xw, A.xe, fx, w) * simpson_J(A.ys, A.yn, fy, w);
          // The quadrature is accurate to ~1e-9 of the integrand's scale; K <= pi w^2.
          const double err = std::abs(K - Kq) / (kPi * w * w);
          worst = std::max(worst, err);
          EXPECT_LT(err, 1e-8) << "A=(" << A.xw << "," << A.xe << "," << A.ys << "," << A.yn
                               << ") w=" << w << " f=(" << fx << "," << fy << ") K=" << K
                               << " quadrature=" << Kq;
        }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", worst);
  RecordProperty("worst_relative_error", buf);
}

TEST(ApertureDiffraction, WideBeamGivesThePlainRectangleSinc) {
  // w0 -> infinity: the window is flat over the aperture and J = int_a^b exp(-2 pi i f x) dx.
  const double w = 1e6, a = -3, b = 7;
  for (double f : {0.0, 0.01, 0.2, 0.75, 3.0}) {
    const cd J = loom::gaussian_window_integral(a, b, f, w);
    const cd ref = f == 0 ? cd(b - a)
                          : (std::exp(cd(0, -2 * kPi * f * a)) - std::exp(cd(0, -2 * kPi * f * b))) /
                                cd(0, 2 * kPi * f);
    EXPECT_LT(std::abs(J - ref), 1e-8 * (b - a)) << "f=" << f;
  }
}

TEST(ApertureDiffraction, UnboundedApertureGivesAGaussian) {
  // The Fourier transform of exp(-x^2/w^2): w sqrt(pi) exp(-(pi f w)^2).
  for (double w : {0.5, 10.0, 300.0})
    for (double f : {0.0, 0.01, 0.05, 0.2, 1.0}) {
      const cd J = loom::gaussian_window_integral(-INFINITY, INFINITY, f, w);
      const double ref = w * std::sqrt(kPi) * std::exp(-std::pow(kPi * f * w, 2));
      EXPECT_NEAR(J.real(), ref, 1e-12 * w) << "w=" << w << " f=" << f;
      EXPECT_NEAR(J.imag(), 0.0, 1e-12 * w);
    }
}

TEST(ApertureDiffraction, ParsevalPowerThroughTheAperture) {
  // int |J(f)|^2 df = int_a^b exp(-2 x^2 / w^2) dx: the far field carries exactly the power the
  // aperture lets through. Trapezoid over f in [-F, F] plus the hard edges' 1/f^2 tails.
  const double w = 10;
  for (auto [a, b] : {std::pair{-5.0, 5.0}, {0.0, 10.0}, {-2.0, 31.0}, {-INFINITY, 4.0}}) {
    const double F = 40, df = 1e-3;
    double sum = 0;
    for (double f = -F; f <= F; f += df) sum += std::norm(loom::gaussian_window_integral(a, b, f, w));
    sum *= df;
    // Tails beyond |f| = F: each finite edge e contributes about exp(-2 e^2/w^2) / (4 pi^2 f^2)
    // on both sides, i.e. 2 exp(-2 e^2 / w^2) / (4 pi^2 F) in total.
    double tail = 0;
    for (double e : {a, b})
      if (std::isfinite(e)) tail += 2 * std::exp(-2 * e * e / (w * w)) / (4 * kPi * kPi * F);
    const loom::Aperture A{a, b, -INFINITY, INFINITY};
    const double power_x = loom::aperture_power(A, w) / (w * std::sqrt(kPi / 2));
    EXPECT_NEAR(sum + tail, power_x, 2e-4 * power_x) << "[" << a << ", " << b << "]";
  }
}

TEST(ApertureDiffraction, BranchesAgreeAtTheNarrowIntervalBoundary) {
  // The Gauss-Legendre branch takes intervals up to w/2 wide; just past it the closed form
  // takes over. The two must agree to double precision on either side.
  const double w = 10;
  for (double a : {-2.5, 0.0, 7.0, 30.0})
    for (double f : {0.0, 0.1, 0.25}) {
      const cd below = loom::gaussian_window_integral(a, a + 0.5 * w, f, w);
      const cd above = loom::gaussian_window_integral(a, a + 0.5 * w * (1 + 1e-12), f, w);
      EXPECT_LT(std::abs(below - above), 1e-11 * w) << "a=" << a << " f=" << f;
    }
}

TEST(ApertureDiffraction, FiniteAtTheExtremes) {
  const double inf = INFINITY, nan = NAN;
  const double bounds[] = {-inf, -1e9, -1e3, -1e-9, 0, 1e-9, 1e-6, 1e3, 1e9, inf};
  const double waists[] = {1e-3, 1.0, 1e6};
  const double freqs[] = {0, 1e-9, 1e-3, 1, 1e3, 1e6, -1e6};
  int n = 0;
  for (double a : bounds)
    for (double b : bounds)
      for (double w : waists)
        for (double f : freqs) {
          const cd J = loom::gaussian_window_integral(a, b, f, w);
          ASSERT_TRUE(std::isfinite(J.real()) && std::isfinite(J.imag()))
              << "a=" << a << " b=" << b << " w=" << w << " f=" << f;
          // |J| <= int exp(-x^2/w^2) = w sqrt(pi).
          ASSERT_LE(std::abs(J), w * std::sqrt(kPi) * (1 + 1e-9));
          ++n;
        }
  EXPECT_EQ(n, 10 * 10 * 3 * 7);
  for (double x : {nan, inf}) {
    EXPECT_EQ(loom::gaussian_window_integral(nan, 1, 0.1, 10), cd(0));
    EXPECT_EQ(loom::gaussian_window_integral(-1, 1, x, 10), cd(0));
    EXPECT_EQ(loom::gaussian_window_integral(-1, 1, 0.1, x == inf ? 0.0 : nan), cd(0));
  }
  // Grazing and degenerate directions, wavelengths at the ends of the visible range.
  const loom::Aperture A{-5, 5, -5, 5};
  for (double lambda : {0.38, 0.78})
    for (auto wo : {std::array<double, 3>{1, 0, 0}, {0, 1, -1e-6}, {0.6, 0.8, 0}, {0, 0, -1}}) {
      const double I = loom::aperture_intensity(A, 10, lambda, {0, 0, 1}, wo);
      EXPECT_TRUE(std::isfinite(I) && I >= 0);
    }
  EXPECT_EQ(loom::aperture_intensity(A, 10, nan, {0, 0, 1}, {0, 0, -1}), 0.0);
  EXPECT_EQ(loom::aperture_intensity(A, 10, 0.5, {nan, 0, 1}, {0, 0, -1}), 0.0);
}

/// Mean saturation 1 - min/max of the RGB pattern over the fringes (0.08 <= |s| , s in
/// [0, 0.4]^2), each direction counted once.
double fringe_saturation(const loom::Aperture& A, double w0, const loom::SpectralRgb& rgb) {
  double sum = 0;
  int n = 0;
  for (double sx = 0; sx <= 0.4; sx += 0.01)
    for (double sy = 0; sy <= 0.4; sy += 0.01) {
      if (std::hypot(sx, sy) < 0.08) continue;
      double c[3] = {0, 0, 0};
      for (size_t k = 0; k < rgb.lambda_nm.size(); ++k) {
        const double l = rgb.lambda_nm[k] * 1e-3;
        const double I = std::norm(loom::aperture_K(A, sx / l, sy / l, w0)) / (l * l);
        for (int j = 0; j < 3; ++j) c[j] += rgb.weight[k][size_t(j)] * I;
      }
      for (double& v : c) v = std::max(v, 0.0);
      const double mx = std::max({c[0], c[1], c[2]}), mn = std::min({c[0], c[1], c[2]});
      if (mx <= 0) continue;
      sum += 1 - mn / mx;
      ++n;
    }
  return sum / n;
}

TEST(ApertureDiffraction, CentredBeamGivesMoreSaturatedFringesSection42) {
  // Eq. S.36: same 10 x 10 um size, beam through the centre (A_1) or the corner (A_2), w0 = 10.
  // Section 4.2: the patterns look alike but A_1's colours are much more saturated.
  const loom::ColourConverter cc;
  const auto rgb = loom::spectral_rgb(cc, 10);
  const double s1 = fringe_saturation({-5, 5, -5, 5}, 10, rgb);
  const double s2 = fringe_saturation({0, 10, 0, 10}, 10, rgb);
  RecordProperty("saturation_A1", std::to_string(s1));
  RecordProperty("saturation_A2", std::to_string(s2));
  EXPECT_GT(s1, s2 + 0.05) << "A_1 " << s1 << " A_2 " << s2;
}

TEST(ApertureDiffraction, PlyEdgeApertureOfSection43) {
  // h = R - d_cut / 4: the beam's right quarter passes, [R - h, d_cut] = [d_cut/4, d_cut].
  const loom::Aperture A = loom::ply_edge_aperture(100, 100 - 7.5, 30);
  EXPECT_DOUBLE_EQ(A.xw, 7.5);
  EXPECT_DOUBLE_EQ(A.xe, 30);
  EXPECT_DOUBLE_EQ(A.ys, -30);
  EXPECT_DOUBLE_EQ(A.yn, 30);
  // Mirror-symmetric in h.
  const loom::Aperture B = loom::ply_edge_aperture(100, -(100 - 7.5), 30);
  EXPECT_DOUBLE_EQ(B.xw, A.xw);
  namespace sh = loom::shading;
  EXPECT_NEAR(sh::diffraction_edge_param(92.5f, 100.0f, 30.0f), 0.25f, 1e-6f);
  EXPECT_NEAR(sh::diffraction_edge_param(-92.5f, 100.0f, 30.0f), 0.25f, 1e-6f);
}

/// The RGB table entry recomputed from Eq. S.35 through aperture_intensity (the probe's path)
/// and the spectral weights: an independent route to what fill_tile computes per axis.
std::array<double, 3> direct_D(const loom::Aperture& A, double w0, double sx, double sy,
                               const loom::SpectralRgb& rgb) {
  // Directions with xi_i + xi_o = (sx, sy) and |xi_i.z| + |xi_o.z| = 2 so that the obliquity
  // factor is 1: not unit vectors, which Eq. S.35 does not need for this identity.
  std::array<double, 3> d{0, 0, 0};
  for (size_t k = 0; k < rgb.lambda_nm.size(); ++k) {
    const double I = loom::aperture_intensity(A, w0, rgb.lambda_nm[k] * 1e-3, {sx, sy, 1},
                                              {0, 0, -1});
    for (int c = 0; c < 3; ++c) d[size_t(c)] += rgb.weight[k][size_t(c)] * I / loom::beam_power(w0);
  }
  return d;
}

TEST(DiffractionTables, TexelsMatchTheSpectralSumOfS35) {
  const loom::ColourConverter cc;
  const auto rgb = loom::spectral_rgb(cc, 10);
  loom::DiffractionSettings s{17, 10, 3, 4};
  const double gx = 12, gy = 20, w0 = 10;
  const auto gap = loom::diffraction_gap_table(gx, gy, w0, rgb, s);
  const auto edge = loom::diffraction_edge_table(w0, rgb, s);
  ASSERT_EQ(gap.width(), 3 * 17);
  ASSERT_EQ(gap.height(), 3 * 17);
  ASSERT_EQ(edge.width(), 4 * 17);
  namespace sh = loom::shading;
  for (int tile : {0, 4, 8})
    for (int u : {0, 3, 16})
      for (int r : {0, 7, 16}) {
        const int i = tile % 3, j = tile / 3;
        // Tile k holds the offset (1 - (1 - k / 2)^2) g / 2 (diffraction_tile_coord).
        const double cx = (1 - (1 - i / 2.0) * (1 - i / 2.0)) * gx / 2;
        const double cy = (1 - (1 - j / 2.0) * (1 - j / 2.0)) * gy / 2;
        const loom::Aperture A{-gx / 2 - cx, gx / 2 - cx, -gy / 2 - cy, gy / 2 - cy};
        const auto d = direct_D(A, w0, sh::diffraction_table_s(u / 16.0f),
                                sh::diffraction_table_s(r / 16.0f), rgb);
        const float* px = gap.px(i * 17 + u, j * 17 + r);
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(px[c], std::max(d[size_t(c)], 0.0), 1e-5 * std::max(d[size_t(c)], 1e-3))
              << "tile " << tile << " u " << u << " r " << r << " c " << c;
      }
  const double d_cut = LOOM_DIFFRACTION_DCUT_WAISTS * w0;
  for (int j : {0, 2, 3})
    for (int u : {0, 5}) {
      const loom::Aperture A{j / 3.0 * d_cut, d_cut, -d_cut, d_cut};
      const auto d = direct_D(A, w0, sh::diffraction_table_s(u / 16.0f), 0.0, rgb);
      const float* px = edge.px(j * 17 + u, 0);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(px[c], std::max(d[size_t(c)], 0.0), 1e-5 * std::max(d[size_t(c)], 1e-3));
    }
  // The last edge tile is a closed aperture.
  EXPECT_EQ(edge.px(3 * 17 + 0, 0)[1], 0.0f);
}

TEST(DiffractionTables, IntegralOverDirectionsIsThePowerThroughTheGap) {
  // At normal incidence s = xi_o.xy and d omega = ds / |xi_o.z|, so the transmitted share of the
  // beam is int obliquity D / |cos| ds. Parseval says it equals aperture_power / beam_power for
  // every channel (the pattern's colours redistribute energy but white in gives white out).
  const loom::ColourConverter cc;
  const auto rgb = loom::spectral_rgb(cc, 10);
  const int N = 129;
  loom::DiffractionSettings s{N, 10, 1, 2};
  const double g = 10, w0 = 10;
  const auto gap = loom::diffraction_gap_table(g, g, w0, rgb, s);
  namespace sh = loom::shading;
  // Trapezoid over the table's own samples in t, ds = 4 t dt per axis (s = 2 t^2), x 4 quadrants,
  // restricted to the unit disk of real outgoing directions.
  double sum[3] = {0, 0, 0};
  const double dt = 1.0 / (N - 1);
  for (int r = 0; r < N; ++r)
    for (int u = 0; u < N; ++u) {
      const double tx = u * dt, ty = r * dt;
      const double sx = sh::diffraction_table_s(float(tx)), sy = sh::diffraction_table_s(float(ty));
      const double s2 = sx * sx + sy * sy;
      if (s2 >= 1) continue;
      const double cz = std::sqrt(1 - s2);
      const double obl = 0.25 * (1 + cz) * (1 + cz);
      const double wt = (u == 0 ? 0.5 : 1.0) * (r == 0 ? 0.5 : 1.0) * 4 * tx * dt * 4 * ty * dt * 4;
      for (int c = 0; c < 3; ++c) sum[c] += wt * obl * gap.px(u, r)[c] / cz;
    }
  const loom::Aperture A{-g / 2, g / 2, -g / 2, g / 2};
  const double expect = loom::aperture_power(A, w0) / loom::beam_power(w0);
  // Left out: the tails beyond the unit disk (hard-edge 1/f^2 tails, about 0.5 % of the power
  // here), and the sqrt warp's trapezoid error at the peak (N = 129: well under 1 %).
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c], expect, 0.015 * expect) << "channel " << c;
}

TEST(ApertureDiffraction, ProbeAnswersAndRejectsBadInput) {
  std::string out;
  const std::string exe = loom::test::bake_exe();
  ASSERT_EQ(loom::test::run(exe + " eval diffraction --aperture 0,10,-inf,5 --waist 8 "
                                  "--lambda 450 --wi 0.1,0,1 --wo 0.2,0.05,-1",
                            &out),
            0)
      << out;
  const auto j = nlohmann::json::parse(out);
  // The probe normalises the directions; recompute from the same unit vectors.
  const double ni = std::hypot(0.1, 1.0), no = std::hypot(0.2, 0.05, 1.0);
  const std::array<double, 3> wi{0.1 / ni, 0, 1 / ni}, wo{0.2 / no, 0.05 / no, -1 / no};
  const double l = 0.45;
  const loom::Aperture A{0, 10, -INFINITY, 5};
  const cd K = simpson_J(0, 10, (wi[0] + wo[0]) / l, 8) * simpson_J(-INFINITY, 5, wo[1] / l, 8);
  EXPECT_NEAR(j["K"][0].get<double>(), K.real(), 1e-8 * kPi * 64);
  EXPECT_NEAR(j["K"][1].get<double>(), K.imag(), 1e-8 * kPi * 64);
  const double a = std::fabs(wi[2]) + std::fabs(wo[2]);
  EXPECT_NEAR(j["intensity"].get<double>(), a * a / (4 * l * l) * std::norm(K),
              1e-6 * j["intensity"].get<double>());
  EXPECT_DOUBLE_EQ(j["intensity"].get<double>(), loom::aperture_intensity(A, 8, l, wi, wo));
  for (const char* bad : {"--aperture 5,0,0,1 --wi 0,0,1 --wo 0,0,-1",
                          "--aperture 0,1,0 --wi 0,0,1 --wo 0,0,-1",
                          "--aperture 0,1,0,1 --wi 0,0,0 --wo 0,0,-1",
                          "--aperture 0,1,0,1 --wi 0,0,1 --wo 0,0,-1 --waist 0",
                          "--aperture 0,1,0,1 --wi 0,0,1 --wo 0,0,-1 --lambda nan"}) {
    EXPECT_NE(loom::test::run(exe + " eval diffraction " + bad + " 2>&1", &out), 0) << bad;
    EXPECT_NE(out.find("--"), std::string::npos) << bad << ": " << out;
  }
}

TEST(Spectrum, WhiteSpectrumIsWhiteAndMatchingFunctionsPeakWhereCieDoes) {
  const loom::ColourConverter cc;
  const auto rgb = loom::spectral_rgb(cc, 5);
  double sum[3] = {0, 0, 0};
  for (auto& w : rgb.weight)
    for (int c = 0; c < 3; ++c) sum[c] += w[size_t(c)];
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c], 1.0, 1e-12);
  // CIE 1931: y-bar = 1 at 555 nm (luminous efficiency); x-bar's main peak 1.06 near 600 nm,
  // z-bar's 1.78 near 445 nm. The Wyman et al. fit is within 2 % there.
  EXPECT_NEAR(loom::cie1931_cmf(555)[1], 1.0, 0.02);
  EXPECT_NEAR(loom::cie1931_cmf(600)[0], 1.0622, 0.02);
  EXPECT_NEAR(loom::cie1931_cmf(445)[2], 1.7826, 0.04);
  // The XYZ to Rec.709 matrix maps D65's white point (0.9505, 1, 1.089) to (1, 1, 1).
  const auto M = cc.xyz_to_linear_matrix();
  const double wp[3] = {0.95047, 1.0, 1.08883};
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(M[size_t(c)][0] * wp[0] + M[size_t(c)][1] * wp[1] + M[size_t(c)][2] * wp[2], 1.0, 1e-3);
}

}  // namespace
