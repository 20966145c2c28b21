#include "loom/aperture_diffraction.h"

#include <cerf.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "loom/shading.h"

namespace loom {

namespace {

using cd = std::complex<double>;
constexpr double kPi = 3.14159265358979323846;

/// Faddeeva's w(z) = exp(-z^2) erfc(-i z) (libcerf).
cd faddeeva(cd z) { return {re_w_of_z(z.real(), z.imag()), im_w_of_z(z.real(), z.imag())}; }

/// E(z) = exp(-gamma^2) erfc(z) for z = beta + i gamma, bounded for all z (see the header).
cd scaled_erfc(double beta, double gamma) {
  if (beta == std::numeric_limits<double>::infinity()) return 0.0;
  const double g2 = std::exp(-gamma * gamma);
  if (beta == -std::numeric_limits<double>::infinity()) return 2.0 * g2;
  const double b = std::fabs(beta);
  // exp(-beta^2) exp(-2 i beta gamma): the phase reduced with the sign of beta.
  const cd ph = std::polar(std::exp(-b * b), -2.0 * beta * gamma);
  if (beta >= 0) return ph * faddeeva(cd(-gamma, beta));  // w(i z), Im(i z) = beta >= 0
  return 2.0 * g2 - ph * faddeeva(cd(gamma, -beta));      // w(-i z), Im(-i z) = -beta > 0
}

// 16-point Gauss-Legendre nodes and weights on [-1, 1] (positive half).
constexpr double kGLx[8] = {0.0950125098376374, 0.2816035507792589, 0.4580167776572274,
                            0.6178762444026438, 0.7554044083550030, 0.8656312023878318,
                            0.9445750230732326, 0.9894009349916499};
constexpr double kGLw[8] = {0.1894506104550685, 0.1826034150449236, 0.1691565193950025,
                            0.1495959888165767, 0.1246289712555339, 0.0951585116824928,
                            0.0622535239386479, 0.0271524594117541};

cd gauss_legendre(double a, double b, double f, double w0, int panels) {
  cd sum = 0;
  const double h = (b - a) / panels;
  for (int p = 0; p < panels; ++p) {
    const double mid = a + (p + 0.5) * h, half = 0.5 * h;
    for (int k = 0; k < 8; ++k)
      for (int s = -1; s <= 1; s += 2) {
        const double x = mid + s * half * kGLx[k];
        sum += kGLw[k] * half * std::polar(std::exp(-(x / w0) * (x / w0)), -2 * kPi * f * x);
      }
  }
  return sum;
}

}  // namespace

cd gaussian_window_integral(double a, double b, double f, double w0) {
  if (!(w0 > 0) || std::isnan(a) || std::isnan(b) || !std::isfinite(f) || !(a < b)) return 0.0;
  const double width = b - a;
  if (width <= 0.5 * w0 && 2 * kPi * std::fabs(f) * width <= 8.0) {
    // Narrow interval: direct quadrature. Panels keep the Gaussian's exponent change per panel
    // at most 2 (exp of a degree-31 polynomial's worth of accuracy); past 64 panels the
    // integrand is below exp(-16000), i.e. zero in double precision anyway.
    const double far = std::max(std::fabs(a), std::fabs(b));
    const int panels = int(std::clamp(std::ceil(far * width / (w0 * w0)), 1.0, 64.0));
    return gauss_legendre(a, b, f, w0, panels);
  }
  const double gamma = kPi * f * w0;
  const cd diff = scaled_erfc(a / w0, gamma) - scaled_erfc(b / w0, gamma);
  return 0.5 * std::sqrt(kPi) * w0 * diff;
}

cd aperture_K(const Aperture& A, double fx, double fy, double w0) {
  return gaussian_window_integral(A.xw, A.xe, fx, w0) * gaussian_window_integral(A.ys, A.yn, fy, w0);
}

double aperture_intensity(const Aperture& A, double w0, double lambda_um,
                          const std::array<double, 3>& xi_i, const std::array<double, 3>& xi_o) {
  if (!(lambda_um > 0) || !std::isfinite(lambda_um)) return 0.0;
  const double fx = (xi_i[0] + xi_o[0]) / lambda_um, fy = (xi_i[1] + xi_o[1]) / lambda_um;
  if (!std::isfinite(fx) || !std::isfinite(fy)) return 0.0;
  const shading::vec3 vi{float(xi_i[0]), float(xi_i[1]), float(xi_i[2])};
  const shading::vec3 vo{float(xi_o[0]), float(xi_o[1]), float(xi_o[2])};
  const double obliquity = shading::diffraction_obliquity(vi, vo);
  return obliquity * std::norm(aperture_K(A, fx, fy, w0)) / (lambda_um * lambda_um);
}

double beam_power(double w0) { return 0.5 * kPi * w0 * w0; }

double aperture_power(const Aperture& A, double w0) {
  // int_a^b exp(-2 x^2 / w0^2) dx = w0 sqrt(pi / 8) [erf(sqrt2 b / w0) - erf(sqrt2 a / w0)].
  auto axis = [&](double a, double b) {
    if (!(a < b)) return 0.0;
    const double s = std::sqrt(2.0) / w0;
    return w0 * std::sqrt(kPi / 8.0) * (std::erf(s * b) - std::erf(s * a));
  };
  return axis(A.xw, A.xe) * axis(A.ys, A.yn);
}

Aperture ply_edge_aperture(double R, double h, double d_cut) {
  return {R - std::fabs(h), d_cut, -d_cut, d_cut};
}

}  // namespace loom
