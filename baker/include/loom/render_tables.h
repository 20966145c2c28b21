// The render tables of a ray-wave atlas: what the shaders read at the yarn colours
// (osl/include/loom/raywave_lobes.h, double_layer_factors.h), baked from the colour-independent
// tables (ply tables, double-layer factors) by the bake's last stage, and read back by the C++
// evaluators (raywave_bsdf.h), which share double_layer_at and layer_factor_pair with it.
#pragma once
#include <array>
#include <vector>

#include "loom/absorption_curve.h"
#include "loom/asg_fit.h"
#include "loom/double_layer.h"
#include "loom/ply_maps.h"
#include "loom/shading.h"

namespace loom {

/// The layer_factors tables' contents (manifest raywave.shading.factors_layout): the per-point
/// factors k_b, k_f of double_layer_factors.h. Atlases with other factors (the ratios
/// B_total / B_t, F_total / F_t, F_total of older bakers) are refused with a re-bake message.
inline constexpr const char* kLayerFactorsLayout = "k_b,k_f";

/// Render tables baked at the yarn colours (layouts in the shared headers).
/// ply_tint_<yarn>: RGB Eq. S.11 scale of each lobe of f_high at sigma_rgb, per corner node in the
/// nodes' lobe-major layout (column l (N' + 1) + j, row i: asg_tint_uv), so that a bilinear
/// look-up between nodes interpolates it as S.7 does the lobes.
Image ply_tint_image(const AsgTable& high, const std::array<double, 3>& sigma_rgb);
/// ply_residual_<yarn>: RGB energy residual of f_refl + f_high (asg_residual.h) per slice and
/// side at sigma_rgb (layout: raywave_residual_uv in raywave_lobes.h).
Image ply_residual_rgb_image(const AsgTable& high, const AsgTable& refl,
                             const std::array<double, 3>& sigma_rgb);

/// A double-layer factor table of the atlas (double_layer_front/back) with its grids.
struct DoubleLayerGrid {
  Image table;  ///< B_t, F_t, B_total, F_total; column phi bin, row k theta_count + theta bin
  int theta_count = 0, phi_count = 0;
  std::vector<double> sigmas;
  AbsorptionCurve absorption;  ///< interpolation variable between levels (absorption_curve.h)
};
/// Eq. S.20's factors at direction xi (unit, xi.z >= 0) and absorption sigma (1/mm): bilinear in
/// the (theta, phi) bin centres (phi periodic, theta clamped), between levels by sigma_interval.
DoubleLayerFactors double_layer_at(const DoubleLayerGrid& g, const shading::vec3& xi,
                                   double sigma);
/// The per-point double-layer factors of double_layer_factors.h from Eq. S.20's tabulated
/// values: k_b = (B_total - B_t) / F_t >= 0 and k_f = F_total / F_t, with k_b + k_f <= 1 (both
/// scaled down to sum 1 where interpolation or the simulation's noise would give more: Eq. S.20
/// gives F_tb / (1 - B_tb), at most 1 for a bottom layer that conserves energy); 0 and 1 (one
/// layer) where F_t vanishes or a value is not finite.
void layer_factor_pair(const DoubleLayerFactors& f, float& kb, float& kf);
/// layer_factors_<side>: the two RGB blocks (k_b, k_f) of double_layer_factors.h at sigma_rgb.
Image layer_factors_image(const DoubleLayerGrid& g, const std::array<double, 3>& sigma_rgb);

/// asg_integral_lut: what asg_integral_from_lut (osl/include/loom/asg.h) reads, one channel,
/// LOOM_ASG_INTEGRAL_LUT_SIZE^2 texels over the bandwidths' LUT coordinates: the shaders take
/// each lobe's integral from it instead of running asg_integral's quadrature per point.
Image asg_integral_lut_image();
/// The microfacet albedo LUT (raywave_lobes.h): E(cos(N, V), alpha) of Cycles' isotropic Beckmann
/// reflection closure (F = 1), by quadrature in the half-vector domain with `n` x 4n points.
Image microfacet_albedo_image(int n = 48);

}  // namespace loom
