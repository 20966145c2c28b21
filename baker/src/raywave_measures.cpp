// Measures of a ray-wave atlas over the sphere of light directions and over its texels
// (raywave_bsdf.h): the repeat-averaged BSDF, the closure-mapping error (also by kind of
// closure) and the directional albedo, for the model and for the closure mixture.
#include <algorithm>
#include <cmath>
#include <memory>
#include <tbb/parallel_for.h>

#include "loom/raywave_bsdf.h"
#include "raywave_point.h"

namespace loom {

using namespace shading;

std::array<float, 3> raywave_eval_average(const Atlas& a, const RaywaveData& d, vec3 wi, vec3 wo,
                                          Evaluator e) {
  const Image& ref = a.map("ply_frame");
  double acc[3] = {0, 0, 0};
  for (int iy = 0; iy < ref.height; ++iy)
    for (int ix = 0; ix < ref.width; ++ix) {
      const std::array<float, 3> f = raywave_eval(d, texel_surface(a, ix, iy), wi, wo, e);
      for (int c = 0; c < 3; ++c) acc[c] += f[size_t(c)];
    }
  const double n = double(ref.width) * ref.height;
  return {float(acc[0] / n), float(acc[1] / n), float(acc[2] / n)};
}

MappingByKind raywave_mapping_by_kind(const Atlas& a, const RaywaveData& d, int texels,
                                      int views, int sphere_n) {
  // Part k of the model and of the closures at L (green, f cos): 0 reflection, 2 refraction,
  // 1 translucent lobes (by the closures' kind), 3 the energy residual, 4 the layers' light from
  // T (the diffuse BTDF of S.22 and the light returned backwards: double_layer_factors.h).
  auto part = [](const RaywavePoint::Impl& qm, const RaywavePoint::Impl& qc, int k, vec3 wi) {
    std::pair<float, float> out{0.0f, 0.0f};
    if (!qm.valid || !qc.valid) return out;
    const vec3 L = normalize(qm.back ? vec3(wi.x, wi.y, -wi.z) : wi);
    const Vec3d lp{dot(L, qm.xp), dot(L, qm.yp), dot(L, qm.t)};
    const vec3 n(0, 0, 1);
    const double lambert = std::fabs(L.z) / M_PI * qm.rest_scale[1];
    // The lobes' closures come first (one to three a lobe), then the rest (lobe = -1): the
    // layers' translucent and diffuse parts, the residual's diffuse and translucent ones,
    // transparent().
    size_t nl = 0;
    while (nl < qc.list.size() && qc.list[nl].lobe >= 0) ++nl;
    if (k == 3) {
      const double m = L.z > 0 ? qm.open * qm.vis_v * qm.res_b[1] * lambert
                               : qm.open * (1 - qm.s) * qm.k_f[1] * qm.res_f[1] * lambert;
      const float c = qc.list[nl + 2].weight[1] * cycles::diffuse_eval(n, L, n) +
                      qc.list[nl + 3].weight[1] * cycles::translucent_eval(n, L, n);
      return std::pair<float, float>(float(m), c);
    }
    if (k == 4) {
      const double m = L.z < 0 ? qm.open * qm.s * qm.k_f[1] * qm.t_fwd[1] * lambert
                               : qm.open * qm.vis_v * qm.k_b[1] * qm.t_fwd[1] * lambert;
      return std::pair<float, float>(
          float(m), qc.list[nl].weight[1] * cycles::translucent_eval(n, L, n) +
                        qc.list[nl + 1].weight[1] * cycles::diffuse_eval(n, L, n));
    }
    float nr[4], nh[4];
    raywave_model_noise(qm, lp, nr, nh);
    const float vis_l = qm.back || L.z <= 0 ? 1.0f : horizon_visibility(L, const_cast<float*>(qm.hor));
    const double factor = L.z > 0 ? qm.open * qm.vis_v * vis_l
                                  : qm.open * (1 - qm.s) * qm.k_f[1];
    size_t imf = 0, irf = 0;
    for (size_t i = 0; i < nl; ++i) {
      const RaywaveClosure& cl = qc.list[i];
      float c = 0;
      if (cl.kind == 0) {
        c = qc.mf[imf].eval(L) * qc.mf_w[imf][1];
        ++imf;
      } else if (cl.kind == 2) {
        c = qc.refr[irf].eval(L) * qc.refr_w[irf][1];
        ++irf;
      } else {
        c = cl.weight[1] * cycles::translucent_eval(n, L, n);
      }
      if (cl.kind != k) continue;
      // The model's part of kind k: each lobe's share of that kind.
      const size_t l = size_t(cl.lobe);
      const bool refl = l < qm.refl.size();
      const AsgLobe& lobe = refl ? qm.refl_rgb[1][l] : qm.high[1][l - qm.refl.size()];
      const double f = cl.share * asg_mixture_eval({lobe}, lp) * (refl ? nr[1] : nh[1]);
      out.first += float(f * factor);
      out.second += c;
    }
    return out;
  };
  MappingByKind r;
  MappingError* slot[5] = {&r.reflection, &r.translucent, &r.refraction, &r.residual,
                           &r.layer_diffuse};
  for (int k = 0; k < 5; ++k)
    *slot[k] = mapping_error_loop(a, texels, views, sphere_n, [&d, k, part](const SurfacePoint& p, vec3 v) {
      auto qm = std::make_shared<const RaywavePoint::Impl>(raywave_prepare(d, p, v, Evaluator::Model, false));
      auto qc = std::make_shared<const RaywavePoint::Impl>(raywave_prepare(d, p, v, Evaluator::Closures, false));
      return MappingPair([qm, qc, k, part](vec3 l) { return part(*qm, *qc, k, l); });
    });
  return r;
}

MappingError raywave_mapping_error(const Atlas& a, const RaywaveData& d, int texels, int views,
                                   int sphere_n) {
  return mapping_error_loop(a, texels, views, sphere_n, [&d](const SurfacePoint& p, vec3 v) {
    // (The gaps' diffraction is too narrow for the sphere of directions: left out of both.)
    const RaywavePoint pm(d, p, v, Evaluator::Model, false), pc(d, p, v, Evaluator::Closures, false);
    return MappingPair([pm, pc](vec3 l) {  // eval is already BSDF times cosine
      return std::pair<float, float>(pm.eval(l)[1], pc.eval(l)[1]);
    });
  });
}


DirectionalAlbedo raywave_albedo(const Atlas& a, const RaywaveData& d, vec3 wo, Evaluator e,
                                 int texels, int sphere_n) {
  const Image& ref = a.map("ply_frame");
  const int side = std::max(1, int(std::lround(std::sqrt(double(std::max(texels, 1))))));
  const double dw = sphere_grid_dw(sphere_n);
  const std::vector<vec3> lights = sphere_grid(sphere_n);
  std::vector<DirectionalAlbedo> per(size_t(side) * side);
  tbb::parallel_for(0, side * side, [&](int idx) {
    const int ix = int((idx % side + 0.5) / side * ref.width);
    const int iy = int((idx / side + 0.5) / side * ref.height);
    const SurfacePoint p = texel_surface(a, ix, iy);
    const RaywavePoint pt(d, p, wo, e, false);
    DirectionalAlbedo& r = per[size_t(idx)];
    for (const vec3& l : lights) {
      const std::array<float, 3> f = pt.eval(l);
      auto& acc = (l.z > 0) == (wo.z > 0) ? r.reflect : r.transmit;
      for (int c = 0; c < 3; ++c) acc[size_t(c)] += f[size_t(c)] * dw;
    }
    r.gap = std::clamp(p.gap, 0.0f, 1.0f);
    const RaywavePoint pc(d, p, wo, Evaluator::Closures);  // (named: it owns the list)
    for (const RaywaveClosure& cl : pc.closures())
      if (cl.kind == 4)
        for (int c = 0; c < 3; ++c) r.diffracted[size_t(c)] = r.gap - cl.weight[size_t(c)];
  });
  DirectionalAlbedo out;
  for (const DirectionalAlbedo& r : per) {
    for (int c = 0; c < 3; ++c) {
      out.reflect[size_t(c)] += r.reflect[size_t(c)] / double(per.size());
      out.transmit[size_t(c)] += r.transmit[size_t(c)] / double(per.size());
    }
    out.gap += r.gap / double(per.size());
    for (int c = 0; c < 3; ++c) out.diffracted[size_t(c)] += r.diffracted[size_t(c)] / double(per.size());
  }
  return out;
}

}  // namespace loom
