// The swatch an atlas renders (swatch.h's definition, issue 35): what each tier shows of a
// picked colour, by the C++ model or the closure mixture, to compare with the picked colour and
// with the other tier.
//
// Geometry as a camera sees it, d:8: the view V at 8 degrees, uniform light over the upper
// hemisphere; R = int f(L, V) |cos L| dL over the upper hemisphere, T the same over the lower
// one (what the viewer sees of light from below, with the open gaps' delta). Below the cloth the
// pile (or a card) sends back X of the diffuse light it receives; the diffuse light it receives
// is what the cloth transmits of the room's, t, and the cloth's underside reflects R_u of the
// pile's; rho = R + T X t / (1 - R_u X) (swatch_rho; the same as the fibers' formula for a
// reciprocal BSDF, and what a camera sees for one that is not). The pile's layers have the
// cloth's diffuse reflect r and transmit t from above (pile_reflectance).
// Quadrature: midpoints of n x 2n cells per hemisphere for the lights (uniform in cos theta),
// n_views x 2 n_views for the views of the diffuse parts, averaged over points of the repeat
// (preset_error_sampling's lattice).
#pragma once
#include "loom/atlas.h"
#include "loom/evaluator.h"
#include "loom/swatch.h"

namespace loom {

struct AtlasSwatchSettings {
  double light_deg = 8;
  double card = -1;  ///< < 0 folded to opacity; else a card of this reflectance
  int points = 16;
  int n = 16;        ///< light cells per hemisphere: n x 2n
  int n_views = 4;   ///< view cells per hemisphere of the diffuse parts
};

/// rho and its parts in Swatch's fields: reflect and transmit R, T at the 8 degree view;
/// down_reflect, down_transmit r, t of diffuse light from above; up_reflect, up_transmit of
/// diffuse light from below (R_u, and what passes upwards); below X.
Swatch atlas_swatch(const Atlas& a, Evaluator e, const AtlasSwatchSettings& s = {});

}  // namespace loom
