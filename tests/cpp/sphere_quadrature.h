// Plain quadratures over the sphere, the independent reference the tests integrate against.
#pragma once
#include <algorithm>
#include <cmath>

#include "loom/shading.h"

namespace loom_test {

/// The unit vector at polar angle theta from +z and azimuth phi from +x.
inline loom::shading::vec3 sph(double theta, double phi) {
  return {float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)),
          float(std::cos(theta))};
}

/// Midpoint quadrature of f over the whole sphere in (cos theta, phi): n x 2n cells.
template <class F>
double sphere_integral(F f, int n) {
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double z = -1 + (i + 0.5) * 2.0 / n, r = std::sqrt(std::max(0.0, 1 - z * z));
    for (int j = 0; j < 2 * n; ++j) {
      const double p = (j + 0.5) * M_PI / n;
      sum += f(loom::shading::vec3{float(r * std::cos(p)), float(r * std::sin(p)), float(z)});
    }
  }
  return sum * (2.0 / n) * (M_PI / n);
}

}  // namespace loom_test
