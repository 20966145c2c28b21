// A woven patch of yarn centre curves: the input of the fiber tier's look-ups (Luan et al. 2017,
// section 4.1: "a set of n yarn curves and per-yarn parameters for the procedural fiber
// geometry").
//
// Choices where the text is silent (it takes curves from simulation or from artists): warp yarns
// run along x, stacked along y at the spec's warp spacing; weft yarns run along y at the weft
// spacing; each yarn passes through one vertex per crossing, at height +h where it lies on top
// and -h where it lies below (the weave matrix), h = (warp diameter + weft diameter) / 8: half
// of what round yarns that just touch would need, as woven yarns flatten at crossings (an
// elliptic section of aspect about 2), and it keeps the bends' radius of curvature near the
// yarn radius at the usual thread counts (sinusoid: spacing^2 / (pi^2 h)); the curve starts and ends half a spacing beyond the patch.
#pragma once
#include <cstdint>
#include <vector>

#include "loom/procedural_ply.h"
#include "loom/spec.h"
#include "loom/weave.h"
#include "loom/yarn_curve.h"

namespace loom {

struct PatchYarn {
  YarnCurve curve;
  PlyParams ply;   ///< Eq. 1-4 parameters of this yarn's plies and fibers
  bool warp = true;
  uint32_t seed_index = 0;  ///< the yarn index of section 5.3's consistent seeding
};

/// The spacing (um) between neighbouring yarns of the woven fabric: the weft's along x (the warp
/// yarns' vertex step), the warp's along y.
struct WovenSpacing {
  double x = 0, y = 0;
};
WovenSpacing woven_spacing(const FabricSpec& s);

/// Vertex m (um) of warp row / weft column `index` of the unbounded fabric woven by `w` (the
/// spec's weave) at the spec's spacings, with the crossing height h of the choices above: the
/// one statement of the woven geometry, for patches and for regions (fiber_region.h) alike.
Vec3d woven_vertex(const FabricSpec& s, const Weave& w, bool warp, int64_t index, int64_t m);

/// The largest patch make_woven_patch builds (yarns in both directions together).
inline constexpr int kMaxPatchYarns = 20000;

/// A patch of `yarns` yarns (warp ceil(yarns / 2), weft the rest), at least 2 and at most
/// kMaxPatchYarns; throws std::invalid_argument naming the range otherwise.
std::vector<PatchYarn> make_woven_patch(const FabricSpec& s, int yarns);

}  // namespace loom
