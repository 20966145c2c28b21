#include "loom/fiber_truth.h"

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "loom/absorption.h"
#include "loom/colour.h"
#include "loom/fiber_optics.h"
#include "loom/ply_scattering.h"
#include "loom/weave.h"
#include "loom/woven_patch.h"

namespace loom {
namespace {

/// A fiber segment as the tracer sees it: the axis from p0 along unit `axis` over `len`.
struct Segment {
  Vec3d p0, axis;
  double len = 0, r = 0;
  uint8_t material = 0;
};

void embree_error(void* user, RTCError code, const char* what) {
  auto* msg = static_cast<std::string*>(user);
  if (msg->empty()) *msg = fmt::format("Embree error {}: {}", int(code), what ? what : "");
}

/// Per block of rays: the tally and the sums for the standard errors.
struct Tally {
  std::vector<double> bins;  // res x res x 3
  std::array<double, 3> refl{}, trans{}, abs{}, refl2{}, trans2{}, abs2{};
  double direct = 0, truncated = 0;
};

}  // namespace

struct FiberTruthScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::string error;
  std::vector<Segment> seg;
  std::vector<FiberMaterial> materials;
  std::array<double, 4> tile{};
  double z_lo = 0, z_hi = 0, eps = 1e-3;
  size_t curves = 0;

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  /// The nearest fiber wall along o + t d for t in (eps, t_max): segment index or -1.
  int intersect(const Vec3d& o, const Vec3d& d, double t_max, double& t) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh{};
    rh.ray.org_x = float(o.x), rh.ray.org_y = float(o.y), rh.ray.org_z = float(o.z);
    rh.ray.dir_x = float(d.x), rh.ray.dir_y = float(d.y), rh.ray.dir_z = float(d.z);
    rh.ray.tnear = float(eps);
    rh.ray.tfar = float(t_max);
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return -1;
    t = rh.ray.tfar;
    return int(rh.hit.primID);
  }

  /// Outward unit normal at q of the infinite cylinder about segment s's axis: the surface the
  /// ray then leaves through (cylinder_exit), so that entry and exit meet one straight
  /// cylinder and no ray is trapped by total internal reflection, which a perfect cylinder never
  /// does (near a joint Embree's surface is the neighbour's cone or the joint's sphere; the
  /// difference is a fraction of a fiber radius along a bend of the fiber).
  Vec3d normal_at(const Segment& s, const Vec3d& q) const {
    return normalized(q - (s.p0 + s.axis * dot(q - s.p0, s.axis)));
  }

  void wrap(Vec3d& o) const {
    const double wx = tile[2] - tile[0], wy = tile[3] - tile[1];
    if (o.x >= tile[2]) o.x -= wx * std::floor((o.x - tile[0]) / wx);
    if (o.x < tile[0]) o.x += wx * std::ceil((tile[0] - o.x) / wx);
    if (o.y >= tile[3]) o.y -= wy * std::floor((o.y - tile[1]) / wy);
    if (o.y < tile[1]) o.y += wy * std::ceil((tile[1] - o.y) / wy);
    o.x = std::clamp(o.x, tile[0], std::nextafter(tile[2], tile[0]));
    o.y = std::clamp(o.y, tile[1], std::nextafter(tile[3], tile[1]));
  }

  TruthPath trace_ray(const Vec3d& wi, const TruthSettings& s, RayRng& rng) const;
};

