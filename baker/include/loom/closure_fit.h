// Fitted specular closures of the surface tier: for one view V and ply tangent t (a cell of the
// closure LUT, closure_mapping.h), the parameters of the Cycles closures that stand for the
// model's fiber specular reflection (Eq. 1-2) and transmission (Eq. 4-5), fitted with Ceres
// against the model itself at bake time.
//
// Objective (issue 31): the relative L1 distance over the sphere of light directions, with the
// cosine, made smooth by Charbonnier's penalty sqrt(e^2 + eps^2) - eps, separately for the two
// hemispheres (k_rs and k_ts scale them independently per texel). Reflection starts from the
// unfitted mapping (GGX (a, 1) rescaled to A_rs); transmission from the hair closure carrying
// all of A_ts (from the unfitted Lambertian translucency its roughnesses have no gradient).
// Each fit is then rescaled to the model's albedo and judged by the L1 on a finer quadrature:
// one that is not better there than the unfitted mapping is discarded, so no cell gets worse.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

#include "loom/cycles_closures.h"
#include "loom/shading.h"

namespace loom {

/// int f(i) di over the sphere, with f concentrated on the cone i . axis = c (width ~ a), in
/// latitude theta about the axis's normal plane (i . axis = sin theta) and azimuth psi about the
/// axis: theta = asin(c) + a tan(zeta), zeta uniform (n samples), psi uniform (m samples),
/// dw = cos theta dtheta dpsi. The latitude keeps the hair closures' 1 / cos theta (a pdf in
/// theta) finite at the poles. f(i, dw) receives each direction with its solid angle.
template <class F>
inline void cone_quadrature(shading::vec3 axis, double c, double a, int n, int m, F f) {
  using shading::vec3;
  const vec3 e1 = std::fabs(axis.z) < 0.9f ? shading::normalize(shading::cross(axis, vec3(0, 0, 1)))
                                           : shading::normalize(shading::cross(axis, vec3(1, 0, 0)));
  const vec3 e2 = shading::cross(axis, e1);
  std::vector<float> cs(static_cast<size_t>(m)), sn(static_cast<size_t>(m));
  for (int j = 0; j < m; ++j) {
    cs[size_t(j)] = float(std::cos((j + 0.5) * 2.0 * M_PI / m));
    sn[size_t(j)] = float(std::sin((j + 0.5) * 2.0 * M_PI / m));
  }
  const double t0 = std::asin(std::clamp(c, -1.0, 1.0));
  const double z0 = std::atan((-M_PI / 2 - t0) / a), z1 = std::atan((M_PI / 2 - t0) / a);
  for (int k = 0; k < n; ++k) {
    const double zeta = z0 + (k + 0.5) * (z1 - z0) / n;
    const double th = std::clamp(t0 + a * std::tan(zeta), -M_PI / 2, M_PI / 2);
    const double dth = a / (std::cos(zeta) * std::cos(zeta)) * (z1 - z0) / n;
    const double u = std::sin(th), r = std::cos(th);
    const double dw = r * dth * 2.0 * M_PI / m;  // solid angle: cos theta dtheta dpsi
    for (int j = 0; j < m; ++j)
      f(axis * float(u) + e1 * float(r * cs[size_t(j)]) + e2 * float(r * sn[size_t(j)]), dw);
  }
}

/// Parameters per unit k_rs (reflection) and per unit k_ts (transmission), in the closures'
/// own terms (cycles_closures.h): GGX alphas along t and across it, hair roughnesses (theta,
/// azimuth).
struct SpecularClosures {
  float ggx_w = 0, ggx_ax = 1, ggx_ay = 1;  ///< microfacet("ggx", N_c, t, ax, ay)
  float ht_w = 0, ht_r1 = 0.2f, ht_r2 = 1;  ///< hair_transmission(N, r1, r2, t, 0)
  float tl_w = 0;                           ///< translucent(N)
};

struct ClosureFitOptions {
  int n = 12, m = 16;  ///< quadrature about the specular cone (cone_quadrature)
  /// The finer quadrature that sets each hemisphere's energy and judges fitted against unfitted
  /// (a fit judged on its own samples can hide energy between them).
  int judge_n = 96, judge_m = 32;
  int max_iterations = 15;
  double charbonnier_eps = 0.02;  ///< in units of the hemisphere's albedo per steradian
  double energy_weight = 1.0;     ///< of the residual (closures' albedo / model's - 1)
};

struct ClosureFit {
  SpecularClosures p;
  /// Relative L1 of the reflection and transmission parts: unfitted mapping, fitted.
  double refl_before = 0, refl_after = 0, trans_before = 0, trans_after = 0;
  double A_rs = 0, A_ts = 0;  ///< the model's directional albedos (per unit k)
};

/// The model's (a, T) specular lobes for view V and tangent t (tangent frame, V.z > 0), fitted.
ClosureFit fit_specular_closures(shading::vec3 V, shading::vec3 t, float a, float T,
                                 const ClosureFitOptions& o = {});

/// The closures' albedos per hemisphere (Cycles' eval integrated over the sphere), each closure
/// on a cone quadrature (n x m) as wide as its own lobe and at least a.
struct SpecularEnergies {
  double reflect = 0, transmit = 0;
};
SpecularEnergies specular_closure_energies(const SpecularClosures& p, shading::vec3 V,
                                           shading::vec3 t, float a, int n, int m);

/// The closures set up for view V and tangent t with N = Ng = +z (Cycles' setup), evaluated
/// for many light directions L: f <L.N> (Cycles' eval) per unit k_rs (reflection, L.z > 0) or
/// k_ts (transmission, L.z < 0). The C++ emulator (evaluator.cpp) and the fit share it.
class SpecularClosureSet {
 public:
  SpecularClosureSet(const SpecularClosures& p, shading::vec3 V, shading::vec3 t);
  float eval(shading::vec3 L) const;

 private:
  SpecularClosures p_;
  cycles::MicrofacetReflection ggx_;
  cycles::HairLobe ht_;
};

}  // namespace loom
