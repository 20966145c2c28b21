// The fiber tier's fiber as a polyline (Luan, Zhao, Bala 2017, Eq. 1-4): the z grid every
// fiber of a ply is sampled on, its vertices in yarn space, the hairs' polylines, how far they
// reach, and what a look-up answers (fiber_lookup.h: both look-ups test these polylines).
#pragma once
#include <cmath>
#include <cstdint>

#include "loom/procedural_ply.h"

namespace loom {

/// The z step of every fiber polyline of a ply: a 32nd of the shortest of the fiber twist pitch
/// a, the migration period a / s and the ply twist pitch, at least 0.5 um (choice: the chord of a
/// 32nd of a turn stays within 0.5 % of the ply radius of the helix).
double fiber_step(const PlyParams& p);
/// Upper bound on the distance between a fiber's polyline and its analytic Eq. 1-4 centre in
/// yarn space: L dz / 2 for the centre's xy speed bound L (loops and hairs included).
double polyline_error(const PlyParams& p, double dz);
/// Largest migration radius of a regular fiber (or loop), in units of the ply radius: r_max of
/// Eq. 2, or the loops' mutated r_max when the ply has loops (section 4.4.1).
double migration_reach(const PlyParams& p);
/// Largest distance of any fiber centre of the yarn from its ply's centre (um).
double ply_reach(const PlyParams& p);
/// Largest distance of any covered point from the yarn centre: the yarn's pipe radius.
double yarn_reach(const PlyParams& p);

struct Vertex2f {
  float x = 0, y = 0;
};
/// Vertex k (z = k dz) of regular fiber `fiber` of ply `ply` of yarn `yarn`, in yarn space:
/// Eq. 1-2 with the loop mutation of section 4.4.1, placed at the ply centre.
Vertex2f regular_vertex(const PlyParams& p, uint32_t yarn, uint32_t ply, uint32_t fiber,
                        const Fiber& f, int64_t k, double dz);
/// The hair's vertex at z (Eq. 4 at the ply centre), in yarn space.
Vertex2f hair_vertex(const PlyParams& p, uint32_t ply, const Hair& h, double z);
/// The hair polyline's segment that holds z in [z1, z2]: its ends za, zb and its index m
/// (vertex 0 at z1, then the multiples of dz inside (z1, z2), then z2).
struct HairSegment {
  double za = 0, zb = 0;
  int64_t m = 0;
};
HairSegment hair_segment(const Hair& h, double dz, double z);
/// Vertex count of a hair polyline.
int64_t hair_vertex_count(const Hair& h, double dz);
/// z of vertex m of a hair polyline.
double hair_vertex_z(const Hair& h, double dz, int64_t m);

struct FiberHit {
  bool covered = false;
  uint32_t yarn = 0, ply = 0;
  uint64_t fiber = 0;  ///< regular fiber index, or the hair's index (its tree id, realization-free)
  bool hair = false;
  double distance = 0;  ///< cross-sectional distance to the fiber centre, um
  Vec3d direction;      ///< unit fiber tangent in fabric space
  bool same_fiber(const FiberHit& o) const {
    return covered == o.covered &&
           (!covered || (yarn == o.yarn && ply == o.ply && fiber == o.fiber && hair == o.hair));
  }
};

/// The k with k dz <= z < (k + 1) dz, computed with the same products the vertices use.
inline int64_t grid_index(double z, double dz) {
  int64_t k = int64_t(std::floor(z / dz));
  if (double(k) * dz > z) --k;
  if (double(k + 1) * dz <= z) ++k;
  return k;
}

}  // namespace loom