namespace {

/// A path's weight per channel for the materials' absorption: exp(-sum_m sigma_m len_m).
std::array<double, 3> path_weight(const TruthPath& p, const std::vector<FiberMaterial>& m) {
  std::array<double, 3> w{};
  for (size_t c = 0; c < 3; ++c) {
    double tau = 0;
    for (size_t k = 0; k < m.size(); ++k) tau += m[k].sigma_per_um[c] * double(p.len_um[k]);
    w[c] = std::exp(-tau);
  }
  return w;
}

/// Adds one path to a tally, with the materials' absorption.
void tally_path(const TruthPath& p, const std::vector<FiberMaterial>& m, bool wi_up, Tally& out) {
  const std::array<double, 3> w = path_weight(p, m);
  for (size_t c = 0; c < 3; ++c) {
    out.abs[c] += 1 - w[c];
    out.abs2[c] += (1 - w[c]) * (1 - w[c]);
  }
  if (p.exit == TruthPath::Truncated) {
    out.truncated += (w[0] + w[1] + w[2]) / 3;
    return;
  }
  const bool same_side = (p.exit == TruthPath::Up) == wi_up;
  auto& sum = same_side ? out.refl : out.trans;
  auto& sum2 = same_side ? out.refl2 : out.trans2;
  for (size_t c = 0; c < 3; ++c) sum[c] += w[c], sum2[c] += w[c] * w[c];
  if (!p.touched) {  // the delta at -wi: counted apart, not in the density (header comment)
    out.direct += 1;
    return;
  }
  for (size_t c = 0; c < 3; ++c) out.bins[size_t(p.bin) * 3 + c] += w[c];
}

}  // namespace

TruthPath FiberTruthScene::Impl::trace_ray(const Vec3d& wi, const TruthSettings& s,
                                           RayRng& rng) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double x = tile[0] + rng.next() * (tile[2] - tile[0]);
  const double y = tile[1] + rng.next() * (tile[3] - tile[1]);
  Vec3d o{x, y, wi.z > 0 ? z_hi : z_lo};
  Vec3d d = wi * -1.0;
  TruthPath path;
  int events = 0;
  bool touched = false, truncated = false;
  // A ray crossing the tile sideways many times (near grazing) is bounded like one that bounces.
  for (int steps = 0;; ++steps) {
    if (events >= s.max_events || steps > 64 * s.max_events) {
      truncated = true;
      break;
    }
    wrap(o);
    const double tx = d.x > 0 ? (tile[2] - o.x) / d.x : d.x < 0 ? (tile[0] - o.x) / d.x : kInf;
    const double ty = d.y > 0 ? (tile[3] - o.y) / d.y : d.y < 0 ? (tile[1] - o.y) / d.y : kInf;
    const double tz = d.z > 0 ? (z_hi - o.z) / d.z : d.z < 0 ? (z_lo - o.z) / d.z : kInf;
    const double t_box = std::max(std::min({tx, ty, tz}), 0.0);
    double t = 0;
    const int hit = intersect(o, d, std::min(t_box, 1e30), t);
    if (hit < 0) {
      if (tz <= std::min(tx, ty)) break;  // leaves the slab of fibers: escaped
      o = o + d * t_box;
      if (t_box == tx) o.x = d.x > 0 ? tile[2] : tile[0] - 1e-9 * (tile[2] - tile[0]);
      if (t_box == ty) o.y = d.y > 0 ? tile[3] : tile[1] - 1e-9 * (tile[3] - tile[1]);
      continue;
    }
    const Segment& sg = seg[size_t(hit)];
    const double ior = materials[sg.material].ior;
    Vec3d q = o + d * t;
    const Vec3d n = normal_at(sg, q);
    const double cos_i = -dot(d, n);
    if (!(cos_i > 0)) {  // a wall met from inside an overlapping fiber: passed through
      o = q;
      continue;
    }
    touched = true;
    ++events;
    double cos_t = 0;
    const double F = fresnel_dielectric(cos_i, ior, cos_t);
    if (rng.next() < F) {
      d = reflected(d, n);
      o = q;
      continue;
    }
    d = refracted(d, n, cos_i, cos_t, ior);
    // Inside the fiber: the wall of the segment's cylinder until the ray refracts out.
    for (;;) {
      double te = 0;
      Vec3d ne = n;
      if (!cylinder_exit(sg.p0, sg.axis, sg.r, q, d, te, ne)) te = 0;  // tangent: leave here
      path.len_um[sg.material] += float(te);
      q = q + d * te;
      const double ci = dot(d, ne);  // > 0: meeting the wall from inside
      if (!(ci > 0)) break;
      double cto = 0;
      const double Fi = fresnel_dielectric(ci, 1 / ior, cto);
      if (++events >= s.max_events) break;
      if (rng.next() < Fi) {
        d = reflected(d, ne);
        continue;
      }
      d = refracted(d, ne * -1.0, ci, cto, 1 / ior);
      break;
    }
    o = q;
  }
  path.touched = touched;
  if (truncated) {
    path.exit = TruthPath::Truncated;
    return path;
  }
  path.exit = d.z > 0 ? TruthPath::Up : TruthPath::Down;
  const int res = s.res;
  const int row = std::clamp(int(std::floor((d.z + 1) * 0.5 * res)), 0, res - 1);
  const int col = std::clamp(int(std::floor((std::atan2(d.y, d.x) + M_PI) / (2 * M_PI) * res)), 0,
                             res - 1);
  path.bin = row * res + col;
  return path;
}

