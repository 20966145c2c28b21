#include "loom/fiber_lookup.h"

#include "fiber_search.h"
#include "loom/hair_flyaways.h"

#include <algorithm>
#include <cmath>
#include <memory>

namespace loom {

using namespace fiber_search;

namespace {
/// Whether a hair can be within m of [x, y] at z in its ply's space (radius r, azimuth th):
/// Eq. 4's R(z) and theta(z) are linear, so by the triangle inequality the point's radius must be
/// within m of R(z), and its azimuth within asin(m / r) of theta(z). Conservative: m holds the
/// polyline error.
bool hair_may_cover(const Hair& h, double z, double r, double th, double m) {
  if (z < h.z1 || z > h.z2) return false;
  double t = h.z2 > h.z1 ? (z - h.z1) / (h.z2 - h.z1) : 0;
  double R = h.R1 + (h.R2 - h.R1) * t;
  if (std::abs(r - R) > m) return false;
  if (r <= m) return true;
  double a = h.theta1 + (h.theta2 - h.theta1) * t;
  double d = std::remainder(th - a, 2 * M_PI);
  return std::abs(d) <= std::asin(std::min(1.0, m / r)) + 1e-6;
}
}  // namespace

// ---- Yarn look-up (section 4.2, 5.2) ----

struct YarnIndex::Impl {
  const std::vector<PatchYarn>* yarns = nullptr;
  Cloud<double> cloud;
  std::vector<uint32_t> yarn_of, vertex_of;
  std::vector<double> reach;
  double radius = 0;
  std::unique_ptr<KdTree<double>> tree;
};

YarnIndex::YarnIndex(const std::vector<PatchYarn>& yarns) : impl_(std::make_unique<Impl>()) {
  impl_->yarns = &yarns;
  for (uint32_t i = 0; i < yarns.size(); ++i) {
    const auto& pts = yarns[i].curve.points();
    impl_->reach.push_back(yarn_reach(yarns[i].ply));
    impl_->radius = std::max(impl_->radius, impl_->reach.back() + yarns[i].curve.delta());
    for (uint32_t v = 0; v < pts.size(); ++v) {
      impl_->cloud.pts.push_back({pts[v].x, pts[v].y, pts[v].z});
      impl_->yarn_of.push_back(i);
      impl_->vertex_of.push_back(v);
    }
  }
  impl_->radius *= 1 + 1e-9;
  impl_->tree = std::make_unique<KdTree<double>>(3, impl_->cloud,
                                                 nanoflann::KDTreeSingleIndexAdaptorParams(16));
  impl_->tree->buildIndex();
}

YarnIndex::~YarnIndex() = default;
YarnIndex::YarnIndex(YarnIndex&&) noexcept = default;

std::vector<std::pair<uint32_t, YarnProjection>> YarnIndex::yarns_at(Vec3d p) const {
  std::vector<std::pair<uint32_t, YarnProjection>> out;
  if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))) return out;
  std::vector<uint32_t> hits;
  const double q[3] = {p.x, p.y, p.z};
  points_within(*impl_->tree, q, impl_->radius, hits);
  // Pieces next to each vertex found, per yarn.
  std::vector<std::pair<uint32_t, int>> pieces;
  for (uint32_t idx : hits) {
    uint32_t y = impl_->yarn_of[idx];
    int v = int(impl_->vertex_of[idx]), n = (*impl_->yarns)[y].curve.pieces();
    if (v - 1 >= 0) pieces.push_back({y, v - 1});
    if (v < n) pieces.push_back({y, v});
  }
  std::sort(pieces.begin(), pieces.end());
  pieces.erase(std::unique(pieces.begin(), pieces.end()), pieces.end());
  for (size_t a = 0; a < pieces.size();) {
    uint32_t y = pieces[a].first;
    YarnProjection best;
    for (; a < pieces.size() && pieces[a].first == y; ++a) {
      YarnProjection pr = (*impl_->yarns)[y].curve.project_piece(p, pieces[a].second);
      if (pr.distance < best.distance) best = pr;
    }
    if (best.interior && best.distance <= impl_->reach[y]) out.push_back({y, best});
  }
  return out;
}

