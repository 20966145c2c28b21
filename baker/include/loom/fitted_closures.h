// The surface tier's per-texel fitted closures (osl/include/loom/fitted_closures.h: the closure
// set, the weights and the texture layout): each texel's weights fitted at bake time against the
// model over the sphere of lights and a set of views, per unit of each colour term.
#pragma once
#include <functional>

#include "loom/atlas.h"
#include "loom/shading.h"
#include "loom/spec.h"

namespace loom {

/// The fit's quadrature: `views` directions on each side (a spherical Fibonacci set of the
/// upper hemisphere) and the sphere_grid(sphere_n) lights.
struct FittedClosureOptions {
  int views = 4, sphere_n = 8;
  int irls_iterations = 4;  ///< reweightings from least squares towards the relative L1
};
FittedClosureOptions fitted_closure_options(Quality q);

/// Fits every texel of the atlas's maps against its model (the closure LUT shapes and weighs the
/// specular closures at each view); returns the texture of fitted_closures.h's layout (rows
/// bottom-up like every loaded map). `progress` gets the fraction done.
Image fit_texel_closures(const Atlas& a, const FittedClosureOptions& o,
                         const std::function<void(double)>& progress = {});

/// Whether the atlas holds fitted closures (an atlas baked with model.closures "fitted").
bool has_fitted_closures(const Atlas& a);

/// The two panels (a_np, a_ns, b_np, b_ns) and (m_g, m_h, l, 0) at (u, v) of the repeat, side
/// `back`, read as a Linear image texture reads them and guarded as the shaders guard them.
void sample_fitted_closures(const Atlas& a, float u, float v, int back, float fd[4], float fs[4]);

}  // namespace loom