FiberTruthScene::FiberTruthScene(const FiberCurves& curves, const std::vector<uint8_t>& material,
                                 std::vector<FiberMaterial> materials, std::array<double, 4> tile)
    : impl_(std::make_unique<Impl>()) {
  Impl& I = *impl_;
  I.materials = std::move(materials);
  I.tile = tile;
  I.curves = curves.curves();
  if (!(tile[0] < tile[2] && tile[1] < tile[3]))
    throw std::invalid_argument("tile: x0 < x1 and y0 < y1 are needed");
  if (material.size() != curves.curves())
    throw std::invalid_argument("material: one entry per curve is needed");
  if (I.materials.empty() || I.materials.size() > kTruthMaterials)
    throw std::invalid_argument("materials: one or two (warp and weft) are traced");
  I.device = rtcNewDevice(nullptr);
  if (!I.device) throw std::runtime_error("Embree: cannot create a device");
  rtcSetDeviceErrorFunction(I.device, embree_error, &I.error);

  std::vector<float> verts;  // x, y, z, r
  std::vector<unsigned> index;
  double r_min = std::numeric_limits<double>::infinity();
  I.z_lo = std::numeric_limits<double>::infinity();
  I.z_hi = -I.z_lo;
  for (size_t c = 0; c < curves.curves(); ++c) {
    if (material[c] >= I.materials.size())
      throw std::invalid_argument(fmt::format("material: curve {} names material {} of {}", c,
                                              int(material[c]), I.materials.size()));
    const double r = curves.radius[c];
    r_min = std::min(r_min, r);
    for (uint32_t v = curves.first[c]; v < curves.first[c + 1]; ++v) {
      const float* p = &curves.points[size_t(v) * 3];
      I.z_lo = std::min(I.z_lo, double(p[2]) - r);
      I.z_hi = std::max(I.z_hi, double(p[2]) + r);
      if (v + 1 < curves.first[c + 1]) {
        const float* p1 = p + 3;
        const Vec3d a{p[0], p[1], p[2]}, b{p1[0], p1[1], p1[2]};
        const double len = std::sqrt(dot(b - a, b - a));
        if (len > 1e-9) {
          index.push_back(unsigned(verts.size() / 4));
          I.seg.push_back({a, (b - a) * (1 / len), len, r, material[c]});
        }
      }
      verts.insert(verts.end(), {p[0], p[1], p[2], float(r)});
    }
  }
  if (I.seg.empty()) throw std::invalid_argument("curves: no fiber segment to trace");
  I.z_lo -= 1, I.z_hi += 1;  // start and end rays clear of every fiber
  I.eps = 1e-2 * r_min;
  RTCGeometry g = rtcNewGeometry(I.device, RTC_GEOMETRY_TYPE_ROUND_LINEAR_CURVE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0,
                                                         RTC_FORMAT_FLOAT4, 4 * sizeof(float),
                                                         verts.size() / 4));
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, sizeof(unsigned), index.size()));
  if (vb && ib) {
    std::copy(verts.begin(), verts.end(), vb);
    std::copy(index.begin(), index.end(), ib);
  }
  rtcCommitGeometry(g);
  I.scene = rtcNewScene(I.device);
  rtcSetSceneFlags(I.scene, RTC_SCENE_FLAG_ROBUST);
  rtcAttachGeometry(I.scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(I.scene);
  if (!I.error.empty() || !vb || !ib) throw std::runtime_error(I.error.empty() ? "Embree: no buffers" : I.error);
}

