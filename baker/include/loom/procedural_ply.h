// Procedural plies and fibers (Luan, Zhao, Bala 2017, section 3.2 and 4.5; after Zhao et al.
// 2016): the regular fibers of a ply as helices (Eq. 1) whose radius migrates (Eq. 2), with
// radii drawn from the cross-sectional density (Eq. 3) by rejection sampling; multi-ply yarns
// twist their plies about the yarn centre. One implementation, for the ray-wave simulation and
// the fiber tier alike.
//
// Consistent seeding (section 5.3): every random number of a fiber is a pure function of
// (yarn, ply, fiber, k), so a fiber is the same whether it is generated alone or with all others,
// in any order, on any thread. Choice where the text differs: the paper indexes a van der Corput
// sequence in blocks of N per fiber; strided radical inverses share their low digits (every
// first sample of a block of 64 is >= 0.5 in base 2), which breaks rejection sampling (tested:
// a Kolmogorov-Smirnov distance of 0.41 against Eq. 3). Loom uses a counter-based generator
// instead: SplitMix64 of the key, the same consistency without the correlation.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "loom/spec.h"

namespace loom {

/// Parameters of Eq. 1-3 for the fibers of one ply, and of the ply twist (lengths in um).
struct PlyParams {
  double ply_radius = 85;       ///< R_ply: fibers are at R * R_ply, R in [0, 1]
  double fiber_radius = 7.5;
  double pitch = 2000;          ///< a of Eq. 1 (fiber twist pitch)
  double r_min = 0.1, r_max = 1.0;  ///< Eq. 2 migration range
  double s = 2.0;               ///< Eq. 2: migration cycles per twist cycle
  double epsilon = 0.1, beta = 0.5;  ///< Eq. 3 density
  int fibers = 40;
  // Flyaways (section 3.2, after Zhao et al. 2016). Choices where the text is silent: hair fibers
  // start inside the ply (R in [r_min, 1]) and end outside it (R in [1, hair_r_max]), turn by at
  // most hair_max_turn radians, and are hair_length_min..max long; loops scale a whole migration
  // cycle's radius to loop_r_max.
  double loop_density = 0.0;   ///< loops per um of ply length (rho_loop)
  double loop_r_max = 1.6;     ///< R_max^loop, in units of R_ply
  double hair_density = 0.0;   ///< hair fibers per um of ply length (rho_hair)
  double hair_r_max = 2.0;     ///< outer end of a hair, in units of R_ply
  double hair_length_min = 200, hair_length_max = 1500;  ///< um along z
  double hair_max_turn = 0.5;  ///< radians
  // The ply about the yarn centre (section 4.5).
  int plies = 2;
  double ply_centre_radius = 65;  ///< distance of the ply centres from the yarn centre
  double ply_pitch = 1000;        ///< z length of one ply revolution
  double twist_sign = 1;          ///< +1 Z twist, -1 S twist (direction of the revolution)
};

/// Parameters of a yarn spec: R_ply from the ply diameter, a from the fiber twist pitch, ply
/// centre radius = yarn radius - ply radius, ply pitch from the ply twist angle
/// (tan alpha = 2 pi R_c / pitch), fibers from fibers_per_ply, Eq. 2-3 and flyaway densities from
/// the yarn's migration_*, density_* and *_flyaways_per_mm fields.
PlyParams ply_params_from_yarn(const YarnSpec& y);

/// Eq. 3, unnormalised: p(R) = (1 - 2 eps) ((e - e^R) / (e - 1))^beta + eps, R in [0, 1].
double fiber_radius_density(double R, double epsilon, double beta);

/// The consistently seeded uniform number k in [0, 1) of fiber (yarn, ply, fiber).
double fiber_random(uint32_t yarn, uint32_t ply, uint32_t fiber, uint32_t k);

/// One regular fiber: R_j (normalised), theta_j, theta_j^(0).
struct Fiber {
  double R = 0, theta = 0, theta0 = 0;
};

inline constexpr uint32_t kRejectionTries = 64;

/// The fiber `fiber` of ply `ply` of yarn `yarn`, consistently seeded.
Fiber make_fiber(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber);
/// All fibers of one ply.
std::vector<Fiber> make_ply_fibers(const PlyParams& p, uint32_t yarn, uint32_t ply);

struct Vec3d {
  double x = 0, y = 0, z = 0;
};
inline Vec3d operator+(Vec3d a, Vec3d b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3d operator-(Vec3d a, Vec3d b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3d operator*(Vec3d a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(Vec3d a, Vec3d b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d cross(Vec3d a, Vec3d b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
/// The unit vector along a, or +z for the zero vector.
inline Vec3d normalized(Vec3d a) {
  double l = std::sqrt(dot(a, a));
  return l > 0 ? a * (1 / l) : Vec3d{0, 0, 1};
}

/// Eq. 2: the migrating radius R_j(z) in um (scaled by the ply radius).
double fiber_radius_at(const PlyParams& p, const Fiber& f, double z);
/// Eq. 1 with Eq. 2: the fiber centre in ply space at height z.
Vec3d fiber_in_ply(const PlyParams& p, const Fiber& f, double z);
/// Centre of ply `ply` in yarn space at height z (plies evenly spaced, twisted about the axis).
Vec3d ply_centre(const PlyParams& p, uint32_t ply, double z);
/// The fiber centre in yarn space at height z (ply space placed at the ply centre).
Vec3d fiber_in_yarn(const PlyParams& p, uint32_t ply, const Fiber& f, double z);

// ---- Flyaways ----

/// Migration cycle of a fiber at height z: Eq. 2's cosine phase / 2 pi + 1/2, floored, so that a
/// cycle starts and ends at the migration minimum (choice: the text does not say where a cycle
/// starts; starting at the minimum keeps a mutated cycle's radius continuous).
int64_t migration_cycle(const PlyParams& p, const Fiber& f, double z);
/// Probability that one migration cycle is mutated into a loop: rho_loop / (fibers * cycles per
/// um), i.e. m_loop / (m k) of section 4.4.1 with m_loop = rho_loop h, k = s h / a cycles.
double loop_probability(const PlyParams& p);
/// Whether cycle `cycle` of fiber (yarn, ply, fiber) is a loop (consistently seeded).
bool is_loop_cycle(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber,
                   int64_t cycle);
/// Eq. 2 with loops: R_j(z) in um, r_max replaced by loop_r_max within a mutated cycle.
double fiber_radius_with_loops(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber,
                               const Fiber& f, double z);

/// A hair-type flyaway (Eq. 4): an arc from (z1, R1, theta1) to (z2, R2, theta2), R in um.
struct Hair {
  double z1 = 0, z2 = 0, R1 = 0, R2 = 0, theta1 = 0, theta2 = 0;
};
/// A Poisson count of the given mean from uniform numbers rnd() in [0, 1): by inversion, or the
/// normal approximation above a mean of 500.
template <class Rnd>
uint32_t poisson_count(double mean, Rnd&& rnd) {
  if (!(mean > 0)) return 0;
  if (mean > 500) {
    double u1 = std::max(rnd(), 1e-300), u2 = rnd();
    double n = mean + std::sqrt(mean) * std::sqrt(-2 * std::log(u1)) * std::cos(2 * M_PI * u2);
    return uint32_t(std::max(0.0, std::round(n)));
  }
  double L = std::exp(-mean), prod = rnd();
  uint32_t n = 0;
  while (prod > L) {
    ++n;
    prod *= rnd();
  }
  return n;
}

/// One hair of Eq. 4 from six uniform numbers rnd(): z1 uniform on [z_start, z_start + length),
/// its length uniform on [hair_length_min, hair_length_max], R1 in [r_min, 1] R_ply, R2 in
/// [1, hair_r_max] R_ply, theta1 uniform, theta2 within hair_max_turn of it.
template <class Rnd>
void draw_hair_shape(const PlyParams& p, Hair& h, Rnd&& rnd) {  ///< R1, R2, theta1, theta2
  h.R1 = p.ply_radius * (p.r_min + (1 - p.r_min) * rnd());
  h.R2 = p.ply_radius * (1 + (p.hair_r_max - 1) * rnd());
  h.theta1 = 2 * M_PI * rnd();
  h.theta2 = h.theta1 + p.hair_max_turn * (2 * rnd() - 1);
}
template <class Rnd>
Hair draw_hair(const PlyParams& p, double z_start, double length, Rnd&& rnd) {
  Hair h;
  h.z1 = z_start + length * rnd();
  h.z2 = h.z1 + p.hair_length_min + (p.hair_length_max - p.hair_length_min) * rnd();
  draw_hair_shape(p, h, rnd);
  return h;
}

/// How many hairs ply `ply` of yarn `yarn` has over z in [0, length) (Poisson with mean
/// hair_density * length, consistently seeded), and where in the ply's random stream the hairs'
/// own numbers start (six per hair), so that one hair can be realized alone (section 4.4.2).
struct HairCount {
  uint32_t count = 0, stream_offset = 0;
};
HairCount ply_hair_count(const PlyParams& p, uint32_t yarn, uint32_t ply, double length);
/// Hair j < c.count of the ply, from its own six random numbers.
Hair make_hair(const PlyParams& p, uint32_t yarn, uint32_t ply, double length,
               const HairCount& c, uint32_t j);
/// All hairs of the ply: make_hair for j < ply_hair_count(...).count.
std::vector<Hair> make_ply_hairs(const PlyParams& p, uint32_t yarn, uint32_t ply,
                                 double length);
/// Eq. 4: the hair's centre in ply space at z in [z1, z2] (R and theta interpolated linearly).
Vec3d hair_in_ply(const Hair& h, double z);

}  // namespace loom
