// Double-layer scattering (ray-wave supplement section 3, Eq. S.20-S.22): a woven fabric is
// locally a stack of two yarn layers; their reflection and transmission factors, and the
// geometric series of inter-layer bounces, correct the ply model's backward and forward light.
//
// Each layer's BSDF f_t, f_b is the ply scattering averaged over the incident position h
// (supplement: "averaging f^single or f^multi over a full range of incident positions h"),
// expressed in the fabric's surface frame. For a surface direction xi towards the light and a
// ply along the unit axis a (in the surface plane), the ply frame is z_p = a,
// y_p = normalize(xi - (xi.a) a), x_p = y_p x z_p, so that xi = (0, cos theta_i, sin theta_i)
// as in the simulation, theta_i = asin(xi.a).
//
// Choices where the text is silent:
//  * The layers' BSDFs come from the raw simulated histograms (not the fitted lobes): their
//    energies are exact, which is what B and F measure. theta_i between simulated samples is
//    interpolated linearly; beyond the grid the last sample is used.
//  * Light that crosses a ply without meeting a fiber (`unscattered`) continues forward
//    unchanged (a delta in -xi) and counts in F_t; the bottom layer sees it.
//  * "Backward" and "forward" are the surface's hemispheres: B integrates f over directions on
//    the light's side of the surface, F over the other side.
//  * Warp over weft for light from the front (+z), weft over warp from the back (-z): the back
//    table is the front one with the layers swapped (a ply is symmetric under the mirror through
//    the surface plane, up to its twist's handedness, which is ignored).
//  * Everything is tabulated per absorption level sigma_k of the simulation (the factors depend
//    on the ply colour), over theta of xi from the normal in [0, 90) and its azimuth in [0, 360).
//  * The blend factor s of Eq. S.22 is the spec's model.double_layer_blend.
#pragma once
#include <vector>

#include "loom/ply_scattering.h"

namespace loom {

/// One layer: a simulated ply lying along `axis` in the surface plane.
struct Layer {
  const PlySimResult* sim = nullptr;
  Vec3d axis{1, 0, 0};
};

struct DoubleLayerSettings {
  int theta_count = 16;  ///< bins of theta (from the normal) over [0, 90)
  int phi_count = 32;    ///< bins of the azimuth over [0, 360)
};

/// Grid sizes of a quality preset.
DoubleLayerSettings double_layer_settings(Quality q);

struct DoubleLayerFactors {
  double Bt = 0, Ft = 0, Bb = 0, Fb = 0, Btotal = 0, Ftotal = 0;
};

/// Eq. S.20: B_t, F_t from the top layer, B_b, F_b from the bottom layer lit by the top's forward
/// light, and the totals, for a direction xi (towards the light, on the +z side).
DoubleLayerFactors double_layer_factors(const Layer& top, const Layer& bottom, const Vec3d& xi,
                                        int k);

/// A table over (theta, phi) of xi in the upper hemisphere and the sigma levels:
/// values[(k * theta_count + t) * phi_count + p] with bin centres theta = (t + 0.5) 90 / T deg,
/// phi = (p + 0.5) 360 / P deg.
struct DoubleLayerTable {
  DoubleLayerSettings settings;
  std::vector<double> sigmas;
  std::vector<DoubleLayerFactors> values;
};
DoubleLayerTable double_layer_table(const Layer& top, const Layer& bottom,
                                    const DoubleLayerSettings& s);

/// Independent check of Eq. S.20: the two layers' full directional transfer iterated bounce by
/// bounce (light kept as energies over a direction grid of `rows` x 2 rows), until less than
/// `tolerance` of the energy is still between the layers. Returns {B, F} escaping up and down.
std::pair<double, double> double_layer_brute_force(const Layer& top, const Layer& bottom,
                                                   const Vec3d& xi, int k, int rows = 24,
                                                   double tolerance = 1e-6);

}  // namespace loom
