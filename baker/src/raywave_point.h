// The ray-wave BSDF's shading point inside the baker (raywave_bsdf.h's RaywavePoint): what a
// view sets up once (Cycles' setup/eval split), shared by the evaluator (raywave_bsdf.cpp) and
// the measures over the sphere that look into its parts (raywave_measures.cpp). Private to
// baker/src.
#pragma once
#include <array>
#include <vector>

#include "loom/cycles_closures.h"
#include "loom/raywave_bsdf.h"

namespace loom {

/// A shading point set up for one view (Cycles' setup/eval split).
struct RaywavePoint::Impl {
  Evaluator e = Evaluator::Model;
  bool valid = false, back = false;
  shading::vec3 V, xp, yp, t;
  float open = 0, vis_v = 1, s = 0.5f;
  float hor[LOOM_HORIZON_DIRS] = {};
  // model
  std::vector<AsgLobe> refl, high[3];
  std::array<float, 3> res_b{}, res_f{};  ///< energy residual per side (asg_residual.h)
  /// double_layer_factors.h: k_b, k_f at xi = V, and the point's forward light T (model: the
  /// lobes' energy below the cloth's plane plus the forward residual; closures: the lobes'
  /// raywave_lobe_forward plus e_f)
  std::array<float, 3> k_b{}, k_f{}, t_fwd{};
  // closures
  std::vector<cycles::MicrofacetReflection> mf;
  std::vector<std::array<float, 3>> mf_w;
  std::vector<cycles::MicrofacetRefraction> refr;
  std::vector<std::array<float, 3>> refr_w;
  std::array<float, 3> transl_w{}, diffuse_w{};
  std::vector<RaywaveClosure> list;
  /// model: f_refl's lobes per channel with raywave_energy_budget's factors in their amplitudes
  /// (high's are scaled in place), and the factor of the residual's and the layers' light
  std::array<std::vector<AsgLobe>, 3> refl_rgb;
  std::array<float, 3> rest_scale{1, 1, 1};
  // speckle noise (speckle_noise.h): the point's instance and rotation, the beam in ply space
  const SpeckleNoise* noise = nullptr;
  int noise_instance = 0;
  float noise_shift = 0;
  shading::vec3 wi_ply;
  // gap diffraction (diffraction_sampling.h): the texel's open fraction and the tiles its
  // offset blends, with their weights (the probabilities of diffraction_tile_pick)
  const GapDiffraction* dif = nullptr;
  const Image* albedo_lut = nullptr;
  float gap = 0;
  int tiles = 0;
  std::vector<int> tile;
  std::vector<float> tile_w;
  std::vector<std::array<float, 3>> p_out;
};

/// The point at `p_in` seen from wo: the model's lobes, factors and residual (Model) or the
/// closure mixture the shaders emit (Closures); `gap_diffraction` as RaywavePoint's.
RaywavePoint::Impl raywave_prepare(const RaywaveData& d, const SurfacePoint& p_in,
                                   shading::vec3 wo, Evaluator e, bool gap_diffraction);

/// The model's speckle noise factors (Eq. S.39) at ply-space direction lp: f_refl's (nr) and
/// f_high's (nh), 1 without noise.
void raywave_model_noise(const RaywavePoint::Impl& q, const Vec3d& lp, float nr[4], float nh[4]);

}  // namespace loom
