// Anisotropic Spherical Gaussian lobes (Xu et al. 2013), as the ray-wave model fits them to
// simulated ply scattering (ray-wave supplement, section 1, Eq. S.1 and S.2).
//
//   G(x, y, z, mu1, mu2, c; v) = c max(v.z, 0) exp(-mu1 (v.x)^2 - mu2 (v.y)^2)       (S.1)
//
// with the frame [x, y, z] from three angles (theta_z, phi_z, phi_xy), (S.2):
//   z  = (cos theta_z cos phi_z, cos theta_z sin phi_z, sin theta_z)
//   x0 = (-sin phi_z, cos phi_z, 0),  y0 = (-sin theta_z cos phi_z, -sin theta_z sin phi_z, cos theta_z)
//   x  = cos phi_xy x0 - sin phi_xy y0,  y = sin phi_xy x0 + cos phi_xy y0
// Directions are in ply space: the ply runs along +z, theta is the elevation from the plane
// normal to the ply (the papers' longitudinal angle) and phi the azimuth about the ply from +x.
//
// The integral over the sphere. In the lobe's frame v = (a, b, s) with s = v.z >= 0 and
// dv = da db / s over the unit disk, so the cosine cancels the Jacobian exactly:
//   I = c iint_{a^2 + b^2 <= 1} exp(-mu1 a^2 - mu2 b^2) da db.
// With lo = min(mu1, mu2) along a and hi = max(mu1, mu2) along b, the inner integral is a chord,
// sqrt(pi / lo) erf(sqrt(lo) r) over |a| <= r = sqrt(1 - b^2), and with b = sin psi:
//   I = 2 c int_0^{pi/2} exp(-hi sin^2 psi) chord(lo, cos psi) cos psi dpsi.
// Choice: the closed form pi c / sqrt(mu1 mu2) when lo >= LOOM_ASG_CLOSED_FORM_MU (relative error
// below 5e-9); otherwise the midpoint rule over psi in [0, Psi], Psi = asin(min(1,
// LOOM_ASG_INTEGRAL_WIDTHS / sqrt(hi))) (what lies beyond is below exp(-20)), with
// LOOM_ASG_INTEGRAL_STEPS points: the integrand is even about 0 (and, when Psi = pi / 2, about
// pi / 2), so the rule converges spectrally; relative error below 1e-5 over all mu (tested against
// brute-force quadrature over the sphere). erf is asg_erf (Abramowitz and Stegun 7.1.26). The
// shaders do not run this quadrature: they read the integral from a table the bake makes of it
// (asg_integral_from_lut below).
#ifndef LOOM_ASG_H
#define LOOM_ASG_H
#include "osl_compat.h"

#define LOOM_ASG_CLOSED_FORM_MU 16.0
#define LOOM_ASG_INTEGRAL_STEPS 8  // midpoints over [0, Psi] (see asg_integral)
#define LOOM_ASG_INTEGRAL_WIDTHS 4.5
/// Bandwidths are clamped to [0, LOOM_ASG_MU_MAX]; beyond it exp() of the smallest off-centre
/// angle a float can resolve underflows anyway.
#define LOOM_ASG_MU_MAX 1.0e6

/// Eq. S.2: the lobe frame from (theta_z, phi_z, phi_xy).
LOOM_FN void asg_frame(float theta_z, float phi_z, float phi_xy, LOOM_OUT(vector) x,
                       LOOM_OUT(vector) y, LOOM_OUT(vector) z) {
  float st = sin(theta_z), ct = cos(theta_z), sp = sin(phi_z), cp = cos(phi_z);
  z = vector(ct * cp, ct * sp, st);
  vector x0 = vector(-sp, cp, 0.0);
  vector y0 = vector(-st * cp, -st * sp, ct);
  float sa = sin(phi_xy), ca = cos(phi_xy);
  x = ca * x0 - sa * y0;
  y = sa * x0 + ca * y0;
}

