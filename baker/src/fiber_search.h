// Internal to the fiber look-ups (fiber_lookup.cpp, realized_fibers.cpp): the fiber
// polyline's grid, the nearest-fiber test both look-ups end with, and nanoflann's adaptors.
#ifndef LOOM_SRC_FIBER_SEARCH_H
#define LOOM_SRC_FIBER_SEARCH_H

#include "loom/fiber_polyline.h"
#include "loom/woven_patch.h"

#include <nanoflann.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace loom::fiber_search {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// Where a regular fiber's polyline is at z: segment k, parameter t.
inline void regular_segment(double z, double dz, int64_t& k, double& t) {
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
inline void consider(Best& best, double x, double y, double t, Vertex2f v0, Vertex2f v1,
                     double seg_dz, double r2, uint32_t yarn, uint32_t ply, uint64_t fiber,
                     bool hair, const YarnProjection& q) {
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
inline void consider_hair(Best& best, const PlyParams& P, uint32_t ply, const Hair& h, double dz,
                          const Vec3d& yp, double r2, uint32_t yarn, uint64_t id,
                          const YarnProjection& q) {
  const double z = yp.z;
  if (z < h.z1 || z > h.z2) return;
  HairSegment s = hair_segment(h, dz, z);
  double t = s.zb > s.za ? (z - s.za) / (s.zb - s.za) : 0;
  consider(best, yp.x, yp.y, t, hair_vertex(P, ply, h, s.za), hair_vertex(P, ply, h, s.zb),
           std::max(s.zb - s.za, 1e-9), r2, yarn, ply, id, true, q);
}

inline FiberHit finish(const Best& b, const std::vector<PatchYarn>& yarns) {
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
inline void points_within(const KdTree<T>& tree, const T* q, T radius, std::vector<uint32_t>& out) {
  WithinRadius<T> r{radius * radius, out};
  r.init();
  tree.findNeighbors(r, q, SearchParams());
}

inline void require_patch_z(const std::vector<PatchYarn>& yarns) {
  for (const auto& y : yarns)
    if (y.curve.z_begin() != 0)
      throw std::invalid_argument("fiber look-ups: patch yarn curves must start at z = 0");
}

}  // namespace loom::fiber_search

#endif  // LOOM_SRC_FIBER_SEARCH_H
