// The albedo look-up table of the surface closure mapping (closure_mapping.h): per yarn kind and
// per view direction, the directional albedos A_rs (model fiber specular reflection, Eq. 1-2),
// A_ggx (the mapped Cycles GGX closure) and A_ts (model fiber transmission, Eq. 4-5), per unit
// albedo k. The closure weights rescale the closures to the model's albedo for each view.
#pragma once
#include "loom/ply_maps.h"
#include "loom/shading.h"

namespace loom {

/// LUT_SIZE x (2 * SLICES * LUT_SIZE) RGBA float image (layout: closure_mapping.h,
/// surface_lut_uv): texel (ix, j) of slice k holds the view azimuth ix / (N - 1) * pi about t,
/// cos theta_V = max(j / (N - 1), kLutMinCos) and t_z = k / (SLICES - 1) * LOOM_LUT_TZ_MAX;
/// channels A_rs, A_ggx, A_ts, 1.
inline constexpr float kLutMinCos = 0.02f;

/// View direction and ply tangent of one LUT texel (tangent frame).
void lut_configuration(int ix, int j, int slice, shading::vec3& V, shading::vec3& t);

/// The three albedos for view V and fiber tangent t (tangent frame, z up), by quadrature in
/// coordinates centred on the specular cone (u = i.t = -V.t + a tan(zeta)), n x m samples.
struct LobeAlbedo {
  double rs = 0, ggx = 0, ts = 0;
};
LobeAlbedo lobe_albedos(shading::vec3 V, shading::vec3 t, float a, float T, int n = 192,
                        int m = 96);

/// Quadrature sizes per quality preset.
void lut_quadrature(Quality q, int& n, int& m);

Image bake_albedo_lut(const FabricSpec& spec, const ProgressFn& progress = {});

/// Look-up of the LUT at LUT coordinates (x, y, z) (surface_lut_coords) for a yarn kind as read from
/// yarn_info (surface_lut_uv in closure_mapping.h picks the rows), with the filtering of an image
/// texture with linear interpolation and clamped (extend) borders.
void sample_albedo_lut(const Image& lut, float kind, float x, float y, float z, float out[3]);

}  // namespace loom
