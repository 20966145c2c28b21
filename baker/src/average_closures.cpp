// The repeat-averaged closures as Cycles evaluates them and as the shaders read them from the
// table (average_closures.h; the fit is average_fit.cpp).
#include <algorithm>
#include <cmath>

#include "loom/average_fit.h"
#include "loom/evaluator.h"

namespace loom {

using namespace shading;

namespace {

const vec3 kN(0, 0, 1), kT(1, 0, 0);
// The lobe quadrature of albedo(): polar x azimuth samples (within 1 % of a fine sphere grid,
// AverageClosures.AlbedoMatchesASphereQuadrature).
constexpr int kLobeN = 24, kLobeM = 24;

/// int f(L) dL over the sphere for f concentrated about direction c (width ~ a): polar angle
/// theta = a tan(zeta) about c, zeta uniform (n), azimuth uniform (m).
template <class F>
double lobe_integral(vec3 c, double a, int n, int m, F f) {
  const vec3 e1 = std::fabs(c.z) < 0.9f ? normalize(cross(c, vec3(0, 0, 1)))
                                        : normalize(cross(c, vec3(1, 0, 0)));
  const vec3 e2 = cross(c, e1);
  const double z1 = std::atan(M_PI / a);
  double sum = 0;
  for (int k = 0; k < n; ++k) {
    const double zeta = (k + 0.5) * z1 / n;
    const double th = std::min(a * std::tan(zeta), M_PI);
    const double dth = a / (std::cos(zeta) * std::cos(zeta)) * z1 / n;
    const double w = std::sin(th) * dth * 2.0 * M_PI / m;
    for (int j = 0; j < m; ++j) {
      const double ph = (j + 0.5) * 2.0 * M_PI / m;
      const vec3 L = c * float(std::cos(th)) +
                     (e1 * float(std::cos(ph)) + e2 * float(std::sin(ph))) * float(std::sin(th));
      sum += f(L) * w;
    }
  }
  return sum;
}

}  // namespace

AverageClosureSet::AverageClosureSet(const AverageClosures& p, vec3 V)
    : p_(p),
      V_(V),
      g_(kN, kT, p.alpha[0], p.alpha[1], kN, V, cycles::Distribution::GGX),
      r_(V, p.alpha[2], float(LOOM_AVERAGE_ETA), kN, V, cycles::Distribution::GGX) {}

float AverageClosureSet::basis(int p, vec3 L) const {
  switch (p) {
    case 0: return cycles::diffuse_eval(kN, L, kN);
    case 1: return cycles::translucent_eval(kN, L, kN);
    case 2: return g_.eval(L);
    default: return r_.eval(L);
  }
}

std::array<float, 3> AverageClosureSet::eval(vec3 L) const {
  std::array<float, 3> f{};
  for (int p = 0; p < kAverageClosures; ++p) {
    const auto& w = p_.w[size_t(p)];
    if (w[0] == 0 && w[1] == 0 && w[2] == 0) continue;
    const float b = basis(p, L);
    for (size_t c = 0; c < 3; ++c) f[c] += w[c] * b;
  }
  return f;
}

double AverageClosureSet::albedo(int p) const {
  if (p < 2) return 1.0;  // diffuse(N), translucent(N): exactly their weights
  if (p == 3)  // about its normal V: straight through
    return lobe_integral(-V_, std::max(double(p_.alpha[2]), 0.01), kLobeN, kLobeM,
                         [&](vec3 L) { return basis(3, L); });
  const vec3 R = kN * (2 * dot(V_, kN)) - V_;  // the mirror direction
  // (a GGX lobe is about twice its alpha wide in the light direction)
  return lobe_integral(R, std::max(double(p_.alpha[0] + p_.alpha[1]), 0.01), kLobeN, kLobeM,
                       [&](vec3 L) { return basis(2, L); });
}

AverageClosures read_average_closures(const Image& table, vec3 wo) {
  const bool back = wo.z < 0;
  const vec3 V = average_mirror(wo, back);
  AverageClosures a;
  for (int p = 0; p < kAverageClosures; ++p) {
    float s, tv, px[4];
    average_closures_uv(V, back ? 1.0f : 0.0f, float(p), s, tv);
    bilinear(table, s, tv, px);
    a.w[size_t(p)] = {px[0], px[1], px[2]};
    a.alpha[size_t(p)] = px[3];
  }
  return a;
}

std::array<float, 3> average_closures_eval(const Image& table, vec3 wo, vec3 L) {
  const bool back = wo.z < 0;
  const AverageClosureSet c(read_average_closures(table, wo),
                            normalize(average_mirror(wo, back)));
  return c.eval(average_mirror(L, back));
}

}  // namespace loom
