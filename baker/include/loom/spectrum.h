// Spectra to the working RGB space: the CIE 1931 2-degree colour matching functions and the
// per-channel spectral weights that integrate a spectral quantity (a diffraction pattern, an
// albedo spectrum) into scene-linear RGB.
#pragma once

#include <array>
#include <vector>

#include "loom/colour.h"

namespace loom {

/// Visible range Loom integrates over, in nanometres.
inline constexpr double kLambdaMinNm = 380.0, kLambdaMaxNm = 780.0;

/// CIE 1931 2-degree colour matching functions (x-bar, y-bar, z-bar) at `lambda_nm`, by the
/// multi-lobe piecewise-Gaussian fit of Wyman, Sloan and Shirley 2013 ("Simple analytic
/// approximations to the CIE XYZ color matching functions", JCGT 2(2)). Choice: the analytic
/// fit rather than the tabulated CIE data, which Debian does not package; its error is below
/// the variation between CIE's own 1931 and 2006 observers (y-bar peaks at 1.0 near 556 nm).
std::array<double, 3> cie1931_cmf(double lambda_nm);

/// Spectral RGB weights: wavelengths lambda_k (uniform, step `step_nm`, both ends included) and
/// per channel weights w_c(lambda_k) including the quadrature step, so that
///   rgb_c = sum_k w_c(lambda_k) S(lambda_k)
/// integrates a spectrum S into the working space. w_c = (M cmf)_c, M the XYZ to scene-linear
/// matrix of the colour converter, normalised per channel so that sum_k w_c = 1: a constant
/// spectrum 1 (a white, lossless surface) maps to RGB (1, 1, 1). This per-channel white balance
/// is the usual choice for reflectance-like quantities (the light's own colour is applied by the
/// renderer); it is what the text leaves open.
struct SpectralRgb {
  std::vector<double> lambda_nm;
  std::vector<std::array<double, 3>> weight;
};
SpectralRgb spectral_rgb(const ColourConverter& cc, double step_nm);

}  // namespace loom
