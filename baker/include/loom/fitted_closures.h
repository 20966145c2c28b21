// The surface tier's per-texel fitted closures (osl/include/loom/fitted_closures.h: the closure
// set, the weights and the texture layout): each texel's weights fitted at bake time against the
// model over the sphere of lights and a set of views, per unit of each colour term. (Reading them
// is the evaluators' part: has_fitted_closures, sample_fitted_closures in evaluator.h.)
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

/// The horizon strip (fitted_closures.h): the horizon maps' sines, tile k holding (h_k, h_k+1,
/// 0, 0), for the shaders' V(V) in one read.
Image horizon_strip(const Atlas& a);

}  // namespace loom
