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

/// The same closure set up once for a view I (Cycles' setup/eval split), for many evaluations.
struct GGXReflection {
  GGXReflection(vec3 N, vec3 T, float alpha_x, float alpha_y, vec3 Ng, vec3 I);
  float eval(vec3 L) const;
  vec3 tangent() const { return X_; }  ///< the closure's alpha_x axis (T made orthogonal to N)

 private:
  vec3 N_, Ng_, I_, X_, Y_;
  float ax_, ay_, cos_NI_, lambda_I_;
  bool valid_;
};

}  // namespace loom::cycles
