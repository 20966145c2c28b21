// Closure emulator: Cycles' own BSDF formulas (Cycles 4.x kernel/closure), evaluated in C++ so the
// error of mapping a Loom model onto Cycles' built-in closures can be measured without Blender.
//
// Cycles' convention: eval(I, L) returns f * <L . N_closure> (the cosine about the closure's own
// normal, clamped), with I towards the viewer and L towards the light. Reproduced here:
//   diffuse(N)      max(L.N, 0) / pi                                   (bsdf_diffuse.h)
//   translucent(N)  max(-L.N, 0) / pi                                  (bsdf_diffuse.h)
//   microfacet("ggx", N, T, ax, ay, eta, 0): F = 1 (no Fresnel), alphas clamped to [0, 1],
//      D anisotropic GGX, height-correlated Smith G = 1 / (1 + Lambda_I + Lambda_L),
//      eval = D G / (4 <I.N>); zero when <I.N> <= 0, <L.N> <= 0, ax*ay <= 5e-7, or when L is
//      below the geometric normal Ng (bsdf_microfacet.h, bsdf_microfacet_eval)
//   Diffuse-type closures (diffuse, translucent) whose normal differs from the shading normal Ns
//      are multiplied by bump_shadowing_term (Chiang et al. 2019, "Taming the Shadow Terminator";
//      Cycles bsdf.h, with the material's default "Bump Map Correction" on).
//   hair_reflection(N, r1, r2, T, offset) / hair_transmission (bsdf_hair.h, the Kajiya-Kay-like
//      pair; OSL and SVM's Hair BSDF node with a linked Tangent alike; SVM negates Offset):
//      eval = pdf = phi_pdf theta_pdf, theta_h = (theta_L + theta_I) / 2 about the fiber's normal
//      plane (the specular cone T.L = -T.I when offset = 0), Cauchy in theta_h of width r1;
//      in the azimuth about T, reflection cos(phi / (2 r2)) / (4 r2) for L on I's side
//      (|phi| <= pi r2 and <= pi/2), transmission Cauchy of width r2 about phi = pi. Reflection is
//      zero below N, transmission above (N raised by ensure_valid_specular_reflection).
//   Microfacet closures get N = ensure_valid_specular_reflection(Ng, I, N) at setup
//      (bsdf_util.h, maybe_ensure_valid_specular_reflection, OSL closures_setup.h and SVM alike):
//      the normal is raised towards Ng until the mirror direction of I clears the surface.
// All vectors are unit, in one frame.
#pragma once
#include "loom/shading.h"

namespace loom::cycles {

using shading::vec3;

/// Ns: the shading normal (sd->N).
float diffuse_eval(vec3 N, vec3 L, vec3 Ns);
float translucent_eval(vec3 N, vec3 L, vec3 Ns);
float bump_shadowing_term(vec3 Ns, vec3 N, vec3 L);
vec3 ensure_valid_specular_reflection(vec3 Ng, vec3 I, vec3 N);
float ggx_eval(vec3 N, vec3 T, float alpha_x, float alpha_y, vec3 Ng, vec3 I, vec3 L);

/// hair_reflection / hair_transmission set up for a view I (bsdf_hair.h); r1, r2 clamped to
/// [0.001, 1] as bsdf_hair_*_setup does.
struct HairLobe {
  HairLobe(vec3 N, vec3 T, float roughness1, float roughness2, float offset, vec3 I,
           bool transmission);
  float eval(vec3 L) const;

 private:
  vec3 N_, T_, locy_;
  float r1_, r2_, offset_, theta_r_, a_, b_;
  bool transmission_;
};

enum class Distribution { GGX, Beckmann };

/// microfacet(distribution, N, T, ax, ay, 1, 0) set up once for a view I (Cycles' setup/eval
/// split), for many evaluations. Beckmann: D = exp(-(h_x^2 + h_y^2) / h_z^2) / (pi ax ay h_z^4)
/// with h = H / (ax, ay, 1) (bsdf_aniso_D), Lambda by the rational approximation below Heitz 2014
/// Eq. 69 (0 when alpha^2 tan^2 < 0.39), as bsdf_lambda_from_sqr_alpha_tan_n.
struct MicrofacetReflection {
  MicrofacetReflection(vec3 N, vec3 T, float alpha_x, float alpha_y, vec3 Ng, vec3 I,
                       Distribution d = Distribution::GGX);
  float eval(vec3 L) const;
  vec3 tangent() const { return X_; }  ///< the closure's alpha_x axis (T made orthogonal to N)

 private:
  float lambda(vec3 v) const;
  vec3 N_, Ng_, I_, X_, Y_;
  float ax_, ay_, cos_NI_, lambda_I_;
  bool valid_;
  Distribution d_;
};
using GGXReflection = MicrofacetReflection;

/// microfacet(distribution, N, T, a, a, eta, 1): isotropic rough refraction, F = 1 (Cycles'
/// refraction closures ignore anisotropy). I on N's side, L below: H = -(eta L + I) / |..|,
/// eval = D(H) / <I.N> (eta / |eta L + I|)^2 |<H.I> <H.L>| / (1 + Lambda_I + Lambda_L)
/// (bsdf_microfacet_eval, transmission branch); zero unless L is below both N and Ng. eta is the
/// closure's ior as Cycles holds it (OSL's microfacet() passes it unchanged on both faces; SVM's
/// Refraction BSDF node inverts it on back faces).
struct MicrofacetRefraction {
  MicrofacetRefraction(vec3 N, float alpha, float eta, vec3 Ng, vec3 I,
                       Distribution d = Distribution::Beckmann);
  float eval(vec3 L) const;

 private:
  float lambda(float cos_n) const;
  vec3 N_, Ng_, I_;
  float a_, eta_, cos_NI_, lambda_I_;
  bool valid_;
  Distribution d_;
};

}  // namespace loom::cycles
