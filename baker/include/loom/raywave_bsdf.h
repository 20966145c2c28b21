// The ray-wave cloth BSDF at a shading point (ray-wave supplement sections 1-3 at render time):
// the model itself, read from the exact tables of an atlas (the reference), and the mixture of
// Cycles closures that the OSL shader and node mode build (osl/include/loom/raywave_lobes.h,
// double_layer_factors.h), evaluated with Cycles' formulas (cycles_closures.h) from the render
// tables, texel for texel as the shaders read them.
//
// Both return Cycles' eval quantity, the BSDF times the cosine, for light from wi seen from wo
// (tangent frame, unit): by reciprocity the camera ray is the simulation's beam, and the ply
// scattering density f (fraction of the beam's power per steradian) is that quantity directly
// (raywave_lobes.h). At a point of the surface maps:
//   f = (1 - c) [ V(wo) (V(wi) (f_refl + f_high) + (R_res + k_b T) |wi.z| / pi)   viewer's side
//               [ k_f ((1 - s) (f_refl + f_high + T_res |wi.z| / pi) + s T |wi.z| / pi)  far side
// with c the gap coverage (the open gap is a delta transmission, not part of f), V the horizon
// visibility (front side only, as in the surface tier), f_refl and f_high the fitted lobes at
// (theta_i, h) of the ply space and the yarn's per-channel absorption sigma_c (S.8, S.12),
// R_res, T_res the energy residual (asg_residual.h), T the point's forward light (the lobes'
// energy below the cloth's plane, asg_side_fraction, plus T_res), and k_b, k_f the per-point
// double-layer factors (double_layer_factors.h: Eq. S.20-S.22 made energy-conserving) at
// xi = wo for the channel's absorption.
//
// Also at render time: the gaps' aperture diffraction (diffraction_sampling.h) and the speckle
// noise per lobe (speckle_noise.h). Not yet: ply-edge diffraction (the atlas holds its table),
// the rays that cross a ply between its fibers (`unscattered`, a forward delta), and a mask of
// where the beam meets both yarn layers (the factors apply on every yarn point).
#pragma once
#include <array>
#include <memory>
#include <vector>

#include "loom/asg_fit.h"
#include "loom/diffraction_tables.h"
#include "loom/double_layer.h"
#include "loom/evaluator.h"
#include "loom/ply_tables.h"
#include "loom/render_tables.h"

namespace loom {

/// Gap diffraction of a ray-wave atlas (osl/include/loom/diffraction_sampling.h): the gap table,
/// its cells (the distribution the shaders sample) and the sampling image.
struct GapDiffraction {
  bool present = false;            ///< false: delta transmission (no gap table)
  DiffractionTable table;          ///< D_c(s) per tile (diffraction_tables.h)
  std::vector<DiffractionSampler> sampler;  ///< per tile and channel: [tile 3 + c]
  const Image* sampling = nullptr;      ///< diffraction_gap_sampling
  double spot_s = 0;
  float gap_fraction[2] = {0, 0};  ///< gap width over yarn spacing along x, y
  int yarns[2] = {1, 1};           ///< yarns per repeat stacked along x (weft), y (warp)
};

/// Speckle noise of a ray-wave atlas (osl/include/loom/speckle_noise.h): the two tiles at their
/// blur levels.
struct SpeckleNoise {
  bool present = false;  ///< false: wave.noise off, no modulation
  const Image *refl = nullptr, *high = nullptr;
  int instances = 1;
};

/// Everything the ray-wave BSDF reads from a loaded atlas.
struct RaywaveData {
  LoadedPlyTables yarn[2];                 ///< warp, weft
  std::array<double, 3> sigma_rgb[2] = {};  ///< per yarn, 1/mm
  DoubleLayerGrid layers[2];               ///< front (warp over weft), back
  double blend = 0.5;                      ///< s of Eq. S.22
  // Render tables, as the shaders read them.
  const Image *nodes_high[2] = {}, *nodes_refl[2] = {}, *tint[2] = {}, *factors[2] = {};
  const Image* residual[2] = {};  ///< ply_residual_<yarn>
  const Image* microfacet_albedo = nullptr;
  const Image* asg_integral = nullptr;  ///< asg_integral_lut (asg.h: asg_integral_from_lut)
  GapDiffraction diffraction;
  SpeckleNoise noise;
};
/// Throws std::runtime_error naming what is missing when the atlas is not a ray-wave atlas with
/// render tables.
RaywaveData load_raywave(const Atlas& a);

/// One closure of the mixture (for tests and reports): kind 0 Beckmann reflection, 1 translucent,
/// 2 Beckmann refraction (eta LOOM_RAYWAVE_ETA), 3 diffuse, 4 transparent (the open gaps' delta
/// transmission, less what the gap diffraction samples; the sampled diffraction lobes, which
/// change with every shading sample, are evaluated in expectation and not listed). A fitted
/// lobe gives one to three closures (raywave_lobe_closures, those of nonzero share), listed
/// first, lobe by lobe (f_refl's, then f_high's); the rest follow with lobe = -1.
struct RaywaveClosure {
  int kind = 0;
  shading::vec3 N, T;
  float alpha_x = 1, alpha_y = 1;
  std::array<float, 3> weight = {};
  int lobe = -1;      ///< the fitted lobe it maps, or -1
  float share = 1;    ///< the share of that lobe it carries (raywave_lobe_closures)
};

/// A shading point set up for one view wo (Cycles' setup/eval split): the lobes at (theta_i, h)
/// and the double-layer factors (Model), or the closure mixture (Closures). Cheap to copy.
class RaywavePoint {
 public:
  /// `gap_diffraction` false leaves the open gaps' diffraction out (delta transmission only,
  /// which eval() never returns): for quadratures over the sphere, which cannot resolve it.
  RaywavePoint(const RaywaveData& d, const SurfacePoint& p, shading::vec3 wo, Evaluator e,
               bool gap_diffraction = true);
  /// f times cosine (header comment), RGB, for light from wi.
  std::array<float, 3> eval(shading::vec3 wi) const;
  /// The mixture the shaders emit (Closures; empty for Model).
  const std::vector<RaywaveClosure>& closures() const;
  struct Impl;

