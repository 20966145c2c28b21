#include "loom/cycles_closures.h"

#include <algorithm>
#include <cmath>

namespace loom::cycles {

using shading::cross;
using shading::length;
using shading::dot;
using shading::normalize;

float bump_shadowing_term(vec3 Ng, vec3 N, vec3 I) {
  const float cosNI = dot(N, I);
  if (cosNI < 0.0f) Ng = -Ng;
  float den = cosNI * dot(Ng, N);
  float g = den != 0.0f ? dot(Ng, I) / den : 0.0f;  // safe_divide
  if (g >= 1.0f) return 1.0f;
  if (g < 0.0f) return 0.0f;
  float g2 = g * g;  // smoothing: SD_USE_BUMP_MAP_CORRECTION is on by default
  return -g2 * g + g2 + g;
}

namespace {
bool isequal(vec3 a, vec3 b) { return a.x == b.x && a.y == b.y && a.z == b.z; }
}  // namespace

float diffuse_eval(vec3 N, vec3 L, vec3 Ns) {
  float e = std::max(dot(N, L), 0.0f) / float(M_PI);
  return isequal(N, Ns) ? e : e * bump_shadowing_term(Ns, N, L);
}
float translucent_eval(vec3 N, vec3 L, vec3 Ns) {
  float e = std::max(-dot(N, L), 0.0f) / float(M_PI);
  return isequal(N, Ns) ? e : e * bump_shadowing_term(Ns, N, L);
}

vec3 ensure_valid_specular_reflection(vec3 Ng, vec3 I, vec3 N) {
  if (isequal(Ng, N)) return N;
  const vec3 R = N * (2 * dot(N, I)) - I;
  const float Iz = dot(I, Ng);
  const float threshold = std::min(0.9f * Iz, 0.01f);
  if (dot(Ng, R) >= threshold) return N;
  vec3 X = N - Ng * dot(N, Ng);
  X = length(X) > 0 ? normalize(X) : N;  // safe_normalize_fallback
  const float Ix = dot(I, X);
  const float a = Ix * Ix + Iz * Iz;
  const float b = 2.0f * (a + Iz * threshold);
  const float c = (threshold + Iz) * (threshold + Iz);
  auto safe_sqrt = [](float x) { return std::sqrt(std::max(x, 0.0f)); };
  const float Nz2 = (Ix < 0) ? 0.25f * (b + safe_sqrt(b * b - 4.0f * a * c)) / a
                             : 0.25f * (b - safe_sqrt(b * b - 4.0f * a * c)) / a;
  const float Nx = safe_sqrt(1.0f - Nz2), Nz = safe_sqrt(Nz2);
  return X * Nx + Ng * Nz;
}

namespace {
// Cycles: bsdf_lambda_from_sqr_alpha_tan_n for GGX (Heitz 2014, Eq. 72).
float ggx_lambda(float ax, float ay, vec3 v) {
  float s = (ax * ax * v.x * v.x + ay * ay * v.y * v.y) / (v.z * v.z);
  return 0.5f * (std::sqrt(1.0f + s) - 1.0f);
}
// Cycles: make_orthonormals_tangent(N, T, &X, &Y): Y = normalize(cross(N, T)), X = cross(Y, N).
void orthonormals_tangent(vec3 N, vec3 T, vec3& X, vec3& Y) {
  Y = normalize(cross(N, T));
  X = cross(Y, N);
}
}  // namespace

float ggx_eval(vec3 N, vec3 T, float alpha_x, float alpha_y, vec3 Ng, vec3 I, vec3 L) {
  float ax = std::clamp(alpha_x, 0.0f, 1.0f), ay = std::clamp(alpha_y, 0.0f, 1.0f);
  float cos_NI = dot(N, I), cos_NO = dot(N, L), cos_NgO = dot(Ng, L);
  bool is_transmission = cos_NO < 0.0f;
  if (cos_NI <= 0 || ax * ay <= 5e-7f || (cos_NgO < 0.0f) != is_transmission || is_transmission)
    return 0.0f;
  vec3 H = normalize(I + L);
  float D, lI, lO;
  if (ax == ay) {
    float a2 = ax * ay, c2 = dot(N, H) * dot(N, H);
    D = a2 / (float(M_PI) * (1 + (a2 - 1) * c2) * (1 + (a2 - 1) * c2));
    vec3 X, Y;
    orthonormals_tangent(N, std::fabs(N.z) < 0.9f ? vec3(0, 0, 1) : vec3(1, 0, 0), X, Y);
    lI = ggx_lambda(ax, ay, {dot(X, I), dot(Y, I), cos_NI});
    lO = ggx_lambda(ax, ay, {dot(X, L), dot(Y, L), cos_NO});
  } else {
    vec3 X, Y;
    orthonormals_tangent(N, T, X, Y);
    vec3 h{dot(X, H) / ax, dot(Y, H) / ay, dot(N, H)};
    float l2 = dot(h, h);
    D = 1.0f / (float(M_PI) * ax * ay * l2 * l2);
    lI = ggx_lambda(ax, ay, {dot(X, I), dot(Y, I), cos_NI});
    lO = ggx_lambda(ax, ay, {dot(X, L), dot(Y, L), cos_NO});
  }
  return D / cos_NI * 0.25f / (1.0f + lI + lO);
}

}  // namespace loom::cycles
