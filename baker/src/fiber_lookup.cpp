#include "loom/fiber_lookup.h"

#include "loom/hair_flyaways.h"

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

namespace loom {

// ---- The fiber polyline, shared by both look-ups ----

double fiber_step(const PlyParams& p) {
  double shortest = p.pitch;
  if (p.s > 0) shortest = std::min(shortest, p.pitch / p.s);
  if (p.plies > 1 && p.ply_centre_radius > 0 && p.ply_pitch > 0)
    shortest = std::min(shortest, p.ply_pitch);
  return std::max(shortest / 32, 0.5);
}

double migration_reach(const PlyParams& p) {
  return p.loop_density > 0 ? std::max(p.r_max, p.loop_r_max) : p.r_max;
}

namespace {
double reach_factor(const PlyParams& p) {
  double f = migration_reach(p);
  if (p.hair_density > 0) f = std::max(f, p.hair_r_max);
  return std::max(f, 1.0);  // hairs start anywhere up to R_ply
}
bool twisted_plies(const PlyParams& p) { return p.plies > 1 && p.ply_centre_radius > 0; }
}  // namespace

double polyline_error(const PlyParams& p, double dz) {
  const double rmax = migration_reach(p);
  double Lc = twisted_plies(p) && p.ply_pitch > 0 ? p.ply_centre_radius * 2 * M_PI / p.ply_pitch
                                                 : 0;
  // Eq. 1-2: |d/dz (R cos, R sin)| <= R 2 pi / a + |dR/dz|, |dR/dz| <= R_ply (rmax - rmin) / 2 *
  // 2 pi s / a.
  double Lreg = p.ply_radius * rmax * 2 * M_PI / p.pitch +
                p.ply_radius * std::max(rmax - p.r_min, 0.0) * 0.5 * 2 * M_PI * p.s / p.pitch;
  double Lhair = 0;
  if (p.hair_density > 0) {  // Eq. 4: R and theta linear over at least hair_length_min
    double len = std::max(p.hair_length_min, dz);
    Lhair = p.ply_radius * p.hair_r_max * (1 + p.hair_max_turn) / len;
  }
  // 1 % and 1e-3 um over the bound for the vertices' float rounding.
  return 0.5 * (Lc + std::max(Lreg, Lhair)) * dz * 1.01 + 1e-3;
}

double ply_reach(const PlyParams& p) { return p.ply_radius * reach_factor(p); }

double yarn_reach(const PlyParams& p) {
  return (twisted_plies(p) ? p.ply_centre_radius : 0) + ply_reach(p) + p.fiber_radius +
         polyline_error(p, fiber_step(p));
}

Vertex2f regular_vertex(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber,
                        const Fiber& f, int64_t k, double dz) {
  double z = double(k) * dz;
  double R = fiber_radius_with_loops(p, yarn, ply, fiber, f, z);
  double ang = f.theta + 2 * M_PI * z / p.pitch;  // Eq. 1
  Vec3d c = ply_centre(p, ply, z);
  return {float(c.x + R * std::cos(ang)), float(c.y + R * std::sin(ang))};
}

Vertex2f hair_vertex(const PlyParams& p, uint32_t ply, const Hair& h, double z) {
  Vec3d c = ply_centre(p, ply, z), q = hair_in_ply(h, z);
  return {float(c.x + q.x), float(c.y + q.y)};
}

namespace {
/// The k with k dz <= z < (k + 1) dz, computed with the same products the vertices use.
int64_t grid_index(double z, double dz) {
  int64_t k = int64_t(std::floor(z / dz));
  if (double(k) * dz > z) --k;
  if (double(k + 1) * dz <= z) ++k;
  return k;
}
/// Smallest k with k dz > z1.
int64_t first_inner(double z1, double dz) { return grid_index(z1, dz) + 1; }
/// Largest k with k dz < z2.
int64_t last_inner(double z2, double dz) {
  int64_t k = grid_index(z2, dz);
  if (double(k) * dz >= z2) --k;
  return k;
}
}  // namespace

HairSegment hair_segment(const Hair& h, double dz, double z) {
  HairSegment s;
  int64_t k = grid_index(z, dz), kf = first_inner(h.z1, dz);
  if (double(k) * dz >= h.z2 && k >= kf) --k;  // z == z2 on the grid: the last segment
  double lo = double(k) * dz, hi = double(k + 1) * dz;
  if (lo <= h.z1) {
    s.za = h.z1;
    s.m = 0;
  } else {
    s.za = lo;
    s.m = k - kf + 1;
  }
  s.zb = hi >= h.z2 ? h.z2 : hi;
  return s;
}

int64_t hair_vertex_count(const Hair& h, double dz) {
  return std::max<int64_t>(0, last_inner(h.z2, dz) - first_inner(h.z1, dz) + 1) + 2;
}

double hair_vertex_z(const Hair& h, double dz, int64_t m) {
  if (m <= 0) return h.z1;
  if (m >= hair_vertex_count(h, dz) - 1) return h.z2;
  return double(first_inner(h.z1, dz) + m - 1) * dz;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// Where a regular fiber's polyline is at z: segment k, parameter t.
void regular_segment(double z, double dz, int64_t& k, double& t) {
  k = grid_index(z, dz);
  t = (z - double(k) * dz) / dz;
}

/// The nearest covering fiber found so far, with what its direction needs.
struct Best {
  double d2 = kInf;
  uint32_t yarn = 0, ply = 0;
  uint64_t fiber = 0;
  bool hair = false;
  Vertex2f v0, v1;
  double seg_dz = 1, cx = 0, cy = 0;  ///< segment, and the fiber centre in yarn space
  YarnProjection proj;

  bool beaten_by(double d, uint32_t y, bool h, uint32_t pl, uint64_t f) const {
    if (d != d2) return d < d2;
    if (y != yarn) return y < yarn;
    if (h != hair) return !h;
    if (pl != ply) return pl < ply;
    return f < fiber;
  }
};

/// The final test of both look-ups: the polyline segment v0-v1 at parameter t against [x, y].
void consider(Best& best, double x, double y, double t, Vertex2f v0, Vertex2f v1, double seg_dz,
              double r2, uint32_t yarn, uint32_t ply, uint64_t fiber, bool hair,
              const YarnProjection& q) {
  double px = double(v0.x) + (double(v1.x) - double(v0.x)) * t;
  double py = double(v0.y) + (double(v1.y) - double(v0.y)) * t;
  double d2 = (x - px) * (x - px) + (y - py) * (y - py);
  if (d2 < r2 && best.beaten_by(d2, yarn, hair, ply, fiber)) {
    best.d2 = d2;
    best.yarn = yarn, best.ply = ply, best.fiber = fiber, best.hair = hair;
    best.v0 = v0, best.v1 = v1, best.seg_dz = seg_dz, best.proj = q;
    best.cx = px, best.cy = py;
  }
}

/// A hair's final test at z (z within [z1, z2]).
void consider_hair(Best& best, const PlyParams& P, uint32_t ply, const Hair& h, double dz,
                   const Vec3d& yp, double r2, uint32_t yarn, uint64_t id,
                   const YarnProjection& q) {
  const double z = yp.z;
  if (z < h.z1 || z > h.z2) return;
  HairSegment s = hair_segment(h, dz, z);
  double t = s.zb > s.za ? (z - s.za) / (s.zb - s.za) : 0;
  consider(best, yp.x, yp.y, t, hair_vertex(P, ply, h, s.za), hair_vertex(P, ply, h, s.zb),
           std::max(s.zb - s.za, 1e-9), r2, yarn, ply, id, true, q);
}

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

FiberHit finish(const Best& b, const std::vector<PatchYarn>& yarns) {
  FiberHit h;
  if (!(b.d2 < kInf)) return h;
  h.covered = true;
  h.yarn = b.yarn, h.ply = b.ply, h.fiber = b.fiber, h.hair = b.hair;
  h.distance = std::sqrt(b.d2);
  // Eq. 7's Jacobian along the fiber: d/dz [a(z) + x n(z) + y b(z)] with the rotation-minimising
  // frame's n' = -(t'.n) t, b' = -(t'.b) t: (1 - x t'.n - y t'.b) t + x' n + y' b.
  const YarnCurve& c = yarns[b.yarn].curve;
  YarnFrame f = c.frame(b.proj.piece, b.proj.u);
  Vec3d k = c.curvature(b.proj.piece, b.proj.u);
  double dx = (double(b.v1.x) - double(b.v0.x)) / b.seg_dz;
  double dy = (double(b.v1.y) - double(b.v0.y)) / b.seg_dz;
  double along = 1 - b.cx * dot(k, f.n) - b.cy * dot(k, f.b);
  h.direction = normalized(f.n * dx + f.b * dy + f.t * along);
  return h;
}

/// nanoflann's dataset adaptor over 3D points.
template <class T>
struct Cloud {
  std::vector<std::array<T, 3>> pts;
  size_t kdtree_get_point_count() const { return pts.size(); }
  T kdtree_get_pt(size_t i, size_t d) const { return pts[i][d]; }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
template <class T>
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<T, Cloud<T>>,
                                                   Cloud<T>, 3, uint32_t>;
#if NANOFLANN_VERSION >= 0x150
using SearchParams = nanoflann::SearchParameters;
#else
using SearchParams = nanoflann::SearchParams;
#endif

/// The indices of the points within a squared radius (the result-set interface of nanoflann
/// 1.4 and later alike).
template <class T>
struct WithinRadius {
  using DistanceType = T;
  using IndexType = uint32_t;
  T radius2;
  std::vector<uint32_t>& out;
  void init() { out.clear(); }
  void clear() { out.clear(); }
  size_t size() const { return out.size(); }
  bool empty() const { return out.empty(); }
  bool full() const { return true; }
  bool addPoint(T d2, uint32_t i) {
    if (d2 < radius2) out.push_back(i);
    return true;
  }
  T worstDist() const { return radius2; }
};

template <class T>
void points_within(const KdTree<T>& tree, const T* q, T radius, std::vector<uint32_t>& out) {
  WithinRadius<T> r{radius * radius, out};
  r.init();
  tree.findNeighbors(r, q, SearchParams());
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

namespace {
void require_patch_z(const std::vector<PatchYarn>& yarns) {
  for (const auto& y : yarns)
    if (y.curve.z_begin() != 0)
      throw std::invalid_argument("fiber look-ups: patch yarn curves must start at z = 0");
}
}  // namespace

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
  Cloud<float> mids;                 ///< segment midpoints in yarn space
  std::vector<uint32_t> seg_poly;    ///< polyline of each segment
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
        for (int64_t k = 0; k < K; ++k) Y.verts.push_back(regular_vertex(p, seed, ply, j, f, k, Y.dz));
        add_segments(pl, [&](uint32_t v) { return double(v) * Y.dz; });
      }
      std::vector<HairFlyaway> hairs;
      if (o.realization_free_hairs) {
        hairs = all_hairs_realization_free(p, seed, ply, L);
      } else {
        HairCount hc = ply_hair_count(p, seed, ply, L);
        for (uint32_t j = 0; j < hc.count; ++j) hairs.push_back({j, make_hair(p, seed, ply, L, hc, j)});
      }
      for (const auto& hf : hairs) {
        const Hair& h = hf.hair;
        int64_t n = hair_vertex_count(h, Y.dz);
        Polyline pl{uint32_t(Y.verts.size()), uint32_t(n), ply, hf.id, true, h.z1, h.z2};
        for (int64_t m = 0; m < n; ++m) Y.verts.push_back(hair_vertex(p, ply, h, hair_vertex_z(h, Y.dz, m)));
        add_segments(pl, [&](uint32_t v) { return hair_vertex_z(h, Y.dz, v); });
      }
    }
    // A covered point is within r of a point of a segment, so within r + half its length of
    // the segment's midpoint; plus float rounding of the midpoints.
    Y.search = (p.fiber_radius + half) * (1 + 1e-5) + 1e-2;
    Y.verts.shrink_to_fit(), Y.polys.shrink_to_fit(), Y.mids.pts.shrink_to_fit();
    Y.seg_poly.shrink_to_fit();
    Y.tree = std::make_unique<KdTree<float>>(3, Y.mids, nanoflann::KDTreeSingleIndexAdaptorParams(16));
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
        consider(best, yp.x, yp.y, t, Y.verts[pl.first + size_t(k)], Y.verts[pl.first + size_t(k) + 1],
                 Y.dz, Y.r2, yi, pl.ply, pl.fiber, false, proj);
      } else {
        if (z < pl.z1 || z > pl.z2) continue;
        Hair h;
        h.z1 = pl.z1, h.z2 = pl.z2;
        HairSegment s = hair_segment(h, Y.dz, z);
        if (s.m < 0 || s.m + 1 >= int64_t(pl.count)) continue;
        double ht = s.zb > s.za ? (z - s.za) / (s.zb - s.za) : 0;
        consider(best, yp.x, yp.y, ht, Y.verts[pl.first + size_t(s.m)],
                 Y.verts[pl.first + size_t(s.m) + 1], std::max(s.zb - s.za, 1e-9), Y.r2, yi,
                 pl.ply, pl.fiber, true, proj);
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
                 regular_vertex(P, y.seed_index, ply, j, f, k + 1, dz), dz, r2, yi, ply, j,
                 false, proj);
      }
      if (o.realization_free_hairs) {
        for (const auto& hf : all_hairs_realization_free(P, y.seed_index, ply, L))
          consider_hair(best, P, ply, hf.hair, dz, yp, r2, yi, hf.id, proj);
      } else {
        HairCount hc = ply_hair_count(P, y.seed_index, ply, L);
        for (uint32_t j = 0; j < hc.count; ++j)
          consider_hair(best, P, ply, make_hair(P, y.seed_index, ply, L, hc, j), dz, yp, r2, yi,
                        j, proj);
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
