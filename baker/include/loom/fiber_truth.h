// Ground truth from the fibers (issue 35): light traced through the explicit procedural fibers
// of a patch of the fabric, as the fiber tier builds them (fiber_region.h: yarn curves, plies,
// fibers, flyaways), with the optics of the ray-wave simulation (fiber_optics.h: smooth
// dielectric cylinders of the yarn's IOR, absorption per unit path inside a fiber from the yarn
// colour, section 6 of the ray-wave supplement), tallied over the sphere of outgoing directions.
//
// Set-up (choices where the issue leaves them open, each stated once):
//  * The patch is a tile of whole weave repeats, at least `min_yarns` yarns across in each
//    direction (the fibers of different yarns differ, so a tile of one repeat would average
//    over too few), periodic: a ray that leaves the tile sideways re-enters on the far side.
//    The yarn curves are periodic over the tile; the fibers are not (each yarn has its own
//    seed), which a ray notices only where it crosses the seam inside a yarn.
//  * Intersections with Embree's round linear curves (one segment per pair of fiber vertices,
//    with the fiber's radius); inside a fiber the ray sees only that fiber's wall, taken as the
//    infinite cylinder of the segment it entered (as ply_scattering.h does), and a wall met from
//    inside another fiber (where fibers overlap) is passed through.
//  * Light arrives from `wi` (towards the light, in the cloth's frame: x along the warp, z the
//    cloth's normal) as a uniform irradiance over the tile; each interface picks reflection
//    with Fresnel's probability (Russian roulette), so every ray ends with its weight in one
//    outcome and a white yarn conserves energy exactly, up to `truncated`.
//  * reflect: the light that leaves on wi's side of the cloth; transmit: the other side,
//    including `direct`, the light that passes through the gaps without meeting a fiber (a
//    delta towards -wi, which the tally leaves out: it is no density).
//  * The tally is the fraction of the incident power per steradian towards each outgoing
//    direction wo: f(wi, wo) |cos theta_o|, which by reciprocity is also what Cycles' closure
//    eval returns for a view wi and a light wo. Bins: res x res over the sphere, rows uniform in
//    cos theta_o from -1 (row 0) to 1, columns uniform in phi_o = atan2(y, x) from -pi, so every
//    bin has the solid angle 4 pi / res^2.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "loom/fiber_region.h"
#include "loom/procedural_ply.h"
#include "loom/spec.h"

namespace loom {

/// One kind of fiber: index of refraction and absorption per um of path inside, per channel.
struct FiberMaterial {
  double ior = 1.55;
  std::array<double, 3> sigma_per_um{0, 0, 0};
};

struct TruthSettings {
  uint64_t rays = 200000;
  int res = 48;            ///< tally bins per side (res x res over the sphere)
  uint64_t seed = 1;
  int min_yarns = 8;       ///< yarns across the tile in each direction, at least
  int max_events = 1024;   ///< interactions before a path counts as truncated
};

struct TruthResult {
  /// Fractions of the incident power, per channel, and their standard errors (Monte Carlo).
  std::array<double, 3> reflect{}, transmit{}, absorbed{};
  std::array<double, 3> reflect_se{}, transmit_se{}, absorbed_se{};
  double direct = 0;     ///< transmitted without meeting a fiber (part of transmit)
  double truncated = 0;  ///< still inside after max_events interactions
  int res = 0;
  std::vector<float> density;  ///< res x res x RGB, row-major from row 0; scattered light only
  uint64_t rays = 0;
  size_t curves = 0, segments = 0;
  std::array<double, 4> tile_um{};  ///< x0, y0, x1, y1
  double z_lo_um = 0, z_hi_um = 0;
};

/// The materials a scene can have (warp and weft).
inline constexpr size_t kTruthMaterials = 2;

/// One traced path. The fibers' absorption does not change where a path goes (each interface
/// picks reflection with Fresnel's probability, which does not depend on it), only its weight,
/// exp(-sum_m sigma_m len_m) per channel: so one set of paths gives the truth for any absorption
/// (FiberTruthScene::tally), which is what solving for a colour needs.
struct TruthPath {
  std::array<float, kTruthMaterials> len_um{0, 0};  ///< path inside fibers of each material
  int32_t bin = -1;  ///< the tally bin it left into (row * res + col); -1 when truncated
  enum Exit : uint8_t { Up, Down, Truncated } exit = Up;  ///< left above (z > 0), below, or not
  bool touched = false;  ///< met a fiber (else it is the gaps' direct light)
};

/// The paths of one trace: from the light wi, or from diffuse light over wi's hemisphere
/// (cosine-weighted; then `direct` and the bins mix directions).
struct TruthPaths {
  Vec3d wi;
  bool diffuse = false;
  int res = 0;
  std::vector<TruthPath> paths;  ///< in ray order (16 bytes each)
};

/// Fibers placed for tracing: an Embree scene of round linear curves over a periodic tile.
class FiberTruthScene {
 public:
  /// material[c] indexes `materials` for curve c of `curves`; the tile (x0, y0, x1, y1, um) is
  /// the period. Throws std::runtime_error when Embree cannot build the scene.
  FiberTruthScene(const FiberCurves& curves, const std::vector<uint8_t>& material,
                  std::vector<FiberMaterial> materials, std::array<double, 4> tile);
  ~FiberTruthScene();
  FiberTruthScene(const FiberTruthScene&) = delete;
  FiberTruthScene& operator=(const FiberTruthScene&) = delete;

  /// Light from unit direction wi (wi.z != 0), traced with s's rays, bins and seed, with the
  /// scene's materials: tally(paths(wi, s), materials()).
  TruthResult trace(const Vec3d& wi, const TruthSettings& s) const;
  /// The paths alone (the materials' IOR used, not their absorption).
  TruthPaths paths(const Vec3d& wi, const TruthSettings& s) const;
  /// Diffuse light (uniform radiance) over the upper or the lower hemisphere.
  TruthPaths diffuse_paths(bool from_above, const TruthSettings& s) const;
  /// The result of paths for materials of other absorption (the same IORs: what the paths
  /// were traced with), one per scene material.
  TruthResult tally(const TruthPaths& p, const std::vector<FiberMaterial>& materials) const;
  const std::vector<FiberMaterial>& materials() const;
  size_t curves() const;

 private:
  TruthPaths paths_of(const Vec3d& wi, bool diffuse, const TruthSettings& s) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The tile of whole weave repeats the truth traces for a spec (header comment).
std::array<double, 4> truth_tile(const FabricSpec& spec, int min_yarns);

/// Per yarn (warp, weft) the fibers' material: the yarn's IOR and the absorption its colour
/// (color_linear: resolve_yarn_colours first) stands for, as the ray-wave tier derives it (absorption.h: the colour through the ply's
/// simulated sigma -> energy curve at the spec's quality, per RGB channel).
std::array<FiberMaterial, 2> truth_materials(const FabricSpec& spec);

/// The scene of a spec's tile: realize the tile's fibers (warp and weft materials from
/// truth_materials), build the Embree scene; trace it for as many wi as needed.
std::unique_ptr<FiberTruthScene> make_truth_scene(const FabricSpec& spec, int min_yarns);

/// The whole computation for a spec: make_truth_scene, then trace.
TruthResult fiber_truth(const FabricSpec& spec, const Vec3d& wi, const TruthSettings& s);

}  // namespace loom
