// Yarn centre curves of the fiber tier (Luan, Zhao, Bala 2017, section 5.1 and 5.2): C^1 cubic
// Hermite splines through the yarn's vertices, rotation-minimising frames along them, the
// fabric-to-yarn transform of Eq. 8-9 and the conservative vertex radius delta of Figure 9.
//
// Choices where the text is silent:
// - tangents at the vertices are Catmull-Rom's (one-sided at the ends);
// - the yarn-space z of Eq. 7 is arc length along the curve (5-point Gauss-Legendre per piece);
// - the rotation-minimising frame is the double-reflection method of Wang et al. 2008 (the
//   paper's [WJZL08]) on 2 samples per piece (its error is fourth order in the step); between samples the frame is the earlier sample's
//   rotated by the minimal rotation onto the exact tangent, then about the tangent by the
//   share of the remaining twist, so the frame is continuous along the whole curve;
// - the projection of a point (the paper solves a quintic with SplineLibrary) is Newton's method
//   on the squared distance from the best of 9 samples per piece.
#pragma once
#include <vector>

#include "loom/procedural_ply.h"

namespace loom {

/// An orthonormal frame along a yarn: t the tangent, n and b = t x n the yarn-space x and y axes.
struct YarnFrame {
  Vec3d t, n, b;
};

/// The nearest point of a yarn curve to a point.
struct YarnProjection {
  int piece = -1;        ///< Hermite piece, -1 when none was examined
  double u = 0;          ///< parameter in the piece, [0, 1]
  double z = 0;          ///< arc length from the curve's start (yarn-space z)
  double distance = 1e300;
  bool interior = false;  ///< false when the nearest point is one of the curve's two ends
};

class YarnCurve {
 public:
  static constexpr int kFrameSamples = 2;  ///< rotation-minimising frame samples per piece

  /// A curve through `points` (at least 2, consecutive points distinct); `up` chooses the first
  /// frame's normal (projected off the first tangent; any vector not parallel to it).
  YarnCurve(std::vector<Vec3d> points, Vec3d up);

  int pieces() const { return int(points_.size()) - 1; }
  const std::vector<Vec3d>& points() const { return points_; }
  double length() const { return arc_.back() - arc_.front(); }
  double z_begin() const { return arc_.front(); }  ///< z of the first vertex (0 unless shifted)
  double z_end() const { return arc_.back(); }
  double z_at_vertex(int v) const { return arc_[size_t(v)]; }
  /// Shifts yarn-space z so that vertex v is at z (a region's piece of a longer yarn keeps the
  /// longer yarn's z, and so its fibers).
  void set_z_at_vertex(int v, double z);
  /// delta_i of section 5.2: every point of the curve lies within delta of one of its vertices.
  double delta() const { return delta_; }

  Vec3d position(int piece, double u) const;
  Vec3d derivative(int piece, double u) const;  ///< d position / d u
  Vec3d second_derivative(int piece, double u) const;
  /// dt/ds, the curvature vector (s arc length): what Eq. 7's Jacobian needs, since a
  /// rotation-minimising frame's n and b turn only towards t (n' = -(t'.n) t, b' = -(t'.b) t).
  Vec3d curvature(int piece, double u) const;
  double arc_length(int piece, double u) const;  ///< yarn-space z
  YarnFrame frame(int piece, double u) const;

  /// The nearest point of piece `piece` to p.
  YarnProjection project_piece(Vec3d p, int piece) const;

  /// Eq. 9: p in this yarn's space given its projection: [<p - a, n>, <p - a, b>, z].
  Vec3d to_yarn(Vec3d p, const YarnProjection& q) const;
  /// Eq. 7: a yarn-space point [x, y, z] (z the arc length) in fabric space.
  Vec3d to_fabric(Vec3d yarn_point) const;
  /// The piece and parameter at arc length z (clamped to the curve).
  void locate(double z, int& piece, double& u) const;

  size_t bytes() const;

 private:
  std::vector<Vec3d> points_, tangents_;
  std::vector<double> arc_;                   ///< arc length at each vertex
  std::vector<Vec3d> frame_t_, frame_n_;      ///< frames at pieces * kFrameSamples + 1 samples
  std::vector<double> twist_;                 ///< remaining twist from sample k to k + 1
  double delta_ = 0;
};

}  // namespace loom
