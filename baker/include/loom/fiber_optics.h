// The optics of one fiber, shared by the two ray simulations that trace fibers (the ply
// scattering of the ray-wave tier, ply_scattering.h, and the fiber-level ground truth,
// fiber_truth.h): a smooth dielectric cylinder of index eta, Fresnel's reflectance for
// unpolarised light, the exit from inside a locally straight fiber, and the counter-based random
// numbers that make a traced ray a pure function of its indices.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "loom/procedural_ply.h"

namespace loom {

/// Fresnel reflectance of unpolarised light at a smooth interface, cos_i > 0 on the incident
/// side, eta = n_transmitted / n_incident; 1 under total internal reflection. cos_t: the
/// refracted ray's cosine (0 under total internal reflection).
inline double fresnel_dielectric(double cos_i, double eta, double& cos_t) {
  const double sin2_t = (1 - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1) {
    cos_t = 0;
    return 1;
  }
  cos_t = std::sqrt(1 - sin2_t);
  const double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  const double rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  return 0.5 * (rs * rs + rp * rp);
}

/// Snell's law for unit d meeting a surface of unit normal n (facing d's origin, cos_i = -d.n >
/// 0) from index 1 into index eta, with cos_t from fresnel_dielectric.
inline Vec3d refracted(const Vec3d& d, const Vec3d& n, double cos_i, double cos_t, double eta) {
  return normalized(d * (1 / eta) + n * (cos_i / eta - cos_t));
}

/// Mirror direction of unit d about unit n.
inline Vec3d reflected(const Vec3d& d, const Vec3d& n) {
  return normalized(d - n * (2 * dot(d, n)));
}

/// Exit of a ray o + t d that is inside the infinite cylinder of radius r about the axis
/// through p0 along unit `axis` (a fiber taken as locally straight): t > 0 and the outward unit
/// normal there. False when d runs along the axis (the ray never meets the wall) or o is not
/// inside.
inline bool cylinder_exit(const Vec3d& p0, const Vec3d& axis, double r, const Vec3d& o,
                          const Vec3d& d, double& t, Vec3d& normal) {
  const Vec3d D = o - p0;
  const double da = dot(d, axis), Da = dot(D, axis);
  const Vec3d dp = d - axis * da, Dp = D - axis * Da;
  const double qa = dot(dp, dp);
  if (qa < 1e-18) return false;
  const double qb = 2 * dot(Dp, dp), qc = dot(Dp, Dp) - r * r;
  const double disc = std::max(qb * qb - 4 * qa * qc, 0.0);
  t = (-qb + std::sqrt(disc)) / (2 * qa);
  if (!(t > 0)) return false;
  normal = normalized(Dp + dp * t);
  return true;
}

/// Counter-based random numbers: SplitMix64 seeded by (seed, stream, index), so that a ray's
/// numbers do not depend on the order or the thread in which rays are traced.
struct RayRng {
  uint64_t state;
  RayRng(uint64_t seed, uint64_t stream, uint64_t index)
      : state(seed * 0x9E3779B97F4A7C15ull ^ (stream << 40) ^ (stream >> 24) ^
              index * 0xD1B54A32D192ED03ull) {}
  double next() {
    uint64_t x = (state += 0x9E3779B97F4A7C15ull);
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    x ^= x >> 31;
    return double(x >> 11) * (1.0 / 9007199254740992.0);
  }
};

}  // namespace loom
