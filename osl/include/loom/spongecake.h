// SpongeCake single-scattering attenuation for the surface model (Zhu et al. 2023, supplement
// Eq. 2 and Eq. 5), a layer of optical thickness T of SGGX fiber microflakes.
//
//   Lambda(w) = sigma(w) / (w . n_s)                   (signed: negative below the surface)
//   G^r = (1 - exp(-T (Lambda_i + Lambda_o))) / (Lambda_i + Lambda_o)        Eq. 2, both above
//   G^t = (1 - exp(-T (Lambda_i + Lambda_o))) / (Lambda_i + Lambda_o) exp(T Lambda_o)   Eq. 5
// Eq. 5 is read with the signed Lambda: o lies on the far side, Lambda_o = -b < 0, so with
// a = Lambda_i > 0 it equals (exp(-T b) - exp(-T a)) / (a - b), the SpongeCake transmission term,
// symmetric in (a, b) and hence reciprocal.
// Numerics: both are written with phi(x) = (1 - exp(-x)) / x, evaluated by its series near 0, and
// the transmission term factors out exp(-T min(a, b)) so that no exponential can overflow.
#ifndef LOOM_SPONGECAKE_H
#define LOOM_SPONGECAKE_H
#include "osl_compat.h"

/// phi(x) = (1 - exp(-x)) / x for x >= 0, phi(0) = 1.
LOOM_FN float spongecake_phi(float x) {
  if (x < 1e-4)
    return 1.0 - 0.5 * x + x * x / 6.0;
  return (1.0 - exp(-x)) / x;
}

/// |Lambda(w)| = sigma(w) / |w . n_s|; callers guarantee |w . n_s| > 0.
LOOM_FN float spongecake_lambda(float sigma, float cos_n) {
  return sigma / max(fabs(cos_n), 1e-12);
}

/// Eq. 2: reflection attenuation, la and lb the (positive) Lambdas of i and o.
LOOM_FN float spongecake_G_reflect(float la, float lb, float T) {
  return T * spongecake_phi(T * (la + lb));
}

/// Eq. 5: transmission attenuation, la = Lambda(i) > 0, lb = -Lambda(o) > 0 (o on the far side).
LOOM_FN float spongecake_G_transmit(float la, float lb, float T) {
  float lo = min(la, lb);
  float hi = max(la, lb);
  return exp(-T * lo) * T * spongecake_phi(T * (hi - lo));
}

#endif