size_t YarnIndex::bytes() const {
  size_t b = sizeof(Impl) + impl_->cloud.pts.capacity() * sizeof(std::array<double, 3>) +
             (impl_->yarn_of.capacity() + impl_->vertex_of.capacity()) * sizeof(uint32_t) +
             impl_->reach.capacity() * sizeof(double);
  b += impl_->tree->usedMemory(*impl_->tree);
  for (const auto& y : *impl_->yarns) b += y.curve.bytes();
  return b;
}

// ---- Realization-minimising look-ups (section 4.3, 4.4) ----

namespace {

/// Per yarn and ply: the regular fibers' trajectories T_j (Eq. 12) binned by azimuth, and the
/// hairs' z extents binned along z (the hybrid solution of section 4.4.2).
struct PlyIndex {
  std::vector<float> a, b, theta;  ///< T_j = {[R cos theta_j, R sin theta_j] | R in [a_j, b_j]}
  std::vector<uint16_t> central;   ///< fibers whose neighbourhood holds the ply centre: any bin
  std::vector<uint32_t> bin_start;
  std::vector<uint16_t> bin_fibers;
  HairCount hairs;
  std::vector<double> hair_edges;  ///< sorted z1 - r, z2 + r of every hair
  std::vector<uint32_t> hair_start, hair_list;

  size_t bytes() const {
    return sizeof(*this) + (a.capacity() + b.capacity() + theta.capacity()) * sizeof(float) +
           (central.capacity() + bin_fibers.capacity()) * sizeof(uint16_t) +
           (bin_start.capacity() + hair_start.capacity() + hair_list.capacity()) *
               sizeof(uint32_t) +
           hair_edges.capacity() * sizeof(double);
  }
};

struct YarnFibers {
  double dz = 1, r2 = 0, margin = 0, ply_select = 0, length = 0;
  std::vector<PlyIndex> plies;
};

double wrap_angle(double a) {  // to (-pi, pi]
  a = std::fmod(a, 2 * M_PI);
  if (a > M_PI) a -= 2 * M_PI;
  if (a <= -M_PI) a += 2 * M_PI;
  return a;
}

}  // namespace

struct FiberLookup::Impl {
  const std::vector<PatchYarn>* yarns = nullptr;
  FiberLookupOptions opt;
  YarnIndex index;
  std::vector<YarnFibers> fibers;
  explicit Impl(const std::vector<PatchYarn>& y) : yarns(&y), index(y) {}
};


