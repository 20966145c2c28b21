// The surface tier's swatch reading of a colour (surface_swatch.h).
#include "loom/surface_swatch.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace loom {

double surface_swatch_rho(const SurfaceSwatchCurve& curve, int ch, double c) {
  const size_t k = size_t(ch);
  auto at = [&](const std::array<double, 3> Swatch::*part) {
    return (curve.at0.*part)[k] + c * ((curve.at1.*part)[k] - (curve.at0.*part)[k]);
  };
  const double R = at(&Swatch::reflect), T = at(&Swatch::transmit);
  const double r = at(&Swatch::down_reflect), t = at(&Swatch::down_transmit);
  const double Ru = at(&Swatch::up_reflect);
  const double X = curve.card < 0 ? pile_reflectance(r, t) : curve.card;  // the pile, or a card
  return swatch_rho(R, T, X, t, Ru);
}

SurfaceSwatchColour surface_swatch_albedo(const SurfaceSwatchCurve& curve,
                                          const std::array<double, 3>& picked) {
  SurfaceSwatchColour out;
  for (int ch = 0; ch < 3; ++ch) {
    const size_t k = size_t(ch);
    double lo = 0, hi = curve.albedo_max;
    const double target = picked[k];
    if (surface_swatch_rho(curve, ch, hi) <= target) {
      lo = hi;
      out.out_of_reach[k] = surface_swatch_rho(curve, ch, hi) < target;
    } else if (surface_swatch_rho(curve, ch, lo) >= target) {
      hi = lo;
      out.out_of_reach[k] = surface_swatch_rho(curve, ch, lo) > target;
    }
    for (int it = 0; it < 60 && hi - lo > 1e-9; ++it) {  // rho rises with the albedo
      const double mid = 0.5 * (lo + hi);
      (surface_swatch_rho(curve, ch, mid) < target ? lo : hi) = mid;
    }
    out.albedo[k] = 0.5 * (lo + hi);
    out.rho[k] = surface_swatch_rho(curve, ch, out.albedo[k]);
  }
  return out;
}

SurfaceSwatchCurve surface_swatch_curve(const Atlas& a, const SurfaceMaps& white,
                                        const AtlasSwatchSettings& s) {
  Atlas zero = a, one = a;
  double white_max = 0;  // the largest albedo texel at c = 1
  for (size_t i = 0; i < a.names.size(); ++i) {
    if (a.names[i].rfind("albedo_", 0) != 0) continue;
    size_t w = 0;
    while (w < white.info.size() && white.info[w].name != a.names[i]) ++w;
    if (w == white.info.size())
      throw std::runtime_error("surface_swatch_curve: no " + a.names[i] + " among the maps");
    const Image& src = white.images[w];
    Image& z = zero.images[i];
    Image& o = one.images[i];
    if (src.width != o.width || src.height != o.height || src.channels != o.channels)
      throw std::runtime_error("surface_swatch_curve: " + a.names[i] + " of another size");
    for (int y = 0; y < o.height; ++y)
      for (int x = 0; x < o.width; ++x)
        for (int ch = 0; ch < 3; ++ch) {  // (the fourth channel, the specular share, stays)
          z.px(x, y)[ch] = 0.0f;
          o.px(x, y)[ch] = src.px(x, y)[ch];
          white_max = std::max(white_max, double(src.px(x, y)[ch]));
        }
  }
  SurfaceSwatchCurve curve{atlas_swatch(zero, Evaluator::Closures, s),
                           atlas_swatch(one, Evaluator::Closures, s), s.card};
  // c_max: the yarns' directional albedo, a0 + c (a1 - a0) at each point and view, at most
  // kSurfaceSwatchMaxAlbedo (never below c = 1, the ply's own reading); no texel above 1.
  double energy = INFINITY;
  const auto& a0 = curve.at0.view_albedo;
  const auto& a1 = curve.at1.view_albedo;
  for (size_t k = 0; k < a0.size() && k < a1.size(); ++k)
    for (size_t ch = 0; ch < 3; ++ch)
      if (a1[k][ch] > a0[k][ch])
        energy = std::min(energy, (kSurfaceSwatchMaxAlbedo - a0[k][ch]) / (a1[k][ch] - a0[k][ch]));
  curve.albedo_max = std::min(white_max > 0 ? 1.0 / white_max : 1.0, std::max(1.0, energy));
  return curve;
}

AtlasSwatchSettings surface_swatch_settings(Quality q) {
  AtlasSwatchSettings s;
  switch (q) {
    // The points (a jittered side x side lattice) matter most: a weave repeat sampled on 3 x 3
    // points put gray wool twill's swatch 6 % off its average over 5 x 5.
    case Quality::Reference: s.points = 144, s.n = 16, s.n_views = 4; break;
    default: s.points = 64, s.n = 12, s.n_views = 3; break;
  }
  return s;
}

}  // namespace loom
