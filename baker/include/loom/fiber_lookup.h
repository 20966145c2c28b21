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

#include "loom/fiber_polyline.h"
#include "loom/woven_patch.h"

namespace loom {

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
