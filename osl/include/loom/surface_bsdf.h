// The surface cloth BSDF of Zhu et al. 2023 (supplement Eq. 1-6), evaluated in the tangent frame
// of the cloth (x along the warp, y along the weft, z the surface normal n_s).
//
//   f = (1 - c) V(i) V(o) [f^{r,s} + f^{r,d}]    i and o on the same side    (Eq. 1, 3)
//   f = (1 - c)           [f^{t,s} + f^{t,d}]    i and o on opposite sides   (Eq. 4, 6)
// with c the gap coverage (open area between yarns: the light passing there is a delta
// transmission, not part of f), V the ply/yarn visibility (visibility.h).
//
// Conventions and choices where the text is silent:
//   * i is the direction towards the light, o towards the viewer, both pointing away from the
//     surface; f is returned without any cosine. In Eq. 3 the ply-normal term carries <i . n_p>
//     over <i . n_s>, so f <i . n_s> is a Lambertian lobe about the ply normal n_p.
//   * The half vector of both reflection and transmission is h = (i + o) / |i + o|, as in
//     SpongeCake (the microflakes reflect, they do not refract); h is undefined for o = -i, where
//     f^{t,s} is set to 0 (a set of measure zero).
//   * The cloth is two-sided. Seen from below (o_z < 0), i and o are mirrored through the tangent
//     plane and the back is taken as the mirror image of the front: the atlas's ply normal n_p is
//     used as stored, facing the viewer, for reflection (Eq. 3) and diffuse transmission (Eq. 6,
//     whose ply-normal term then sees light leaving towards the viewer, as on the front). The
//     fiber specular transmission (Eq. 4) goes through the one physical slab: its fiber tangent
//     is mirrored, so that it stays reciprocal across the two sides. Visibility is only baked for
//     the front and is 1 on the back.
//   * k^{r,s}, k^{t,s} are scalar (fibers are dielectrics: their specular reflection is white);
//     k^{r,d}, k^{t,d} are colours.
#ifndef LOOM_SURFACE_BSDF_H
#define LOOM_SURFACE_BSDF_H
#include "osl_compat.h"
#include "sggx.h"
#include "spongecake.h"
#include "visibility.h"

/// Eq. 1: specular reflection, i and o above the surface (i_z, o_z > 0).
LOOM_FN float surface_specular_reflect(vector i, vector o, vector t, float a, float T) {
  vector h = normalize(i + o);
  float D = sggx_fiber_D(h, t, a);
  float li = spongecake_lambda(sggx_fiber_sigma(i, t, a), i[2]);
  float lo = spongecake_lambda(sggx_fiber_sigma(o, t, a), o[2]);
  return D * spongecake_G_reflect(li, lo, T) / (4.0 * i[2] * o[2]);
}

/// Eq. 4: specular transmission, o above and i below the surface (o_z > 0, i_z < 0).
LOOM_FN float surface_specular_transmit(vector i, vector o, vector t, float a, float T) {
  vector s = i + o;
  float len = length(s);
  if (len < 1e-6)
    return 0.0;
  float D = sggx_fiber_D(s / len, t, a);
  float li = spongecake_lambda(sggx_fiber_sigma(i, t, a), i[2]);
  float lo = spongecake_lambda(sggx_fiber_sigma(o, t, a), o[2]);
  return D * spongecake_G_transmit(li, lo, T) / (4.0 * fabs(i[2]) * o[2]);
}

/// Eq. 3 (reflection, cos_i = i . n_s > 0) and Eq. 6 (transmission, called with -i so that
/// cos_i > 0): w k <i.n_p> / (pi <i.n_s>) + (1 - w) k / pi, returned per unit albedo k.
LOOM_FN float surface_diffuse(float cos_i_np, float cos_i, float w) {
  return (w * max(cos_i_np, 0.0) / cos_i + (1.0 - w)) / LOOM_M_PI;
}

/// The whole surface BSDF f(i, o) (Eq. 1-6) at one atlas texel.
///   t, n_p   ply tangent and ply normal (unit, tangent frame);  a SGGX roughness;  T optical
///            thickness;  w diffuse blend of Eq. 3/6;  k_rs, k_ts specular albedos; k_rd, k_td
///            diffuse albedos;  c gap coverage;  hor the horizon sines (visibility.h).
LOOM_FN color surface_bsdf_eval(vector i_in, vector o_in, vector t_in, vector np_in, float a,
                                float T, float w, float k_rs, color k_rd, float k_ts,
                                color k_td, float c, float hor[LOOM_HORIZON_DIRS]) {
  // Non-finite directions (a NaN from upstream) scatter nothing rather than poison the pixel.
  if (!(isfinite(i_in[0]) && isfinite(i_in[1]) && isfinite(i_in[2]) && isfinite(o_in[0]) &&
        isfinite(o_in[1]) && isfinite(o_in[2])))
    return color(0.0);
  vector i = i_in;
  vector o = o_in;
  vector t = t_in;
  vector np = np_in;
  float front = 1.0;
  if (o[2] < 0.0) {
    i[2] = -i[2];
    o[2] = -o[2];
    front = 0.0;
  }
  if (!(o[2] > 0.0) || i[2] == 0.0 || !(c < 1.0))
    return color(0.0);
  float open = 1.0 - c;
  if (i[2] > 0.0) {
    float vis = 1.0;
    if (front > 0.0)
      vis = horizon_visibility(i, hor) * horizon_visibility(o, hor);
    float fs = k_rs * surface_specular_reflect(i, o, t, a, T);
    color fd = k_rd * surface_diffuse(dot(i, np), i[2], w);
    return (open * vis) * (fd + color(fs));
  }
  if (front == 0.0)  // the fibers of the physical slab, seen from its back
    t[2] = -t[2];
  float fs = k_ts * surface_specular_transmit(i, o, t, a, T);
  color fd = k_td * surface_diffuse(-dot(i, np), -i[2], w);
  return open * (fd + color(fs));
}

#endif
