#include "loom/atlas_bsdf.h"

#include <algorithm>
#include <cmath>

#include "loom/raywave_bsdf.h"

namespace loom {

using namespace shading;

AtlasBsdf::AtlasBsdf(const Atlas& a, Evaluator e)
    : a_(a), e_(e), raywave_(a.manifest.value("tier", "") == "raywave") {
  if (raywave_) data_ = std::make_unique<RaywaveData>(load_raywave(a));
}

AtlasBsdf::~AtlasBsdf() = default;

SurfacePoint AtlasBsdf::point(float u, float v) const {
  if (!raywave_) return sample_surface(a_, u, v);
  const Image& ref = a_.map("ply_frame");
  const int ix = std::clamp(int(u * ref.width), 0, ref.width - 1);
  const int iy = std::clamp(int(v * ref.height), 0, ref.height - 1);
  return texel_surface(a_, ix, iy);
}

float AtlasBsdf::open(float u, float v) const {
  return std::clamp(guard_surface_point(point(u, v)).gap, 0.0f, 1.0f);
}

std::function<std::array<float, 3>(vec3)> AtlasBsdf::at(float u, float v, vec3 wo) const {
  if (raywave_) {
    const RaywavePoint q(*data_, point(u, v), wo, e_, /*gap_diffraction=*/false);
    return [q](vec3 l) { return q.eval(l); };
  }
  const SurfacePoint p = point(u, v);
  const Atlas* a = &a_;
  const Evaluator e = e_;
  return [a, p, wo, e](vec3 l) {
    auto f = eval_bsdf(*a, p, l, wo, e);
    const float c = std::fabs(l.z);
    return std::array<float, 3>{f[0] * c, f[1] * c, f[2] * c};
  };
}

}  // namespace loom
