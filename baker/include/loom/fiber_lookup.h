// Fiber look-ups of the fiber tier (Luan, Zhao, Bala 2017, sections 4 and 5): the fiber, if any,
// that covers a fabric-space point, and its direction, both
// - realization-minimising (FiberLookup): yarns found by a point Kd-tree over the yarn curves'
//   vertices with the conservative radius R_yarn + delta of section 5.2; the point taken into
//   the yarn's space by projection on the yarn curve (Eq. 8-9), into the space of each ply that
//   can reach it (section 4.5); regular fibers pruned by their migration trajectories binned by
//   azimuth (Eq. 11-12, Algorithm 2) and realized on the fly, loops included (section 4.4.1);
//   hair flyaways by the hybrid z-binning of section 4.4.2 (their z extents pre-generated, the
//   rest realized on demand);
// - fully realized (RealizedFibers): every fiber's polyline generated and stored, found through
//   a Kd-tree over its segments.
// Both answer the same question with the same code for the final test, so they must agree at
// every point; the tests and `loom-bake eval fibers` check that they do.
//
// What "covered" means (choices where the text is silent):
// - a fiber is the polyline through its Eq. 1-4 centre at z = k dz (dz = fiber_step), the curve a
//   renderer is given, so what is looked up is what is drawn; between vertices it is linear in z;
// - a point [x, y, z] in yarn space is covered by a fiber when its distance to the fiber's centre
//   in the cross-section at z is below the fiber radius (the test of Figure 6); a hair covers
//   only z within its own [z1, z2];
// - where fibers overlap, the nearest centre wins (ties: lower yarn, regular before hair, lower
//   ply, lower fiber index);
// - a point is in a yarn only between the yarn curve's two ends (the projection is interior).
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "loom/procedural_ply.h"
#include "loom/woven_patch.h"

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

struct FiberLookupOptions {
  int azimuth_bins = 64;      ///< bins B_k of Algorithm 2
  double margin_scale = 1.0;  ///< < 1 makes pruning unsafe: only for showing the check can fail
  /// Hairs by Algorithm 3 (hair_flyaways.h: nothing stored, slower) instead of the hybrid
  /// z-binning. The two are different samples of the same hair process.
  bool realization_free_hairs = false;
};

/// Section 4.2 and 5.2: the yarns whose pipe may hold a point, by a point Kd-tree over all yarn
/// vertices searched with radius max_i (R_i + delta_i).
class YarnIndex {
 public:
  explicit YarnIndex(const std::vector<PatchYarn>& yarns);  ///< keeps a reference to yarns
  explicit YarnIndex(std::vector<PatchYarn>&&) = delete;
  ~YarnIndex();
  YarnIndex(YarnIndex&&) noexcept;
  /// For each yarn whose pipe holds p (interior projection within the yarn's reach), its
  /// projection; in increasing yarn order.
  std::vector<std::pair<uint32_t, YarnProjection>> yarns_at(Vec3d p) const;
  size_t bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Realization-minimising look-ups (Algorithm 1).
class FiberLookup {
 public:
  FiberLookup(const std::vector<PatchYarn>& yarns, FiberLookupOptions o = {});  ///< keeps a ref.
  FiberLookup(std::vector<PatchYarn>&&, FiberLookupOptions = {}) = delete;
  ~FiberLookup();
  FiberHit lookup(Vec3d p) const;
  size_t bytes() const;  ///< everything it stores, yarn curves and Kd-tree included
  /// Hairs of the patch (for checking flyaway counts against the spec's densities); with
  /// realization-free hairs, their Poisson counts (nothing else is stored).
  uint64_t hair_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Full realization: every fiber polyline stored, found by a Kd-tree over segment midpoints.
class RealizedFibers {
 public:
  /// Only `realization_free_hairs` of the options matters: which hair process is realized.
  explicit RealizedFibers(const std::vector<PatchYarn>& yarns, FiberLookupOptions o = {});
  RealizedFibers(std::vector<PatchYarn>&&, FiberLookupOptions = {}) = delete;
  ~RealizedFibers();
  FiberHit lookup(Vec3d p) const;
  size_t bytes() const;
  uint64_t vertex_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The definition itself, for tests: every yarn projected over all its pieces, every fiber and
/// hair of every ply realized at the point's z; no Kd-tree, no bins.
FiberHit brute_force_fiber_lookup(const std::vector<PatchYarn>& yarns, Vec3d p,
                                   FiberLookupOptions o = {});

/// K seeded points for comparing the two: half in random yarns' cross-sections (within their
/// reach, so many are covered), half uniform in the patch's bounding box.
std::vector<Vec3d> fiber_test_points(const std::vector<PatchYarn>& yarns, int count,
                                     uint64_t seed);

}  // namespace loom
