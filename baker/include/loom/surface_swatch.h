// The surface tier's reading of a yarn colour as its swatch (swatch.h's definition, issue 35):
// the diffuse albedo, per channel, that makes the swatch the surface atlas renders
// (atlas_swatch.h, by its closures: what Cycles renders) the picked colour.
//
// The surface maps are linear in the yarn colour (ply_maps.h: the albedo maps' colour channels;
// the specular weights carry none), so each part of the swatch (R, T, r, t, R_u, T_u) is affine
// in it: the swatches of the cloth with every albedo 0 and every albedo 1 give rho(c) per
// channel in closed form. rho rises with c; a colour is solved by bisection in [0, c_max] and,
// out of that range (brighter than the cloth at c_max, or darker than its sheen alone), clamped
// and flagged. c may exceed 1: the surface model loses light that the fibers keep (a white plain
// weave at albedo 1 reflects and transmits 0.60 of the light from 8 degrees, its fibers all of
// it), and a larger albedo stands in for that light, as far as energy allows: c_max is where the
// yarns' directional albedo (reflect + transmit), affine in c at each of the swatch's points and
// views, first reaches kSurfaceSwatchMaxAlbedo (but at least 1), and no albedo texel exceeds 1.
// As for the fibers, a yarn's colour is the swatch of a cloth of the spec's weave with every
// yarn of that colour (each system keeps its own specular and transmission shares).
#pragma once
#include <array>

#include "loom/atlas.h"
#include "loom/atlas_swatch.h"
#include "loom/ply_maps.h"
#include "loom/spec.h"
#include "loom/swatch.h"

namespace loom {

/// The swatches of the cloth at albedo 0 and 1 (every yarn, every channel).
struct SurfaceSwatchCurve {
  Swatch at0, at1;
  double card = -1;  ///< what lies below: < 0 the pile of the cloth, else a card (atlas_swatch.h)
  double albedo_max = 1;  ///< c_max (see above)
};

/// The most a cloth may reflect and transmit of the light from any one direction when the
/// swatch reading raises its albedo (a margin below 1 for the views between the sampled ones).
inline constexpr double kSurfaceSwatchMaxAlbedo = 0.95;

/// rho of the cloth at albedo c in channel ch (c in [0, albedo_max]).
double surface_swatch_rho(const SurfaceSwatchCurve& curve, int ch, double c);

struct SurfaceSwatchColour {
  std::array<double, 3> albedo{}, rho{};  ///< the solved albedo and the swatch it gives
  std::array<bool, 3> out_of_reach{};
};
/// The albedo whose swatch is `picked` (scene linear), per channel.
SurfaceSwatchColour surface_swatch_albedo(const SurfaceSwatchCurve& curve,
                                          const std::array<double, 3>& picked);

/// The curve of a surface atlas: its albedo maps' colour channels replaced by 0, then by those
/// of `white` (bake_surface_maps of the spec with every colour 1), the rest as baked.
SurfaceSwatchCurve surface_swatch_curve(const Atlas& a, const SurfaceMaps& white,
                                        const AtlasSwatchSettings& s);

/// The spec with every colour (warp, weft, each yarn type) replaced by f(colour).
template <class F>
FabricSpec with_colours(FabricSpec spec, F f) {
  spec.warp.color_linear = f(spec.warp.color_linear);
  spec.weft.color_linear = f(spec.weft.color_linear);
  for (YarnType& t : spec.yarn_types) t.color_linear = f(t.color_linear);
  return spec;
}

/// The swatch's quadrature at a quality preset (the bake's).
AtlasSwatchSettings surface_swatch_settings(Quality q);

}  // namespace loom
