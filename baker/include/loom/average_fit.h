// The repeat-averaged closures of an atlas (average_closures.h: level of detail by footprint),
// fitted at bake time against the atlas's own model averaged over the weave repeat, per view
// direction of the table, with Ceres; both tiers.
//
// Per view: the model's f |cos| averaged over a jittered lattice of points of the repeat (the
// yarns' part, AtlasBsdf::at) on an even lattice of light directions; the closures' alphas and
// weights fitted to its grey (mean of RGB) by the relative distance over the sphere (relative
// to the model, floored at its mean) made smooth by Charbonnier's penalty, with the closures'
// albedo (integrated about each lobe) held to the model's and no lobe narrower than the lights'
// spacing (closure_fit.h does the same for the surface LUT); then each colour channel's weights
// fitted with the alphas fixed. Views are fitted along cos theta from the normal down, each
// starting from the one before; then the alphas of each row are set to their median and the
// weights refitted, so that the shaders' interpolation between views mixes closures of the same
// shapes.
#pragma once
#include <array>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

#include "loom/atlas.h"
#include "loom/cycles_closures.h"
#include "loom/shading.h"

namespace loom {

inline constexpr int kAverageClosures = LOOM_AVERAGE_PANELS;

/// One view's closures (average_closures.h's table, one texel of each panel): closure p's
/// weight w[p] (RGB: diffuse, translucent, glossy, refraction) and the alphas (a_x, a_y, a_t, 0).
struct AverageClosures {
  std::array<std::array<float, 3>, kAverageClosures> w{};
  std::array<float, kAverageClosures> alpha = {0.3f, 0.3f, 0.5f, 0.0f};
};

/// The closures set up for view V (the frame T = +x, B = +y, N = +z towards the viewer, V.z >
/// 0) as Cycles sets them up; eval gives f <L.N> per channel (Cycles' eval), basis(p, L)
/// closure p's alone at unit weight.
class AverageClosureSet {
 public:
  AverageClosureSet(const AverageClosures& p, shading::vec3 V);
  std::array<float, 3> eval(shading::vec3 L) const;
  float basis(int p, shading::vec3 L) const;
  /// Closure p's albedo at unit weight (diffuse and translucent: 1), integrated about its lobe.
  double albedo(int p) const;

 private:
  AverageClosures p_;
  shading::vec3 V_;
  cycles::MicrofacetReflection g_;
  cycles::MicrofacetRefraction r_;
};

/// A direction of the cloth's frame as the table's closures see it from the back side (`back`:
/// z mirrored, as the shaders' frame on a back face), or as it is.
inline shading::vec3 average_mirror(shading::vec3 v, bool back) {
  return back ? shading::vec3(v.x, v.y, -v.z) : v;
}

/// The closures the shaders read at view wo (the cloth's frame: x warp, z the front normal; wo.z
/// < 0 is the back side, read mirrored as the shaders do), bilinearly from the table.
AverageClosures read_average_closures(const Image& table, shading::vec3 wo);

/// f |cos| (RGB) of the averaged closures at light L and view wo (the cloth's frame, either
/// side), mirrored to the upper side as read_average_closures.
std::array<float, 3> average_closures_eval(const Image& table, shading::vec3 wo, shading::vec3 L);

struct AverageFitOptions {
  int points = 64;       ///< points of the repeat averaged (a jittered lattice)
  int sphere_n = 16;     ///< 2 sphere_n^2 light directions (a spherical Fibonacci lattice)
  int max_iterations = 15;  ///< each view starts from its neighbour's solution
  double charbonnier_eps = 0.02;
};

/// Options by quality: fewer points and light directions for draft and preview.
AverageFitOptions average_fit_options(const std::string& quality);

struct AverageFit {
  Image table;              ///< (PHI + 1) x (2 PANELS THETA) RGBA, rows bottom-up
  float gap_mean = 0;       ///< the repeat's mean open fraction (over every texel)
  double fit_l1_mean = 0;   ///< relative L1 of the fitted views, on the fit's own samples
  double fit_l1_worst = 0;
};

/// Fits the table for atlas `a` (either tier). progress(fraction) is called as views finish.
AverageFit fit_average_closures(const Atlas& a, const AverageFitOptions& o,
                                const std::function<void(double)>& progress = {});

/// The manifest entry of the table ("average": texture, grid, gap_mean, the fit's error).
nlohmann::json average_manifest(const AverageFit& f, const AverageFitOptions& o);

/// The averaged closures against the model averaged over the repeat, at views off the table's
/// nodes (fibonacci_views over both sides) and on an independent lattice of `points` points:
/// mean and worst relative L1 over the sphere (sphere_n grid, green), the mean energy error,
/// and for comparison the mean relative L1 of the per-texel closures (what the shaders render
/// near, eval mapping's mixture) averaged over the same points.
struct AverageError {
  double l1_mean = 0, l1_worst = 0, energy_mean = 0, texel_closures_l1_mean = 0;
  int views = 0;
};
AverageError average_closures_error(const Atlas& a, int points, int views, int sphere_n);

}  // namespace loom
