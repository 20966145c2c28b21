// The fiber tier's full realization (every fiber's polyline, indexed by a k-d tree of its
// segments' midpoints), the brute-force look-up the tests compare both look-ups with, and the
// test points they use (section 4.3: what the realization-minimising look-up avoids).
#include "loom/fiber_lookup.h"

#include "fiber_search.h"
#include "loom/hair_flyaways.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

namespace loom {

using namespace fiber_search;

// ---- Full realization ----

namespace {

struct Polyline {
  uint32_t first = 0, count = 0;  ///< vertices
  uint32_t ply = 0;
  uint64_t fiber = 0;
  bool hair = false;
  double z1 = 0, z2 = 0;  ///< hair extent
};

struct RealizedYarn {
  double dz = 1, r2 = 0, search = 0;
  std::vector<Vertex2f> verts;
  std::vector<Polyline> polys;
  Cloud<float> mids;               ///< segment midpoints in yarn space
  std::vector<uint32_t> seg_poly;  ///< polyline of each segment
  std::unique_ptr<KdTree<float>> tree;
};

}  // namespace

struct RealizedFibers::Impl {
  const std::vector<PatchYarn>* yarns = nullptr;
  YarnIndex index;
  std::vector<RealizedYarn> realized;
  explicit Impl(const std::vector<PatchYarn>& y) : yarns(&y), index(y) {}
};

RealizedFibers::RealizedFibers(const std::vector<PatchYarn>& yarns, FiberLookupOptions o)
    : impl_((require_patch_z(yarns), std::make_unique<Impl>(yarns))) {
  impl_->realized.resize(yarns.size());
  for (size_t i = 0; i < yarns.size(); ++i) {
    const PlyParams& p = yarns[i].ply;
    const uint32_t seed = yarns[i].seed_index;
    RealizedYarn& Y = impl_->realized[i];
    Y.dz = fiber_step(p);
    Y.r2 = p.fiber_radius * p.fiber_radius;
    const double L = yarns[i].curve.length();
    const int64_t K = grid_index(L, Y.dz) + 2;  // vertices 0..K-1 cover z in [0, L]
    double half = 0;
    auto add_segments = [&](const Polyline& pl, auto z_of) {
      for (uint32_t v = 0; v + 1 < pl.count; ++v) {
        Vertex2f a = Y.verts[pl.first + v], b = Y.verts[pl.first + v + 1];
        double za = z_of(v), zb = z_of(v + 1);
        Y.mids.pts.push_back({0.5f * (a.x + b.x), 0.5f * (a.y + b.y), float(0.5 * (za + zb))});
        Y.seg_poly.push_back(uint32_t(Y.polys.size()));
        double ex = double(b.x) - a.x, ey = double(b.y) - a.y, ez = zb - za;
        half = std::max(half, 0.5 * std::sqrt(ex * ex + ey * ey + ez * ez));
      }
      Y.polys.push_back(pl);
    };
    for (uint32_t ply = 0; ply < uint32_t(std::max(p.plies, 1)); ++ply) {
      for (uint32_t j = 0; j < uint32_t(p.fibers); ++j) {
        Fiber f = make_fiber(p, seed, ply, j);
        Polyline pl{uint32_t(Y.verts.size()), uint32_t(K), ply, j, false, 0, 0};
        for (int64_t k = 0; k < K; ++k)
          Y.verts.push_back(regular_vertex(p, seed, ply, j, f, k, Y.dz));
        add_segments(pl, [&](uint32_t v) { return double(v) * Y.dz; });
      }
      std::vector<HairFlyaway> hairs;
      if (o.realization_free_hairs) {
        hairs = all_hairs_realization_free(p, seed, ply, L);
      } else {
        HairCount hc = ply_hair_count(p, seed, ply, L);
        for (uint32_t j = 0; j < hc.count; ++j)
          hairs.push_back({j, make_hair(p, seed, ply, L, hc, j)});
      }
      for (const auto& hf : hairs) {
        const Hair& h = hf.hair;
        int64_t n = hair_vertex_count(h, Y.dz);
        Polyline pl{uint32_t(Y.verts.size()), uint32_t(n), ply, hf.id, true, h.z1, h.z2};
        for (int64_t m = 0; m < n; ++m)
          Y.verts.push_back(hair_vertex(p, ply, h, hair_vertex_z(h, Y.dz, m)));
        add_segments(pl, [&](uint32_t v) { return hair_vertex_z(h, Y.dz, v); });
      }
    }
    // A covered point is within r of a point of a segment, so within r + half its length of
    // the segment's midpoint; plus float rounding of the midpoints.
    Y.search = (p.fiber_radius + half) * (1 + 1e-5) + 1e-2;
    Y.verts.shrink_to_fit(), Y.polys.shrink_to_fit(), Y.mids.pts.shrink_to_fit();
    Y.seg_poly.shrink_to_fit();
    Y.tree =
        std::make_unique<KdTree<float>>(3, Y.mids, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    Y.tree->buildIndex();
  }
}

RealizedFibers::~RealizedFibers() = default;

FiberHit RealizedFibers::lookup(Vec3d p) const {
  Best best;
  const auto& yarns = *impl_->yarns;
  std::vector<uint32_t> hits, polys;
  for (auto& [yi, proj] : impl_->index.yarns_at(p)) {
    const RealizedYarn& Y = impl_->realized[yi];
    Vec3d yp = yarns[yi].curve.to_yarn(p, proj);
    const double z = yp.z;
    const float q[3] = {float(yp.x), float(yp.y), float(z)};
    hits.clear();
    points_within(*Y.tree, q, float(Y.search), hits);
    polys.clear();
    for (uint32_t h : hits) polys.push_back(Y.seg_poly[h]);
    std::sort(polys.begin(), polys.end());
    polys.erase(std::unique(polys.begin(), polys.end()), polys.end());
    for (uint32_t pi : polys) {
      const Polyline& pl = Y.polys[pi];
      if (!pl.hair) {
        int64_t k;
        double t;
        regular_segment(z, Y.dz, k, t);
        if (k < 0 || k + 1 >= int64_t(pl.count)) continue;
        consider(best, yp.x, yp.y, t, Y.verts[pl.first + size_t(k)],
                 Y.verts[pl.first + size_t(k) + 1], Y.dz, Y.r2, yi, pl.ply, pl.fiber, false, proj);
      } else {
        if (z < pl.z1 || z > pl.z2) continue;
        Hair h;
        h.z1 = pl.z1, h.z2 = pl.z2;
        HairSegment s = hair_segment(h, Y.dz, z);
        if (s.m < 0 || s.m + 1 >= int64_t(pl.count)) continue;
        double ht = s.zb > s.za ? (z - s.za) / (s.zb - s.za) : 0;
        consider(best, yp.x, yp.y, ht, Y.verts[pl.first + size_t(s.m)],
                 Y.verts[pl.first + size_t(s.m) + 1], std::max(s.zb - s.za, 1e-9), Y.r2, yi, pl.ply,
                 pl.fiber, true, proj);
      }
    }
  }
  return finish(best, yarns);
}

size_t RealizedFibers::bytes() const {
  size_t b = sizeof(Impl) + impl_->index.bytes();
  for (const auto& Y : impl_->realized) {
    b += sizeof(RealizedYarn) + Y.verts.capacity() * sizeof(Vertex2f) +
         Y.polys.capacity() * sizeof(Polyline) +
         Y.mids.pts.capacity() * sizeof(std::array<float, 3>) +
         Y.seg_poly.capacity() * sizeof(uint32_t) + Y.tree->usedMemory(*Y.tree);
  }
  return b;
}

uint64_t RealizedFibers::vertex_count() const {
  uint64_t n = 0;
  for (const auto& Y : impl_->realized) n += Y.verts.size();
  return n;
}

FiberHit brute_force_fiber_lookup(const std::vector<PatchYarn>& yarns, Vec3d p,
                                  FiberLookupOptions o) {
  Best best;
  for (uint32_t yi = 0; yi < yarns.size(); ++yi) {
    const PatchYarn& y = yarns[yi];
    const PlyParams& P = y.ply;
    YarnProjection proj;
    for (int k = 0; k < y.curve.pieces(); ++k) {
      YarnProjection pr = y.curve.project_piece(p, k);
      if (pr.distance < proj.distance) proj = pr;
    }
    if (!proj.interior || !(proj.distance <= yarn_reach(P))) continue;
    Vec3d yp = y.curve.to_yarn(p, proj);
    const double z = yp.z, dz = fiber_step(P), r2 = P.fiber_radius * P.fiber_radius;
    const double L = y.curve.length();
    for (uint32_t ply = 0; ply < uint32_t(std::max(P.plies, 1)); ++ply) {
      int64_t k;
      double t;
      regular_segment(z, dz, k, t);
      for (uint32_t j = 0; j < uint32_t(P.fibers); ++j) {
        Fiber f = make_fiber(P, y.seed_index, ply, j);
        consider(best, yp.x, yp.y, t, regular_vertex(P, y.seed_index, ply, j, f, k, dz),
                 regular_vertex(P, y.seed_index, ply, j, f, k + 1, dz), dz, r2, yi, ply, j, false,
                 proj);
      }
      if (o.realization_free_hairs) {
        for (const auto& hf : all_hairs_realization_free(P, y.seed_index, ply, L))
          consider_hair(best, P, ply, hf.hair, dz, yp, r2, yi, hf.id, proj);
      } else {
        HairCount hc = ply_hair_count(P, y.seed_index, ply, L);
        for (uint32_t j = 0; j < hc.count; ++j)
          consider_hair(best, P, ply, make_hair(P, y.seed_index, ply, L, hc, j), dz, yp, r2, yi, j,
                        proj);
      }
    }
  }
  return finish(best, yarns);
}

std::vector<Vec3d> fiber_test_points(const std::vector<PatchYarn>& yarns, int count,
                                     uint64_t seed) {
  std::vector<Vec3d> out;
  if (yarns.empty() || count <= 0) return out;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
  double reach = 0;
  for (const auto& y : yarns) {
    reach = std::max(reach, yarn_reach(y.ply));
    for (auto& v : y.curve.points()) {
      lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
      hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
    }
  }
  out.reserve(size_t(count));
  for (int i = 0; i < count; ++i) {
    if (i % 2 == 0) {
      const auto& y = yarns[size_t(U(rng) * double(yarns.size())) % yarns.size()];
      double rr = yarn_reach(y.ply) * std::sqrt(U(rng)), a = 2 * M_PI * U(rng);
      double z = y.curve.length() * U(rng);
      out.push_back(y.curve.to_fabric({rr * std::cos(a), rr * std::sin(a), z}));
    } else {
      out.push_back({lo.x - reach + (hi.x - lo.x + 2 * reach) * U(rng),
                     lo.y - reach + (hi.y - lo.y + 2 * reach) * U(rng),
                     lo.z - reach + (hi.z - lo.z + 2 * reach) * U(rng)});
    }
  }
  return out;
}

}  // namespace loom