 private:
  std::shared_ptr<const Impl> impl_;
};

/// RaywavePoint(d, p, wo, e).eval(wi).
std::array<float, 3> raywave_eval(const RaywaveData& d, const SurfacePoint& p, shading::vec3 wi,
                                  shading::vec3 wo, Evaluator e);

/// raywave_eval averaged over the texels of one weave repeat (each texel's surface maps read as
/// they are, as an Image Texture node with 'Closest' interpolation does): what a render of many
/// repeats shows per unit irradiance (the node-mode parity test compares with it).
std::array<float, 3> raywave_eval_average(const Atlas& a, const RaywaveData& d, shading::vec3 wi,
                                          shading::vec3 wo, Evaluator e);

/// Directional albedo of the cloth seen from wo: the energy it sends back to wo's side
/// (reflect) and through to the other side (transmit) per unit irradiance, RGB, mean over
/// `texels` texels of the repeat, by midpoint quadrature over a sphere of light directions
/// (sphere_n x 2 sphere_n). Ray-wave atlases: the model or the closure mixture. The light through
/// the open gaps (too narrow for the quadrature) is counted apart: `gap`, and the share of it
/// that the closures send into diffraction lobes rather than transparent() (diffraction_sampling.h).
struct DirectionalAlbedo {
  std::array<double, 3> reflect{0, 0, 0}, transmit{0, 0, 0};  ///< the yarns' scattering
  double gap = 0;  ///< mean open fraction: what the gaps pass (delta or diffracted)
  std::array<double, 3> diffracted{0, 0, 0};  ///< of it, what the closures diffract (lobes)
};
DirectionalAlbedo raywave_albedo(const Atlas& a, const RaywaveData& d, shading::vec3 wo,
                                 Evaluator e, int texels = 64, int sphere_n = 96);

/// The closure-mapping error by kind of closure: for each of the fitted lobes the shaders turn
/// into a Beckmann reflection (kind 0), a Beckmann refraction (2) or a translucent closure (1),
/// the lobes of that kind together (their model, with the factors that multiply them, against
/// their closures), the energy residual (exact by construction, a check) and the layers' light
/// from the point's forward light T (double_layer_factors.h: the model's T splits each lobe at
/// the cloth's plane, the closures' by its share raywave_reflection_share). Same texels, views and sphere as raywave_mapping_error.
struct MappingByKind {
  MappingError reflection, refraction, translucent, residual, layer_diffuse;
};
MappingByKind raywave_mapping_by_kind(const Atlas& a, const RaywaveData& d, int texels = 64,
                                      int views = 24, int sphere_n = 96);

/// The closure-mapping error of mapping_error() (evaluator.h) for a ray-wave atlas: relative L1
/// over the sphere of light directions of the eval quantity, green channel.
MappingError raywave_mapping_error(const Atlas& a, const RaywaveData& d, int texels = 64,
                                   int views = 24, int sphere_n = 96);

}  // namespace loom