FiberTruthScene::~FiberTruthScene() = default;

size_t FiberTruthScene::curves() const { return impl_->curves; }

TruthPaths FiberTruthScene::paths(const Vec3d& wi_in, const TruthSettings& s) const {
  const Vec3d wi = normalized(wi_in);
  if (!(std::fabs(wi.z) >= 1e-3))
    throw std::invalid_argument("wi: the light must not be parallel to the cloth (|z| >= 1e-3)");
  return paths_of(wi, false, s);
}

TruthPaths FiberTruthScene::diffuse_paths(bool from_above, const TruthSettings& s) const {
  return paths_of({0, 0, from_above ? 1.0 : -1.0}, true, s);
}

TruthPaths FiberTruthScene::paths_of(const Vec3d& wi, bool diffuse, const TruthSettings& s) const {
  const Impl& I = *impl_;
  if (s.res < 1 || s.rays < 1) throw std::invalid_argument("rays and res must be >= 1");
  TruthPaths out;
  out.wi = wi;
  out.diffuse = diffuse;
  out.res = s.res;
  out.paths.resize(s.rays);
  tbb::parallel_for(uint64_t(0), s.rays, [&](uint64_t r) {
    RayRng rng(s.seed, 7, r);
    Vec3d w = wi;
    if (diffuse) {  // cosine-weighted over wi's hemisphere (Malley), |z| kept off the plane
      const double u = rng.next(), phi = 2 * M_PI * rng.next();
      const double z = std::max(std::sqrt(1 - u), 1e-3), rr = std::sqrt(1 - z * z);
      w = {rr * std::cos(phi), rr * std::sin(phi), wi.z > 0 ? z : -z};
    }
    out.paths[r] = I.trace_ray(w, s, rng);
  });
  return out;
}

TruthResult FiberTruthScene::tally(const TruthPaths& p,
                                   const std::vector<FiberMaterial>& materials) const {
  const Impl& I = *impl_;
  if (materials.size() != I.materials.size())
    throw std::invalid_argument("tally: one material per material of the scene is needed");
  const uint64_t rays = p.paths.size();
  if (rays < 1) throw std::invalid_argument("tally: no paths");
  const int res = p.res;
  // Blocks of paths, each with its own tally, summed in block order: the result does not depend
  // on the thread count.
  const uint64_t blocks = std::min<uint64_t>(64, rays);
  std::vector<Tally> tallies(blocks);
  tbb::parallel_for(uint64_t(0), blocks, [&](uint64_t b) {
    Tally& t = tallies[b];
    t.bins.assign(size_t(res) * size_t(res) * 3, 0.0);
    const uint64_t r0 = rays * b / blocks, r1 = rays * (b + 1) / blocks;
    for (uint64_t r = r0; r < r1; ++r) tally_path(p.paths[r], materials, p.wi.z > 0, t);
  });
  TruthResult out;
  out.res = res;
  out.rays = rays;
  out.segments = I.seg.size();
  out.curves = I.curves;
  out.tile_um = I.tile;
  out.z_lo_um = I.z_lo, out.z_hi_um = I.z_hi;
  std::vector<double> bins(size_t(res) * size_t(res) * 3, 0.0);
  Tally sum;
  for (const Tally& t : tallies) {
    for (size_t k = 0; k < bins.size(); ++k) bins[k] += t.bins[k];
    for (size_t c = 0; c < 3; ++c) {
      sum.refl[c] += t.refl[c], sum.trans[c] += t.trans[c], sum.abs[c] += t.abs[c];
      sum.refl2[c] += t.refl2[c], sum.trans2[c] += t.trans2[c], sum.abs2[c] += t.abs2[c];
    }
    sum.direct += t.direct, sum.truncated += t.truncated;
  }
  const double N = double(rays);
  auto se = [N](double s1, double s2) {
    const double m = s1 / N;
    return std::sqrt(std::max(s2 / N - m * m, 0.0) / N);
  };
  for (size_t c = 0; c < 3; ++c) {
    out.reflect[c] = sum.refl[c] / N, out.reflect_se[c] = se(sum.refl[c], sum.refl2[c]);
    out.transmit[c] = sum.trans[c] / N, out.transmit_se[c] = se(sum.trans[c], sum.trans2[c]);
    out.absorbed[c] = sum.abs[c] / N, out.absorbed_se[c] = se(sum.abs[c], sum.abs2[c]);
  }
  out.direct = sum.direct / N;
  out.truncated = sum.truncated / N;
  const double per_sr = 1.0 / (N * 4 * M_PI / (double(res) * res));
  out.density.resize(bins.size());
  for (size_t k = 0; k < bins.size(); ++k) out.density[k] = float(bins[k] * per_sr);
  return out;
}

