// What a yarn colour means (issue 35: "the colour you pick is the colour you see"): the colour
// of a swatch of the cloth as a colour book shows it, measured on the fibers (fiber_truth.h).
//
// Definition (choices where the issue leaves them open, each stated once):
//  * Geometry d:8 of CIE 15 (diffuse light, viewed at 8 degrees from the normal), by reciprocity
//    the same as light from 8 degrees and every reflected direction collected: the directional-
//    hemispherical reflectance. Azimuth 45 degrees between warp and weft.
//  * Folded to opacity, as textile colour measurement does (ISO 105-J01, AATCC EP6: the
//    specimen folded into as many layers as make it opaque): the cloth lies on a pile of itself.
//    With the cloth's reflect R and transmit T for that light (T with the gaps' direct light),
//    its diffuse reflect and transmit R_u, T_u for light from below (uniform radiance, traced as
//    such), and X what lies below sends back of the diffuse light it receives, the sum of the
//    bounces between the cloth and what is below is
//        rho = R + T X T_u / (1 - R_u X).
//    For the pile, X = R_inf, the reflectance of infinitely many layers, each with the diffuse
//    reflect r and transmit t of light from above: the root in [0, 1] of R = r + t^2 R / (1 - r R),
//        R_inf = (1 + r^2 - t^2 - sqrt((1 + r^2 - t^2)^2 - 4 r^2)) / (2 r).
//    The gaps of one layer are covered by the next, so a gappy red cloth is red, not pink.
//    Alternatively (`card` >= 0) the cloth lies on a Lambertian card of that reflectance: X = card
//    (1: a sheer white organza on white paper looks white).
//  * A yarn's colour is the swatch of a cloth of the spec's weave with both warp and weft of that
//    yarn (so that a warp and a weft of different colours each have a colour of their own).
//  * Solving: the fibers' absorption per unit length sigma, per channel (warp and weft alike), is
//    what makes rho equal the picked colour (scene linear). rho falls monotonically with sigma; a
//    colour brighter than the cloth with no absorption, or darker than at kSigmaMaxPerUm, is
//    out of reach: sigma is clamped there and the distance that remains reported.
#pragma once
#include <array>
#include <vector>

#include "loom/fiber_truth.h"
#include "loom/spec.h"

namespace loom {

struct SwatchSettings {
  double light_deg = 8;  ///< the light's angle from the normal
  double card = -1;      ///< < 0: folded to opacity; else on a card of this reflectance
  TruthSettings truth;   ///< rays per trace (two traces), seed, min_yarns
};

struct Swatch {
  std::array<double, 3> rho{};  ///< the swatch reflectance, scene linear
  std::array<double, 3> reflect{}, transmit{};  ///< R, T of the light from 8 degrees
  std::array<double, 3> up_reflect{}, up_transmit{};      ///< R_u, T_u: diffuse from below
  std::array<double, 3> down_reflect{}, down_transmit{};  ///< r, t: diffuse from above
  std::array<double, 3> below{};  ///< X: R_inf of the pile, or the card
  /// An atlas's (atlas_swatch.h): at each of its points and views, channel by channel, the
  /// directional albedo of the yarns there (reflect + transmit over the part of the point that
  /// is not open gap; 0 where all of it is); empty for the fibers'.
  std::vector<std::array<double, 3>> view_albedo;
};

/// The largest absorption the solver tries, per um (a 15 um fiber is then black).
inline constexpr double kSigmaMaxPerUm = 10.0;

struct SwatchSolve {
  std::array<double, 3> sigma_per_um{};
  Swatch swatch;                   ///< what that absorption gives
  std::array<bool, 3> clamped{};   ///< the picked colour is out of reach in this channel
};

/// rho(sigma) with every fiber absorbing sigma per um (every channel alike): sigma 0, then a
/// geometric grid from 1e-6 to kSigmaMaxPerUm. A colour's absorption follows from it without
/// tracing, so a colour-only re-bake needs only the curve.
struct SwatchCurve {
  std::vector<double> sigma_per_um, rho;
};

/// The sigma per um whose rho is `rho`, interpolated linearly in log sigma between the curve's
/// levels (0 below the first level); `clamped` when rho is out of the curve's range.
double swatch_sigma(const SwatchCurve& c, double rho, bool* clamped = nullptr);

/// The two formulas of the header, shared by the fibers' swatch and an atlas's (atlas_swatch.h):
/// the pile's reflectance R_inf of layers of diffuse reflect r and transmit t, and the swatch
/// rho = R + T X T_back / (1 - R_back X) for what lies below sending back X.
double pile_reflectance(double r, double t);
double swatch_rho(double R, double T, double X, double T_back, double R_back);

/// The curve's rho at sigma per um (linear in log sigma between levels; rho(0) below the first).
double swatch_rho_at(const SwatchCurve& c, double sigma_per_um);

/// A colour's absorption by its swatch (what the ray-wave bake stores): per channel the sigma
/// whose rho is the colour, at most sigma_max (the ply tables' last level), per mm; the rho it
/// gives; whether the colour was out of reach.
struct SwatchAbsorption {
  std::array<double, 3> sigma_per_mm{}, rho{};
  std::array<bool, 3> out_of_reach{};
};
SwatchAbsorption swatch_absorption(const SwatchCurve& c, const std::array<double, 3>& colour,
                                   double sigma_max_per_mm);

/// The three traces of a swatch (light from 8 degrees above; diffuse light from below and from
/// above), from which
/// the swatch of any absorption follows without tracing again (TruthPath).
class SwatchPaths {
 public:
  SwatchPaths(const FiberTruthScene& scene, const SwatchSettings& s);
  /// The swatch with the fibers of `materials` (one per material of the scene, same IORs).
  Swatch swatch(const std::vector<FiberMaterial>& materials) const;
  /// The absorption, the same for every material of the scene, that makes rho = target.
  SwatchSolve solve(const std::array<double, 3>& target) const;
  /// rho as a function of that absorption (swatch_sigma inverts it).
  SwatchCurve curve() const;

 private:
  const FiberTruthScene& scene_;
  SwatchSettings s_;
  TruthPaths front_, up_, down_;
};

/// The rays of the swatch traces at a quality preset (the bake's and eval truth's): Monte Carlo
/// error in rho about 1 / sqrt(rays), 0.7 % at draft.
uint64_t swatch_rays(Quality q);

/// The fibers' materials of a spec's scene as its colour reading has them (spec.h): the
/// ply-albedo reading (truth_materials) or the swatch's (swatch_absorption through the
/// scene's own swatch curve, traced with swatch_rays, each yarn's colour on its own).
std::vector<FiberMaterial> reading_materials(const FiberTruthScene& scene, const FabricSpec& spec);

}  // namespace loom
