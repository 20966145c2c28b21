// The C++ evaluators of an atlas: the surface model itself (the reference) and the closure
// emulator (the mixture of Cycles closures that the OSL shader and node mode build), both reading
// the same texels as the shaders and both through the shared shading math.
#pragma once
#include <array>
#include <cmath>
#include <functional>
#include <utility>
#include <vector>

#include "loom/atlas.h"
#include "loom/shading.h"

namespace loom {

/// Everything the BSDF needs at one surface point, sampled from the atlas.
struct SurfacePoint {
  shading::vec3 t, n_p;
  float h = 0, height = 0;
  float kind = 0;  ///< as interpolated from yarn_info (0 gap, 1 warp, 2 weft)
  float along = 0, ply_id = 0, gap = 0;
  shading::vec3 k_rd, k_td;
  float k_rs = 0, k_ts = 0;
  float roughness = 0.25f, thickness = 1, blend = 0.5f, ior = 1.5f;
  float horizon[LOOM_HORIZON_DIRS] = {};
  float u = 0, v = 0;    ///< where in the repeat, [0, 1) (v from the bottom)
  float du = 0, dv = 0;  ///< the footprint around (u, v) (a texel; 0 for a point)
};

/// Bilinear, periodic sample at (u, v) (v from the bottom, any real value: wrapped), with the
/// same filtering as a Blender image texture (linear, repeat); tangent and normal renormalised.
SurfacePoint sample_surface(const Atlas& a, float u, float v);
/// An image read as a Linear, repeating image texture reads it: bilinear between texel centres,
/// at (u, v) with v from the bottom, wrapped; out[0 .. channels - 1].
void bilinear(const Image& img, float u, float v, float out[4]);
/// The exact texel (ix, iy) (row iy from the bottom).
SurfacePoint texel_surface(const Atlas& a, int ix, int iy);

/// Whether the atlas holds per-texel fitted closures (model.closures "fitted",
/// fitted_closures.h).
bool has_fitted_closures(const Atlas& a);
/// Their two panels (a_np, a_ns, b_np, b_ns) and (m_g, m_h, l, 0) at (u, v) of the repeat, side
/// `back`, read as a Linear image texture reads them and guarded as the shaders guard them.
void sample_fitted_closures(const Atlas& a, float u, float v, int back, float fd[4], float fs[4]);

/// p with every field in the range the baker writes (texel_guard.h): NaN to the field's neutral
/// value, anything else outside its range to the nearest end, a degenerate ply frame to a valid
/// one. The identity for every texel of a valid atlas; both tiers' evaluators apply it first, so
/// no texel value can make them return NaN, Inf or a negative value.
SurfacePoint guard_surface_point(const SurfacePoint& p);

enum class Evaluator { Model, Closures };
/// Which Cycles front end builds the closures: node mode (SVM) or the OSL shader. They differ in
/// one place: SVM's Translucent BSDF raises its normal with ensure_valid_specular_reflection.
enum class Backend { Nodes, Osl };

/// f(wi, wo) without the cosine; wi towards the light, wo towards the viewer, tangent frame.
std::array<float, 3> eval_bsdf(const Atlas& a, const SurfacePoint& p, shading::vec3 wi,
                               shading::vec3 wo, Evaluator e, Backend backend = Backend::Nodes);

/// Mean of f over all texels of the repeat (what a pixel covering many repeats sees).
std::array<float, 3> eval_bsdf_average(const Atlas& a, shading::vec3 wi, shading::vec3 wo,
                                       Evaluator e, Backend backend = Backend::Nodes);

/// The directions of Loom's quadratures over the sphere. Views: a spherical Fibonacci set of
/// n directions on both sides of the cloth (|z| <= 0.99). Lights: the midpoint grid of
/// n x 2n cells uniform in z and phi, each of solid angle sphere_grid_dw(n).
std::vector<shading::vec3> fibonacci_views(int n);
/// n directions of a spherical Fibonacci lattice, z scaled by z_scale (1: the whole sphere,
/// each direction of solid angle 4 pi / n; fibonacci_views is it at 0.99).
std::vector<shading::vec3> fibonacci_sphere(int n, double z_scale = 1.0);
std::vector<shading::vec3> sphere_grid(int n);
inline double sphere_grid_dw(int n) { return (2.0 / n) * (M_PI / n); }

/// The closure-mapping error: for texels spread over the repeat and views V over the whole sphere
/// (front and back of the cloth), the relative L1 distance over the sphere of light directions,
///   e(x, V) = int |f_closures - f_model| |cos| dL / int f_model |cos| dL   (green channel),
/// and the same for the directional albedo alone (energy error). Mean and worst over (x, V).
struct MappingError {
  double mean_l1 = 0, worst_l1 = 0, mean_energy = 0, worst_energy = 0;
  int texels = 0, views = 0;
};
MappingError mapping_error(const Atlas& a, int texels = 64, int views = 24, int sphere_n = 64,
                           Backend backend = Backend::Nodes);

/// The loop of mapping_error() for any tier: `setup(p, V)` returns, for a surface point and a
/// view, the function of the light direction L giving (model, closures), green channel, each
/// times |cos| of L about the surface.
using MappingPair = std::function<std::pair<float, float>(shading::vec3 L)>;
MappingError mapping_error_loop(const Atlas& a, int texels, int views, int sphere_n,
                                const std::function<MappingPair(const SurfacePoint&, shading::vec3)>& setup);

}  // namespace loom
