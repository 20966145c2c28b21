// The fibers of one region of a fabric, realized for a renderer: what the fiber tier hands to
// Blender for the part of the cloth the camera resolves (Luan et al. 2017 realize nothing; a
// curve renderer needs curves, so only the region seen is realized).
//
// The fabric is unbounded and every yarn keeps its fibers wherever a region is cut from it:
// - warp yarn r runs along x at y = (r + 1/2) / warp density, weft c along y at x = (c + 1/2) /
//   weft density, through one vertex per crossing (woven_patch.h's geometry), seeded by its global
//   index (section 5.3), so two overlapping regions give the same fibers where they overlap;
// - a yarn's z (arc length) is measured from a fixed origin kRegionOrigin weave periods before its
//   vertex at x = 0 (or y = 0), from the period's piece lengths, so its fibers' phases do not
//   depend on where a region starts;
// - hairs are a Poisson process along each ply in blocks of kHairBlockUm, each block drawn from
//   its own generator keyed by (yarn, ply, block), so the hairs too are the region's share of one
//   process over the whole yarn. (Not the same samples as FiberLookup's patch hairs.)
// Each fiber is the polyline through its Eq. 1-4 centre every fiber_step (fiber_lookup.h), and at
// most every 16th of the crossing spacing so that its straight segments follow the yarn's bends,
// mapped into the fabric by the yarn's frame (Eq. 7).
#pragma once
#include <cstdint>
#include <filesystem>
#include <vector>

#include "loom/spec.h"

namespace loom {

/// A rectangle of the fabric plane in um: x along the warp, y along the weft.
struct FiberRegion {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

/// Weave periods before the origin; regions must lie within kRegionOrigin - 8 yarn spacings of
/// x = y = 0.
inline constexpr int64_t kRegionOrigin = 1 << 16;
inline constexpr double kHairBlockUm = 4000;
inline constexpr uint64_t kDefaultMaxFiberVertices = 20'000'000;

/// Realized curves, in fabric space (um; z up from the cloth's mid-plane).
struct FiberCurves {
  std::vector<float> points;      ///< x, y, z of every vertex
  std::vector<uint32_t> first;    ///< first vertex of each curve; one more entry: vertex count
  std::vector<float> radius;      ///< per curve, um
  std::vector<uint8_t> hair;      ///< per curve: 1 for a hair flyaway
  std::vector<uint32_t> yarn;     ///< per curve: the yarn's seed index (warp even, weft odd)
  std::vector<uint16_t> ply;      ///< per curve
  std::vector<uint64_t> fiber;    ///< per curve: regular index, or block << 32 | hair index
  std::vector<int64_t> first_k;   ///< per curve: grid index of its first vertex (regular only)
  uint32_t yarns = 0;
  size_t curves() const { return radius.size(); }
  size_t vertices() const { return points.size() / 3; }
  size_t bytes() const;
};

/// The vertices realize_fiber_region would write, counted without realizing them.
uint64_t estimate_region_vertices(const FabricSpec& s, const FiberRegion& r);

/// The fibers of every yarn that can reach into the region. Throws std::invalid_argument naming
/// the field and its range for an empty, non-finite or too distant region, and when the estimate
/// exceeds max_vertices (saying how many it would need).
FiberCurves realize_fiber_region(const FabricSpec& s, const FiberRegion& r,
                                 uint64_t max_vertices = kDefaultMaxFiberVertices);

/// Writes dir/manifest.json (schema loom.fibers/1: region, counts, file layout) beside
/// points.f32, first.u32, radius.f32, hair.u8 and warp.u8 (1 for a warp yarn's curve), all
/// little-endian, into a temporary directory renamed into place: dir holds a complete set or
/// nothing new.
void write_fiber_curves(const FiberCurves& c, const FabricSpec& s, const FiberRegion& r,
                        const std::filesystem::path& dir);

}  // namespace loom
