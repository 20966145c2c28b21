#include "loom/procedural_ply.h"

#include <algorithm>
#include <cmath>

namespace loom {

PlyParams ply_params_from_yarn(const YarnSpec& y) {
  PlyParams p;
  p.plies = y.plies;
  p.fibers = y.fibers_per_ply;
  p.ply_radius = 0.5 * y.ply_diameter_um;
  p.fiber_radius = 0.5 * y.fiber_diameter_um;
  p.pitch = y.fiber_twist_pitch_um;
  p.ply_centre_radius = y.plies > 1 ? std::max(0.0, 0.5 * y.yarn_diameter_um - p.ply_radius) : 0;
  double ta = std::tan(y.ply_twist_deg * M_PI / 180.0);
  // tan(alpha) = 2 pi R_c / pitch; an untwisted or single-ply yarn has no ply revolution.
  p.ply_pitch = (ta > 1e-9 && p.ply_centre_radius > 0) ? 2 * M_PI * p.ply_centre_radius / ta : 0;
  p.twist_sign = y.twist == "Z" ? 1.0 : -1.0;
  p.r_min = y.migration_min;
  p.r_max = y.migration_max;
  p.s = y.migration_period;
  p.epsilon = y.density_epsilon;
  p.beta = y.density_beta;
  p.loop_density = y.loop_flyaways_per_mm * 1e-3;  // per um
  p.hair_density = y.hair_flyaways_per_mm * 1e-3;
  return p;
}

double fiber_radius_density(double R, double epsilon, double beta) {
  const double e = M_E;
  double base = std::max(0.0, (e - std::exp(R)) / (e - 1));
  return (1 - 2 * epsilon) * std::pow(base, beta) + epsilon;
}

double fiber_random(uint32_t yarn, uint32_t ply, uint32_t fiber, uint32_t k) {
  // SplitMix64 (Steele et al. 2014) of the packed key.
  uint64_t x = (uint64_t(yarn) << 40) ^ (uint64_t(ply) << 32) ^ (uint64_t(fiber) << 12) ^ k;
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  x ^= x >> 31;
  return double(x >> 11) * (1.0 / 9007199254740992.0);  // 53 bits
}

Fiber make_fiber(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber) {
  Fiber f;
  f.theta = 2 * M_PI * fiber_random(yarn, ply, fiber, 0);
  f.theta0 = 2 * M_PI * fiber_random(yarn, ply, fiber, 1);
  // Eq. 3 by rejection: R uniform in [0, 1], accepted with probability p(R) / max p, where
  // max p = p(0) (p decreases in R for beta > 0).
  const double pmax = std::max(fiber_radius_density(0, p.epsilon, p.beta), p.epsilon);
  for (uint32_t k = 0; k < kRejectionTries; ++k) {
    double R = fiber_random(yarn, ply, fiber, 2 + 2 * k);
    double u = fiber_random(yarn, ply, fiber, 3 + 2 * k);
    if (u * pmax <= fiber_radius_density(R, p.epsilon, p.beta)) {
      f.R = R;
      return f;
    }
  }
  // 64 rejections in a row has probability below (1 - eps / max p)^64 (< 1e-3 for eps = 0.1,
  // far less for the usual densities); keep the last candidate rather than loop forever.
  f.R = fiber_random(yarn, ply, fiber, 2 + 2 * (kRejectionTries - 1));
  return f;
}

std::vector<Fiber> make_ply_fibers(const PlyParams& p, uint32_t yarn, uint32_t ply) {
  std::vector<Fiber> out;
  out.reserve(size_t(p.fibers));
  for (int j = 0; j < p.fibers; ++j) out.push_back(make_fiber(p, yarn, ply, uint32_t(j)));
  return out;
}

double fiber_radius_at(const PlyParams& p, const Fiber& f, double z) {
  double c = std::cos(p.s * 2 * M_PI * z / p.pitch + f.theta0);
  return p.ply_radius * (p.r_min * f.R + 0.5 * (p.r_max - p.r_min) * f.R * (c + 1));  // Eq. 2
}

Vec3d fiber_in_ply(const PlyParams& p, const Fiber& f, double z) {
  double R = fiber_radius_at(p, f, z), ang = f.theta + 2 * M_PI * z / p.pitch;  // Eq. 1
  return {R * std::cos(ang), R * std::sin(ang), z};
}

Vec3d ply_centre(const PlyParams& p, uint32_t ply, double z) {
  if (p.plies <= 1 || p.ply_centre_radius <= 0) return {0, 0, z};
  double ang = 2 * M_PI * ply / p.plies;
  if (p.ply_pitch > 0) ang += p.twist_sign * 2 * M_PI * z / p.ply_pitch;
  return {p.ply_centre_radius * std::cos(ang), p.ply_centre_radius * std::sin(ang), z};
}

Vec3d fiber_in_yarn(const PlyParams& p, uint32_t ply, const Fiber& f, double z) {
  Vec3d c = ply_centre(p, ply, z), q = fiber_in_ply(p, f, z);
  return {c.x + q.x, c.y + q.y, z};
}

// ---- Flyaways ----

int64_t migration_cycle(const PlyParams& p, const Fiber& f, double z) {
  // Cycles run from one migration minimum (cos = -1) to the next, so a loop's radius leaves and
  // rejoins the regular fiber continuously at r_min R_j.
  double phase = p.s * z / p.pitch + f.theta0 / (2 * M_PI);
  return int64_t(std::floor(phase + 0.5));
}

double loop_probability(const PlyParams& p) {
  double cycles_per_um = p.s / p.pitch;
  return std::clamp(p.loop_density / (std::max(p.fibers, 1) * cycles_per_um), 0.0, 1.0);
}

bool is_loop_cycle(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber,
                   int64_t cycle) {
  // Random numbers 1000 + cycle (mod 2^31) of the fiber: independent of its Eq. 1-3 numbers.
  uint32_t k = 1000u + uint32_t(uint64_t(cycle) & 0x7fffffffu);
  return fiber_random(yarn, ply, fiber, k) < loop_probability(p);
}

double fiber_radius_with_loops(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber,
                               const Fiber& f, double z) {
  if (p.loop_density <= 0 || !is_loop_cycle(p, yarn, ply, fiber, migration_cycle(p, f, z)))
    return fiber_radius_at(p, f, z);
  PlyParams q = p;
  q.r_max = p.loop_r_max;
  return fiber_radius_at(q, f, z);
}

namespace {
// Hairs draw from the ply's own stream: fiber index kHairStream, numbers 0, 1, 2, ...
constexpr uint32_t kHairStream = 0xFFFFF;  // beyond any regular fiber index
}  // namespace

HairCount ply_hair_count(const PlyParams& p, uint32_t yarn, uint32_t ply, double length) {
  HairCount c;
  if (p.hair_density <= 0 || length <= 0) return c;
  uint32_t k = 0;
  c.count = poisson_count(p.hair_density * length,
                          [&] { return fiber_random(yarn, ply, kHairStream, k++); });
  c.stream_offset = k;
  return c;
}

Hair make_hair(const PlyParams& p, uint32_t yarn, uint32_t ply, double length,
               const HairCount& c, uint32_t j) {
  uint32_t k = c.stream_offset + 6 * j;
  return draw_hair(p, 0.0, length, [&] { return fiber_random(yarn, ply, kHairStream, k++); });
}

std::vector<Hair> make_ply_hairs(const PlyParams& p, uint32_t yarn, uint32_t ply, double length) {
  std::vector<Hair> out;
  HairCount c = ply_hair_count(p, yarn, ply, length);
  out.reserve(c.count);
  for (uint32_t j = 0; j < c.count; ++j) out.push_back(make_hair(p, yarn, ply, length, c, j));
  return out;
}

Vec3d hair_in_ply(const Hair& h, double z) {
  double t = h.z2 > h.z1 ? std::clamp((z - h.z1) / (h.z2 - h.z1), 0.0, 1.0) : 0.0;
  double R = h.R1 + (h.R2 - h.R1) * t, th = h.theta1 + (h.theta2 - h.theta1) * t;  // Eq. 4
  return {R * std::cos(th), R * std::sin(th), z};
}

}  // namespace loom