/// Eq. S.1 for a unit direction v. Non-finite or negative parameters give 0 rather than NaN.
LOOM_FN float asg_eval(float theta_z, float phi_z, float phi_xy, float mu1, float mu2, float c,
                       vector v) {
  vector x, y, z;
  asg_frame(theta_z, phi_z, phi_xy, x, y, z);
  float vz = dot(v, z);
  if (!(vz > 0.0) || !(c > 0.0))
    return 0.0;
  float m1 = clamp(mu1, 0.0, LOOM_ASG_MU_MAX), m2 = clamp(mu2, 0.0, LOOM_ASG_MU_MAX);
  float vx = dot(v, x), vy = dot(v, y);
  return c * vz * exp(-m1 * vx * vx - m2 * vy * vy);
}

/// erf(x) for x >= 0 (Abramowitz and Stegun 7.1.26, absolute error below 1.5e-7).
LOOM_FN float asg_erf(float x) {
  float t = 1.0 / (1.0 + 0.3275911 * x);
  float poly = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741 +
                                                           t * (-1.453152027 + t * 1.061405429))));
  return 1.0 - poly * exp(-x * x);
}

/// The chord integral of exp(-mu a^2) over |a| <= r, mu >= 0, r >= 0: sqrt(pi / mu) erf(sqrt(mu) r),
/// and its series 2 r (1 - mu r^2 / 3) where mu r^2 < 1e-4.
LOOM_FN float asg_chord(float mu, float r) {
  float x2 = mu * r * r;
  if (x2 < 1e-4)
    return 2.0 * r * (1.0 - x2 / 3.0);
  float sm = sqrt(mu);
  return sqrt(LOOM_M_PI) / sm * asg_erf(sm * r);
}

/// The integral of Eq. S.1 over the sphere (see the header comment for the method).
LOOM_FN float asg_integral(float mu1_in, float mu2_in, float c) {
  if (!(c > 0.0))
    return 0.0;
  float mu1 = clamp(mu1_in, 0.0, LOOM_ASG_MU_MAX), mu2 = clamp(mu2_in, 0.0, LOOM_ASG_MU_MAX);
  float lo = min(mu1, mu2), hi = max(mu1, mu2);
  if (lo >= LOOM_ASG_CLOSED_FORM_MU)
    return c * LOOM_M_PI / sqrt(lo * hi);
  float psi_max = asin(min(1.0, LOOM_ASG_INTEGRAL_WIDTHS / sqrt(max(hi, 1e-12))));
  float dpsi = psi_max / LOOM_ASG_INTEGRAL_STEPS;
  float sum = 0.0;
  for (int i = 0; i < LOOM_ASG_INTEGRAL_STEPS; i += 1) {
    float ps = (i + 0.5) * dpsi;
    float sb = sin(ps), cb = cos(ps);
    sum += exp(-hi * sb * sb) * asg_chord(lo, cb) * cb;
  }
  return 2.0 * c * sum * dpsi;
}

/// Texels per side of the ASG integral LUT (the atlas's asg_integral_lut, made by the bake):
/// shaders read a lobe's integral from it instead of running asg_integral's quadrature.
#define LOOM_ASG_INTEGRAL_LUT_SIZE 64

/// The LUT coordinate of a bandwidth, in [0, 1]: log(1 + mu) / log(1 + LOOM_ASG_MU_MAX).
LOOM_FN float asg_integral_lut_coord(float mu) {
  return log(1.0 + clamp(mu, 0.0, LOOM_ASG_MU_MAX)) / log(1.0 + LOOM_ASG_MU_MAX);
}

/// Image coordinates in the ASG integral LUT of bandwidths (mu1, mu2): texel centres at the
/// coordinates k / (LOOM_ASG_INTEGRAL_LUT_SIZE - 1).
LOOM_FN void asg_integral_lut_uv(float mu1, float mu2, LOOM_OUT(float) s, LOOM_OUT(float) tv) {
  float n = LOOM_ASG_INTEGRAL_LUT_SIZE;
  s = (0.5 + asg_integral_lut_coord(mu1) * (n - 1.0)) / n;
  tv = (0.5 + asg_integral_lut_coord(mu2) * (n - 1.0)) / n;
}