FiberLookup::FiberLookup(const std::vector<PatchYarn>& yarns, FiberLookupOptions o)
    : impl_((require_patch_z(yarns), std::make_unique<Impl>(yarns))) {
  impl_->opt = o;
  const int B = std::max(1, o.azimuth_bins);
  impl_->opt.azimuth_bins = B;
  impl_->fibers.resize(yarns.size());
  for (size_t i = 0; i < yarns.size(); ++i) {
    const PlyParams& p = yarns[i].ply;
    const uint32_t seed = yarns[i].seed_index;
    YarnFibers& Y = impl_->fibers[i];
    Y.dz = fiber_step(p);
    Y.r2 = p.fiber_radius * p.fiber_radius;
    double e = polyline_error(p, Y.dz);
    Y.margin = (p.fiber_radius + e) * o.margin_scale;
    Y.ply_select = (ply_reach(p) + p.fiber_radius + e) * std::min(1.0, o.margin_scale) + 1e-3;
    Y.length = yarns[i].curve.length();
    const double rmax = migration_reach(p);
    Y.plies.resize(size_t(std::max(p.plies, 1)));
    for (uint32_t ply = 0; ply < Y.plies.size(); ++ply) {
      PlyIndex& P = Y.plies[ply];
      std::vector<std::vector<uint16_t>> bins(static_cast<size_t>(B));
      for (int j = 0; j < p.fibers; ++j) {
        Fiber f = make_fiber(p, seed, ply, uint32_t(j));
        double a = p.ply_radius * f.R * p.r_min, b = p.ply_radius * f.R * rmax;
        P.a.push_back(float(a));
        P.b.push_back(float(b));
        P.theta.push_back(float(f.theta));
        // Footnote 2: a bin lists every fiber whose trajectory comes within the margin of it.
        double m = Y.margin + 1e-3;
        if (a <= m || std::asin(std::min(1.0, m / a)) >= M_PI / 2) {
          P.central.push_back(uint16_t(j));
          continue;
        }
        double w = std::asin(m / a) + 1e-6;
        int k0 = int(std::floor((f.theta - w) / (2 * M_PI) * B));
        int k1 = int(std::floor((f.theta + w) / (2 * M_PI) * B));
        for (int k = k0; k <= k1 && k < k0 + B; ++k) bins[size_t(((k % B) + B) % B)].push_back(uint16_t(j));
      }
      P.bin_start.push_back(0);
      for (auto& bl : bins) {
        P.bin_fibers.insert(P.bin_fibers.end(), bl.begin(), bl.end());
        P.bin_start.push_back(uint32_t(P.bin_fibers.size()));
      }
      // Hairs: z extents pre-generated, bins between consecutive ends with their active hairs.
      P.hairs = ply_hair_count(p, seed, ply, Y.length);
      if (o.realization_free_hairs) continue;  // Algorithm 3 stores nothing
      std::vector<std::pair<double, double>> ext;
      for (uint32_t j = 0; j < P.hairs.count; ++j) {
        Hair h = make_hair(p, seed, ply, Y.length, P.hairs, j);
        ext.push_back({h.z1 - p.fiber_radius, h.z2 + p.fiber_radius});
        P.hair_edges.push_back(ext.back().first);
        P.hair_edges.push_back(ext.back().second);
      }
      std::sort(P.hair_edges.begin(), P.hair_edges.end());
      P.hair_edges.erase(std::unique(P.hair_edges.begin(), P.hair_edges.end()),
                         P.hair_edges.end());
      // Hair j is active in the bins from its lower end's edge to the one before its upper
      // end's (all ends are edges): counted, then filled, in time linear in the lists.
      const size_t nb = P.hair_edges.size() > 0 ? P.hair_edges.size() - 1 : 0;
      auto edge = [&](double end) {
        return size_t(std::lower_bound(P.hair_edges.begin(), P.hair_edges.end(), end) -
                      P.hair_edges.begin());
      };
      std::vector<std::pair<size_t, size_t>> span(ext.size());
      std::vector<uint32_t> count(nb + 1, 0);
      for (size_t j = 0; j < ext.size(); ++j) {
        span[j] = {edge(ext[j].first), edge(ext[j].second)};
        for (size_t b = span[j].first; b < span[j].second; ++b) ++count[b];
      }
      P.hair_start.assign(nb + 1, 0);
      for (size_t b = 0; b < nb; ++b) P.hair_start[b + 1] = P.hair_start[b] + count[b];
      P.hair_list.resize(P.hair_start[nb]);
      std::vector<uint32_t> fill(P.hair_start.begin(), P.hair_start.end() - 1);
      for (size_t j = 0; j < ext.size(); ++j)  // j ascending: each bin's list stays sorted
        for (size_t b = span[j].first; b < span[j].second; ++b) P.hair_list[fill[b]++] = uint32_t(j);
      if (nb == 0) P.hair_start.assign(1, 0);
      P.a.shrink_to_fit(), P.b.shrink_to_fit(), P.theta.shrink_to_fit();
      P.central.shrink_to_fit(), P.bin_fibers.shrink_to_fit(), P.hair_edges.shrink_to_fit();
      P.hair_list.shrink_to_fit(), P.hair_start.shrink_to_fit(), P.bin_start.shrink_to_fit();
    }
  }
}

FiberLookup::~FiberLookup() = default;

