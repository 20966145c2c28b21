// An atlas's BSDF at a point of the weave repeat, read as its shader reads it (the surface tier
// bilinearly, as Linear image textures do; the ray-wave tier from the nearest texel, as Closest
// does), set up once for a view and then evaluated for many light directions: the common inner
// loop of the quadratures that compare an atlas with something else (preset_error.h against
// another preset, truth_error.h against the fibers).
#pragma once
#include <array>
#include <functional>
#include <memory>

#include "loom/atlas.h"
#include "loom/evaluator.h"
#include "loom/shading.h"

namespace loom {

struct RaywaveData;

class AtlasBsdf {
 public:
  /// The model or the closure mixture (closures as node mode builds them) of atlas a, which must
  /// outlive this.
  AtlasBsdf(const Atlas& a, Evaluator e);
  ~AtlasBsdf();
  bool raywave() const { return raywave_; }
  /// f(L, wo) |cos L| (RGB; L towards the light, wo towards the viewer, the cloth's frame) at
  /// (u, v) of the repeat seen from wo, as a function of L. The open gaps' delta transmission
  /// and (ray-wave) their diffraction are not in it: no quadrature over L resolves them.
  std::function<std::array<float, 3>(shading::vec3)> at(float u, float v, shading::vec3 wo) const;
  /// The open fraction at (u, v): what passes the gaps as a delta (transparent(), both tiers and
  /// both evaluators), or, on the ray-wave tier, is diffracted about the delta.
  float open(float u, float v) const;

 private:
  SurfacePoint point(float u, float v) const;
  const Atlas& a_;
  Evaluator e_;
  bool raywave_;
  std::unique_ptr<RaywaveData> data_;
};

}  // namespace loom
