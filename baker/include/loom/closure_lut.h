// The closure LUT of the surface closure mapping (closure_mapping.h): per yarn kind, ply tangent
// elevation and view direction, the parameters of the Cycles closures fitted to the model's
// fiber specular reflection (Eq. 1-2) and transmission (Eq. 4-5), per unit albedo k
// (closure_fit.h). Colours are not in it, so a colour-only re-bake reuses it as it is.
#pragma once
#include "loom/closure_fit.h"
#include "loom/ply_maps.h"
#include "loom/shading.h"

namespace loom {

/// (LOOM_LUT_PANELS N) x (2 SLICES N) RGBA float image, N = LOOM_CLOSURE_LUT_SIZE (layout:
/// closure_mapping.h, surface_lut_uv): texel (ix, j) of slice k holds the view azimuth
/// ix / (N - 1) * pi about t, cos theta_V = max(j / (N - 1), kLutMinCos) and
/// t_z = k / (SLICES - 1) * LOOM_LUT_TZ_MAX; panel 0 (g, ax, ay, 0), panel 1 (h, r1, r2, l).
inline constexpr float kLutMinCos = 0.02f;
/// Largest weight (g, h, l) the LUT holds: where a closure carries almost nothing of its own
/// albedo (grazing views) the energy match would otherwise ask for any factor.
inline constexpr float kClosureLutMaxWeight = 50.0f;

/// View direction and ply tangent of one LUT texel (tangent frame).
void lut_configuration(int ix, int j, int slice, shading::vec3& V, shading::vec3& t);

/// The fit's quadrature and iterations per quality preset.
ClosureFitOptions closure_fit_options(Quality q);

Image bake_closure_lut(const FabricSpec& spec, const ProgressFn& progress = {});

/// Look-up of panel `panel` of the LUT at LUT coordinates (x, y, z) (surface_lut_coords) for a
/// yarn kind as read from yarn_info (surface_lut_uv in closure_mapping.h picks the rows), with
/// the filtering of an image texture with linear interpolation and clamped (extend) borders.
void sample_closure_lut(const Image& lut, float kind, float x, float y, float z, int panel,
                        float out[4]);

}  // namespace loom
