#include "loom/yarn_curve.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace loom {
namespace {

double norm(Vec3d a) { return std::sqrt(dot(a, a)); }

/// The minimal rotation taking unit a onto unit b, applied to v (Rodrigues with k = a x b).
Vec3d rotate_min(Vec3d v, Vec3d a, Vec3d b) {
  double c = dot(a, b);
  if (c < -1 + 1e-12) return v * -1.0;  // antiparallel: not met along a C^1 yarn
  Vec3d k = cross(a, b);
  Vec3d kv = cross(k, v);
  return v + kv + cross(k, kv) * (1 / (1 + c));
}

/// v rotated by angle about unit axis t (v orthogonal to t).
Vec3d rotate_about(Vec3d v, Vec3d t, double angle) {
  return v * std::cos(angle) + cross(t, v) * std::sin(angle);
}

// 5-point Gauss-Legendre on [0, 1].
constexpr double kGLx[5] = {0.04691007703066800, 0.23076534494715845, 0.5, 0.76923465505284155,
                            0.95308992296933200};
constexpr double kGLw[5] = {0.11846344252809454, 0.23931433524968324, 0.28444444444444444,
                            0.23931433524968324, 0.11846344252809454};

}  // namespace

YarnCurve::YarnCurve(std::vector<Vec3d> points, Vec3d up) : points_(std::move(points)) {
  const size_t n = points_.size();
  if (n < 2) throw std::invalid_argument("yarn curve: needs at least 2 points");
  for (size_t i = 0; i + 1 < n; ++i)
    if (norm(points_[i + 1] - points_[i]) <= 0)
      throw std::invalid_argument("yarn curve: two consecutive points coincide");
  tangents_.resize(n);
  for (size_t i = 0; i < n; ++i) {  // Catmull-Rom, one-sided at the ends
    size_t a = i == 0 ? 0 : i - 1, b = i + 1 == n ? n - 1 : i + 1;
    tangents_[i] = (points_[b] - points_[a]) * (1.0 / double(b - a));
  }
  arc_.assign(n, 0.0);
  for (int k = 0; k < pieces(); ++k) arc_[size_t(k) + 1] = arc_length(k, 1.0);  // uses arc_[k]

  // Section 5.2: split each piece at u = 1/2 (de Casteljau); the convex hull of each half's
  // Bezier points contains that half, and lies in the ball about the half's vertex whose radius
  // is the farthest Bezier point. delta is the largest such radius.
  for (int k = 0; k < pieces(); ++k) {
    Vec3d b0 = points_[size_t(k)], b3 = points_[size_t(k) + 1];
    Vec3d b1 = b0 + tangents_[size_t(k)] * (1.0 / 3), b2 = b3 - tangents_[size_t(k) + 1] * (1.0 / 3);
    Vec3d l1 = (b0 + b1) * 0.5, m12 = (b1 + b2) * 0.5, r2 = (b2 + b3) * 0.5;
    Vec3d l2 = (l1 + m12) * 0.5, r1 = (m12 + r2) * 0.5, mid = (l2 + r1) * 0.5;
    for (Vec3d q : {l1, l2, mid}) delta_ = std::max(delta_, norm(q - b0));
    for (Vec3d q : {mid, r1, r2}) delta_ = std::max(delta_, norm(q - b3));
  }

  // Double reflection (Wang et al. 2008) over the frame samples.
  const int S = kFrameSamples, m = pieces() * S + 1;
  frame_t_.resize(size_t(m));
  frame_n_.resize(size_t(m));
  std::vector<Vec3d> x(static_cast<size_t>(m));
  for (int s = 0; s < m; ++s) {
    int k = std::min(s / S, pieces() - 1);
    double u = double(s - k * S) / S;
    x[size_t(s)] = position(k, u);
    frame_t_[size_t(s)] = normalized(derivative(k, u));
  }
  Vec3d t0 = frame_t_[0], n0 = up - t0 * dot(up, t0);
  if (norm(n0) < 1e-9 * std::max(1.0, norm(up))) {  // up parallel to the tangent: any normal
    Vec3d e = std::abs(t0.x) < 0.9 ? Vec3d{1, 0, 0} : Vec3d{0, 1, 0};
    n0 = e - t0 * dot(e, t0);
  }
  frame_n_[0] = normalized(n0);
  twist_.assign(size_t(m), 0.0);
  for (int s = 0; s + 1 < m; ++s) {
    Vec3d v1 = x[size_t(s) + 1] - x[size_t(s)];
    double c1 = dot(v1, v1);
    Vec3d r = frame_n_[size_t(s)], t = frame_t_[size_t(s)];
    Vec3d rL = r - v1 * (2 / c1 * dot(v1, r)), tL = t - v1 * (2 / c1 * dot(v1, t));
    Vec3d v2 = frame_t_[size_t(s) + 1] - tL;
    double c2 = dot(v2, v2);
    Vec3d rn = c2 > 1e-24 ? rL - v2 * (2 / c2 * dot(v2, rL)) : rL;
    Vec3d tn = frame_t_[size_t(s) + 1];
    rn = normalized(rn - tn * dot(rn, tn));
    frame_n_[size_t(s) + 1] = rn;
    // Twist left between the minimal rotation of sample s and the reflected frame at s + 1.
    Vec3d rm = rotate_min(r, t, tn);
    twist_[size_t(s)] = std::atan2(dot(cross(rm, rn), tn), dot(rm, rn));
  }
}

