#include "loom/fiber_polyline.h"

#include <algorithm>

namespace loom {

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

}  // namespace loom