/// The integral of a lobe (mu1, mu2, c) from the LUT's value h at its bandwidths. The LUT holds
/// h = asg_integral(mu1, mu2, 1) sqrt((1 + mu1) (1 + mu2)) / pi, which is 1 at mu = 0 and tends
/// to 1 for sharp lobes (pi / sqrt(mu1 mu2)): smooth in the LUT's log coordinates, so a bilinear
/// look-up keeps it within a fraction of a percent (tests/cpp/test_asg.cpp).
LOOM_FN float asg_integral_from_lut(float h, float mu1, float mu2, float c) {
  if (!(c > 0.0))
    return 0.0;
  float m1 = clamp(mu1, 0.0, LOOM_ASG_MU_MAX), m2 = clamp(mu2, 0.0, LOOM_ASG_MU_MAX);
  return c * LOOM_M_PI * h / sqrt((1.0 + m1) * (1.0 + m2));
}

/// Eq. S.1 and its gradient with respect to the six parameters (theta_z, phi_z, phi_xy, mu1,
/// mu2, c), for the fitter, from the lobe's precomputed trigonometry (st, ct = sin, cos theta_z;
/// sp, cp of phi_z; sa, ca of phi_xy), so that a fit evaluating one lobe at many directions pays
/// for it once. Uses dz/dtheta = y0, dz/dphi = cos(theta) x0, dx0/dphi = e,
/// dy0/dtheta = -z, dy0/dphi = -sin(theta) x0 with e = (-cos phi, -sin phi, 0), dx/dphi_xy = -y,
/// dy/dphi_xy = x. The gradient of the max() is taken as 0 where v.z <= 0.
LOOM_FN float asg_eval_grad_trig(float st, float ct, float sp, float cp, float sa, float ca,
                                 float mu1, float mu2, float c, vector v,
                                 LOOM_OUT(vector) g_angles, LOOM_OUT(vector) g_shape) {
  g_angles = vector(0.0);
  g_shape = vector(0.0);
  vector z = vector(ct * cp, ct * sp, st);
  float vz = dot(v, z);
  if (!(vz > 0.0))
    return 0.0;
  vector x0 = vector(-sp, cp, 0.0);
  vector y0 = vector(-st * cp, -st * sp, ct);
  vector e = vector(-cp, -sp, 0.0);
  vector x = ca * x0 - sa * y0;
  vector y = sa * x0 + ca * y0;
  float vx = dot(v, x), vy = dot(v, y);
  float ex = exp(-mu1 * vx * vx - mu2 * vy * vy);
  float val = c * vz * ex;
  // d/dtheta: z' = y0, x' = -sa (-z) = sa z, y' = ca (-z).
  float dvz_t = dot(v, y0), dvx_t = sa * vz, dvy_t = -ca * vz;
  // d/dphi: z' = ct x0, x0' = e, y0' = -st x0.
  float ve = dot(v, e), vx0 = dot(v, x0);
  float dvz_p = ct * vx0, dvx_p = ca * ve + sa * st * vx0, dvy_p = sa * ve - ca * st * vx0;
  // d/dphi_xy: x' = -y, y' = x.
  float dvx_a = -vy, dvy_a = vx;
  float dexp_t = -2.0 * (mu1 * vx * dvx_t + mu2 * vy * dvy_t);
  float dexp_p = -2.0 * (mu1 * vx * dvx_p + mu2 * vy * dvy_p);
  float dexp_a = -2.0 * (mu1 * vx * dvx_a + mu2 * vy * dvy_a);
  g_angles = vector(c * ex * (dvz_t + vz * dexp_t), c * ex * (dvz_p + vz * dexp_p),
                    val * dexp_a);
  g_shape = vector(-val * vx * vx, -val * vy * vy, vz * ex);
  return val;
}

/// Eq. S.1 and its gradient (see asg_eval_grad_trig) from the six parameters.
LOOM_FN float asg_eval_grad(float theta_z, float phi_z, float phi_xy, float mu1, float mu2,
                            float c, vector v, LOOM_OUT(vector) g_angles,
                            LOOM_OUT(vector) g_shape) {
  return asg_eval_grad_trig(sin(theta_z), cos(theta_z), sin(phi_z), cos(phi_z), sin(phi_xy),
                            cos(phi_xy), mu1, mu2, c, v, g_angles, g_shape);
}

#endif