Vec3d YarnCurve::position(int k, double u) const {
  double u2 = u * u, u3 = u2 * u;
  double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
  return points_[size_t(k)] * h00 + tangents_[size_t(k)] * h10 + points_[size_t(k) + 1] * h01 +
         tangents_[size_t(k) + 1] * h11;
}

Vec3d YarnCurve::derivative(int k, double u) const {
  double u2 = u * u;
  double d00 = 6 * u2 - 6 * u, d10 = 3 * u2 - 4 * u + 1, d01 = -6 * u2 + 6 * u, d11 = 3 * u2 - 2 * u;
  return points_[size_t(k)] * d00 + tangents_[size_t(k)] * d10 + points_[size_t(k) + 1] * d01 +
         tangents_[size_t(k) + 1] * d11;
}

Vec3d YarnCurve::second_derivative(int k, double u) const {
  double a = 12 * u - 6;
  return points_[size_t(k)] * a + tangents_[size_t(k)] * (6 * u - 4) +
         points_[size_t(k) + 1] * (-a) + tangents_[size_t(k) + 1] * (6 * u - 2);
}

Vec3d YarnCurve::curvature(int k, double u) const {
  Vec3d d1 = derivative(k, u), d2 = second_derivative(k, u);
  double l2 = dot(d1, d1);
  if (l2 <= 0) return {0, 0, 0};
  Vec3d t = d1 * (1 / std::sqrt(l2));
  return (d2 - t * dot(d2, t)) * (1 / l2);
}

double YarnCurve::arc_length(int k, double u) const {
  double s = 0;
  for (int i = 0; i < 5; ++i) s += kGLw[i] * norm(derivative(k, u * kGLx[i]));
  return arc_[size_t(k)] + u * s;
}

void YarnCurve::set_z_at_vertex(int v, double z) {
  double d = z - arc_[size_t(v)];
  for (double& a : arc_) a += d;
}

void YarnCurve::locate(double z, int& piece, double& u) const {
  z = std::clamp(z, arc_.front(), arc_.back());
  auto it = std::upper_bound(arc_.begin(), arc_.end(), z);
  piece = std::clamp(int(it - arc_.begin()) - 1, 0, pieces() - 1);
  // Newton on arc_length(piece, u) = z, started from the chord guess.
  double a = arc_[size_t(piece)], b = arc_[size_t(piece) + 1];
  u = b > a ? (z - a) / (b - a) : 0;
  for (int i = 0; i < 8; ++i) {
    double f = arc_length(piece, u) - z, d = norm(derivative(piece, u));
    if (d <= 0) break;
    u = std::clamp(u - f / d, 0.0, 1.0);
    if (std::abs(f) < 1e-9) break;
  }
}

YarnFrame YarnCurve::frame(int k, double u) const {
  const int S = kFrameSamples;
  double su = std::clamp(u, 0.0, 1.0) * S;
  int j = std::min(int(su), S - 1);
  double w = su - j;
  size_t s = size_t(k * S + j);
  Vec3d t = normalized(derivative(k, u));
  Vec3d n = rotate_min(frame_n_[s], frame_t_[s], t);
  n = rotate_about(n, t, w * twist_[s]);
  n = normalized(n - t * dot(n, t));
  return {t, n, cross(t, n)};
}

YarnProjection YarnCurve::project_piece(Vec3d p, int k) const {
  YarnProjection best;
  best.piece = k;
  double bu = 0, bd = 1e300;
  for (int i = 0; i <= 8; ++i) {
    double u = i / 8.0, d = dot(position(k, u) - p, position(k, u) - p);
    if (d < bd) bd = d, bu = u;
  }
  double u = bu;
  for (int it = 0; it < 12; ++it) {  // Newton on g(u) = |a(u) - p|^2
    Vec3d e = position(k, u) - p, d1 = derivative(k, u), d2 = second_derivative(k, u);
    double g1 = dot(e, d1), g2 = dot(d1, d1) + dot(e, d2);
    double step = g2 > 0 ? g1 / g2 : (g1 > 0 ? 0.05 : -0.05);
    double nu = std::clamp(u - step, 0.0, 1.0);
    if (std::abs(nu - u) < 1e-12) break;
    u = nu;
  }
  double d = norm(position(k, u) - p);
  if (d * d > bd) u = bu, d = std::sqrt(bd);
  best.u = u;
  best.distance = d;
  best.z = arc_length(k, u);
  best.interior = !((k == 0 && u <= 0) || (k == pieces() - 1 && u >= 1));
  return best;
}

Vec3d YarnCurve::to_yarn(Vec3d p, const YarnProjection& q) const {
  YarnFrame f = frame(q.piece, q.u);
  Vec3d e = p - position(q.piece, q.u);
  return {dot(e, f.n), dot(e, f.b), q.z};
}

Vec3d YarnCurve::to_fabric(Vec3d yp) const {
  int k;
  double u;
  locate(yp.z, k, u);
  YarnFrame f = frame(k, u);
  return position(k, u) + f.n * yp.x + f.b * yp.y;
}

size_t YarnCurve::bytes() const {
  return sizeof(*this) + (points_.capacity() + tangents_.capacity() + frame_t_.capacity() +
                          frame_n_.capacity()) * sizeof(Vec3d) +
         (arc_.capacity() + twist_.capacity()) * sizeof(double);
}

}  // namespace loom