FiberHit FiberLookup::lookup(Vec3d p) const {
  Best best;
  const auto& yarns = *impl_->yarns;
  const int B = impl_->opt.azimuth_bins;
  for (const auto& found : impl_->index.yarns_at(p)) {
    // (Not a structured binding: the lambda below captures these, which clang 14 refuses.)
    const uint32_t yi = found.first;
    const YarnProjection& proj = found.second;
    const PatchYarn& yarn = yarns[yi];
    const PlyParams& P = yarn.ply;
    const YarnFibers& Y = impl_->fibers[yi];
    Vec3d yp = yarn.curve.to_yarn(p, proj);
    const double z = yp.z, m = Y.margin;
    for (uint32_t ply = 0; ply < Y.plies.size(); ++ply) {
      const PlyIndex& I = Y.plies[ply];
      Vec3d c = ply_centre(P, ply, z);
      double dx = yp.x - c.x, dy = yp.y - c.y;
      if (dx * dx + dy * dy > Y.ply_select * Y.ply_select) continue;  // section 4.5
      // Algorithm 2: [x', y'] = [x, y] M(z) in the ply's space, then its azimuth bin.
      double phi = 2 * M_PI * z / P.pitch, cs = std::cos(phi), sn = std::sin(phi);
      double xr = dx * cs + dy * sn, yr = -dx * sn + dy * cs;
      double r = std::sqrt(xr * xr + yr * yr), th = std::atan2(yr, xr);
      const double th_ply = std::atan2(dy, dx);  // hairs are not rotated by M(z)
      if (th < 0) th += 2 * M_PI;
      int bin = std::clamp(int(th / (2 * M_PI) * B), 0, B - 1);
      double wmax = r > m ? std::asin(m / r) + 1e-6 : kInf;
      int64_t k;
      double t;
      regular_segment(z, Y.dz, k, t);
      auto test = [&](uint16_t j) {
        if (r < double(I.a[j]) - m || r > double(I.b[j]) + m) return;
        if (wmax < kInf && std::abs(wrap_angle(th - double(I.theta[j]))) > wmax) return;
        Fiber f = make_fiber(P, yarn.seed_index, ply, j);  // realized on the fly
        Vertex2f v0 = regular_vertex(P, yarn.seed_index, ply, j, f, k, Y.dz);
        Vertex2f v1 = regular_vertex(P, yarn.seed_index, ply, j, f, k + 1, Y.dz);
        consider(best, yp.x, yp.y, t, v0, v1, Y.dz, Y.r2, yi, ply, j, false, proj);
      };
      for (uint16_t j : I.central) test(j);
      for (uint32_t q = I.bin_start[size_t(bin)]; q < I.bin_start[size_t(bin) + 1]; ++q)
        test(I.bin_fibers[q]);
      if (impl_->opt.realization_free_hairs) {  // Algorithm 3
        thread_local std::vector<HairFlyaway> active;
        active.clear();
        active_hairs(P, yarn.seed_index, ply, Y.length, z, P.fiber_radius, active);
        for (const auto& a : active)
          if (hair_may_cover(a.hair, z, r, th_ply, m))
            consider_hair(best, P, ply, a.hair, Y.dz, yp, Y.r2, yi, a.id, proj);
        continue;
      }
      // Hairs: the z bin by binary search, its active hairs realized on demand.
      if (I.hair_edges.size() >= 2 && z >= I.hair_edges.front() && z < I.hair_edges.back()) {
        size_t hb = size_t(std::upper_bound(I.hair_edges.begin(), I.hair_edges.end(), z) -
                           I.hair_edges.begin()) - 1;
        for (uint32_t q = I.hair_start[hb]; q < I.hair_start[hb + 1]; ++q) {
          uint32_t j = I.hair_list[q];
          Hair h = make_hair(P, yarn.seed_index, ply, Y.length, I.hairs, j);
          if (hair_may_cover(h, z, r, th_ply, m))
            consider_hair(best, P, ply, h, Y.dz, yp, Y.r2, yi, j, proj);
        }
      }
    }
  }
  return finish(best, yarns);
}

size_t FiberLookup::bytes() const {
  size_t b = sizeof(Impl) + impl_->index.bytes();
  for (const auto& Y : impl_->fibers) {
    b += sizeof(YarnFibers);
    for (const auto& P : Y.plies) b += P.bytes();
  }
  return b;
}

uint64_t FiberLookup::hair_count() const {
  uint64_t n = 0;
  for (const auto& Y : impl_->fibers)
    for (const auto& P : Y.plies) n += P.hairs.count;
  return n;
}

}  // namespace loom