TruthResult FiberTruthScene::trace(const Vec3d& wi, const TruthSettings& s) const {
  return tally(paths(wi, s), impl_->materials);
}

const std::vector<FiberMaterial>& FiberTruthScene::materials() const { return impl_->materials; }

std::array<double, 4> truth_tile(const FabricSpec& spec, int min_yarns) {
  const Weave w = make_weave(spec.weave);
  const WovenSpacing sp = woven_spacing(spec);
  const int kx = std::max(1, (min_yarns + w.cols() - 1) / w.cols());
  const int ky = std::max(1, (min_yarns + w.rows() - 1) / w.rows());
  return {0.0, 0.0, kx * w.cols() * sp.x, ky * w.rows() * sp.y};
}

std::array<FiberMaterial, 2> truth_materials(const FabricSpec& spec) {
  std::array<FiberMaterial, 2> out;
  const ColourConverter cc("");
  const SpectralUpsampler up(cc, 5.0);
  for (int i = 0; i < 2; ++i) {
    const YarnSpec& y = i == 0 ? spec.warp : spec.weft;
    const AbsorptionCurve curve = absorption_curve(y, spec.quality);
    const double sigma_max = ply_sim_settings(spec.quality).sigmas.back();
    const YarnAbsorption ya = yarn_absorption(y.color_linear, up, fit_absorption(curve), curve,
                                              sigma_max);
    out[size_t(i)].ior = y.ior;
    for (size_t c = 0; c < 3; ++c) out[size_t(i)].sigma_per_um[c] = ya.sigma_rgb[c] * 1e-3;
  }
  return out;
}

std::unique_ptr<FiberTruthScene> make_truth_scene(const FabricSpec& spec, int min_yarns) {
  const auto tile = truth_tile(spec, min_yarns);
  const FiberCurves curves = realize_fiber_region(spec, {tile[0], tile[1], tile[2], tile[3]});
  std::vector<uint8_t> material(curves.curves());
  for (size_t c = 0; c < material.size(); ++c) material[c] = curves.yarn[c] % 2;  // warp even
  const auto m = truth_materials(spec);
  return std::make_unique<FiberTruthScene>(curves, material,
                                           std::vector<FiberMaterial>{m[0], m[1]}, tile);
}

TruthResult fiber_truth(const FabricSpec& spec, const Vec3d& wi, const TruthSettings& s) {
  return make_truth_scene(spec, s.min_yarns)->trace(wi, s);
}

}  // namespace loom
