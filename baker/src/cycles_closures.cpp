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

MicrofacetReflection::MicrofacetReflection(vec3 N, vec3 T, float alpha_x, float alpha_y, vec3 Ng,
                                           vec3 I, Distribution d)
    : N_(N), Ng_(Ng), I_(I), d_(d) {
  ax_ = std::clamp(alpha_x, 0.0f, 1.0f);
  ay_ = std::clamp(alpha_y, 0.0f, 1.0f);
  cos_NI_ = dot(N, I);
  valid_ = cos_NI_ > 0 && ax_ * ay_ > 5e-7f;
  // Isotropic closures use any frame about N (their Lambda only needs tan^2); anisotropic ones
  // the frame of the tangent.
  orthonormals_tangent(N, ax_ == ay_ ? (std::fabs(N.z) < 0.9f ? vec3(0, 0, 1) : vec3(1, 0, 0)) : T,
                       X_, Y_);
  lambda_I_ = valid_ ? lambda({dot(X_, I), dot(Y_, I), cos_NI_}) : 0.0f;
}

float MicrofacetReflection::lambda(vec3 v) const {
  if (d_ == Distribution::GGX) return ggx_lambda(ax_, ay_, v);
  const float t = (ax_ * ax_ * v.x * v.x + ay_ * ay_ * v.y * v.y) / (v.z * v.z);
  if (!(t >= 0.39f)) return 0.0f;
  const float a = 1.0f / std::sqrt(t);
  return ((0.396f * a - 1.259f) * a + 1.0f) / ((2.181f * a + 3.535f) * a);
}

float MicrofacetReflection::eval(vec3 L) const {
  float cos_NO = dot(N_, L), cos_NgO = dot(Ng_, L);
  bool is_transmission = cos_NO < 0.0f;
  if (!valid_ || (cos_NgO < 0.0f) != is_transmission || is_transmission) return 0.0f;
  vec3 H = normalize(I_ + L);
  vec3 h{dot(X_, H) / ax_, dot(Y_, H) / ay_, dot(N_, H)};
  float D;
  if (d_ == Distribution::GGX) {
    // Anisotropic D (bsdf_aniso_D); for ax == ay it equals the isotropic bsdf_D.
    float l2 = dot(h, h);
    D = 1.0f / (float(M_PI) * ax_ * ay_ * l2 * l2);
  } else {
    float c2 = h.z * h.z;
    D = std::exp(-(h.x * h.x + h.y * h.y) / c2) / (float(M_PI) * ax_ * ay_ * c2 * c2);
  }
  float lO = lambda({dot(X_, L), dot(Y_, L), cos_NO});
  return D / cos_NI_ * 0.25f / (1.0f + lambda_I_ + lO);
}

MicrofacetRefraction::MicrofacetRefraction(vec3 N, float alpha, float eta, vec3 Ng, vec3 I,
                                           Distribution d)
    : N_(N), Ng_(Ng), I_(I), d_(d) {
  a_ = std::clamp(alpha, 0.0f, 1.0f);
  eta_ = eta;
  cos_NI_ = dot(N, I);
  valid_ = cos_NI_ > 0 && a_ * a_ > 5e-7f && eta > 0;
  lambda_I_ = valid_ ? lambda(cos_NI_) : 0.0f;
}

float MicrofacetRefraction::lambda(float cos_n) const {
  // bsdf_lambda: sqr_alpha_tan_n = alpha^2 max(1 / cos^2 - 1, 0)
  const float t = a_ * a_ * std::max(1.0f / (cos_n * cos_n) - 1.0f, 0.0f);
  if (d_ == Distribution::GGX) return 0.5f * (std::sqrt(1.0f + t) - 1.0f);
  if (!(t >= 0.39f)) return 0.0f;
  const float a = 1.0f / std::sqrt(t);
  return ((0.396f * a - 1.259f) * a + 1.0f) / ((2.181f * a + 3.535f) * a);
}

float MicrofacetRefraction::eval(vec3 L) const {
  const float cos_NO = dot(N_, L);
  if (!valid_ || cos_NO >= 0.0f || dot(Ng_, L) >= 0.0f) return 0.0f;
  vec3 H = -(L * eta_ + I_);
  const float len = length(H);
  const float inv_len = len > 0 ? 1.0f / len : 0.0f;  // safe_divide
  H = H * inv_len;
  const float cos_NH = dot(N_, H);
  const float c2 = std::min(cos_NH * cos_NH, 1.0f), a2 = a_ * a_;
  float D;
  if (d_ == Distribution::GGX) {
    D = a2 / (float(M_PI) * (1.0f - c2 + a2 * c2) * (1.0f - c2 + a2 * c2));
  } else {
    D = 1.0f / (std::exp((1.0f - c2) / (c2 * a2)) * float(M_PI) * a2 * c2 * c2);
  }
  if (!std::isfinite(D)) return 0.0f;
  const float common = D / cos_NI_ * (eta_ * inv_len) * (eta_ * inv_len) *
                       std::fabs(dot(H, I_) * dot(H, L));
  return common / (1.0f + lambda_I_ + lambda(cos_NO));
}

HairLobe::HairLobe(vec3 N, vec3 T, float roughness1, float roughness2, float offset, vec3 I,
                   bool transmission)
    : N_(N), T_(T), offset_(offset), transmission_(transmission) {
  r1_ = std::clamp(roughness1, 0.001f, 1.0f);
  r2_ = std::clamp(roughness2, 0.001f, 1.0f);
  const float Iz = dot(T, I);
  locy_ = normalize(I - T * Iz);
  theta_r_ = float(M_PI_2) - std::acos(std::clamp(Iz, -1.0f, 1.0f));
  a_ = std::atan(((float(M_PI_2) + theta_r_) * 0.5f - offset) / r1_);
  b_ = std::atan(((-float(M_PI_2) + theta_r_) * 0.5f - offset) / r1_);
}

float HairLobe::eval(vec3 L) const {
  const float cos_NL = dot(N_, L);
  if (transmission_ ? cos_NL >= 0.0f : cos_NL < 0.0f) return 0.0f;
  const float wo_z = dot(T_, L);
  const vec3 wo_y = normalize(L - T_ * wo_z);
  const float theta_i = float(M_PI_2) - std::acos(std::clamp(wo_z, -1.0f, 1.0f));
  const float cosphi = std::clamp(dot(wo_y, locy_), -1.0f, 1.0f);
  if (float(M_PI_2) - std::fabs(theta_i) < 0.001f) return 0.0f;
  const float t = (theta_i + theta_r_) * 0.5f - offset_;
  const float theta_pdf = r1_ / (2 * (t * t + r1_ * r1_) * (a_ - b_) * std::cos(theta_i));
  float phi_pdf;
  if (!transmission_) {
    if (cosphi < 0.0f) return 0.0f;
    float phi = std::acos(cosphi) / r2_;
    phi = std::fabs(phi) < float(M_PI) ? phi : float(M_PI);
    phi_pdf = std::cos(phi * 0.5f) * 0.25f / r2_;
  } else {
    const float c = 2 * std::atan(float(M_PI_2) / r2_);
    const float p = float(M_PI) - std::fabs(std::acos(cosphi));
    phi_pdf = r2_ / (c * (p * p + r2_ * r2_));
  }
  return phi_pdf * theta_pdf;
}

float ggx_eval(vec3 N, vec3 T, float alpha_x, float alpha_y, vec3 Ng, vec3 I, vec3 L) {
  return GGXReflection(N, T, alpha_x, alpha_y, Ng, I).eval(L);
}

}  // namespace loom::cycles
