// Wave-optics speckle noise tiles (ray-wave supplement, section 5, Eq. S.37-S.38).
//
// A tile is N_2D(lambda, theta_o, phi_o) = |c|^2 = (r^2 + i^2) / 2 over outgoing directions in
// ply space (osl/include/loom/speckle_noise.h has the coordinates and the look-up), where
// c = (r + i i) / sqrt 2 is a circular complex Gaussian field with unit variance, so that r and
// i ~ N(0, 1) (S.37) and E[N] = 1 (S.38). The field is synthesised by FFT (FFTW) as
// c = IFFT(sqrt(P_2D) Z) with Z complex white noise and the isotropic 2D PSD
// P_2D(f_theta, f_phi) = P_1D(sqrt(f_theta^2 + f_phi^2)), renormalised to sum 1 (section 5.1).
//
// The 1D PSD (the main paper's is not in our texts; our choice). A coherent beam of waist w
// (Eq. S.25) lighting a surface whose height varies randomly over much less than w gives a far
// field whose angular autocorrelation is the Fourier transform of the illuminated intensity
// exp(-2 x^2 / w^2) (van Cittert-Zernike). In frequency f (cycles per radian of outgoing angle)
// that is P_1D(lambda; f) = exp(-2 (lambda f / w)^2): speckle grains about lambda / w radians
// wide, finer for wider coherent patches and shorter wavelengths. w is the spec's
// `wave.speckle_width_um` (by default the diffraction's beam waist, the same coherent patch).
//
// Wavelength bands: the tile's three channels hold lambda = 610, 550, 465 nm (near the
// dominant wavelengths of Rec.709's primaries). All bands share one Z: the same surface seen at
// another wavelength gives the same speckle, scaled in angle by lambda, so colours separate
// towards the grains' edges as in real speckle. Tiles for reflection and for higher-order
// scattering (section 5.1) come from different seeds; the text gives no other difference.
//
// Prefilter along phi (section 5.1): in (theta, phi) an isotropic grain covers less solid angle
// towards the poles. Each row is blurred in phi (periodically) with a Gaussian of
// sigma_phi = sigma_g |tan theta|, sigma_g = lambda / (sqrt 2 pi w) the correlation width of N:
// then N's correlation in phi is sigma_g / cos theta in angle, sigma_g in arc length, as on the
// equator. The mean stays 1; the variance drops to 1 / sqrt(1 + 2 tan^2 theta).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "loom/ply_maps.h"
#include "loom/spec.h"

namespace loom {

inline constexpr std::array<double, 3> kNoiseBandsNm{610.0, 550.0, 465.0};
/// The atlas's tiles use seeds kNoiseSeed (reflection) and kNoiseSeed + 1 (higher order): they
/// depend only on the waist and the quality, so a colour-only change keeps a fabric's speckle
/// (variation across the cloth comes from the ply-ID hash of speckle_noise.h).
inline constexpr uint64_t kNoiseSeed = 0x5eed10aull;

struct NoiseSettings {
  int theta_count = 256;  ///< rows per instance (theta over [-pi/2, pi/2]); 2x that many columns
  int instances = 2;      ///< independent tiles stacked in v, chosen per ply segment by a hash
};
NoiseSettings noise_settings(Quality q);

/// P_1D(lambda; f) of the header, lambda and w in um, f in cycles per radian.
double speckle_psd_1d(double lambda_um, double f, double w_um);

/// Correlation width (radians) of N in phi on the equator: lambda / (sqrt 2 pi w).
double speckle_grain_sigma(double lambda_um, double w_um);

/// A noise tile: (2 theta_count) x (instances theta_count) texels, RGB = the three bands, rows
/// counted from the bottom (theta = -pi/2 of instance 0). Deterministic in `seed`.
Image speckle_noise_tile(const NoiseSettings& s, double w_um, uint64_t seed, bool prefilter = true);

/// The tile at the blur levels the shaders read per lobe (osl/include/loom/speckle_noise.h:
/// LOOM_NOISE_LEVELS, noise_level_blur), stacked in v, level 0 (the tile itself) at the bottom:
/// each instance and band blurred by a Gaussian of noise_level_blur(l) radians of arc,
/// periodically in phi (sigma / cos theta of phi there, so that the blur is isotropic on the
/// sphere) and with clamped edges in theta.
Image speckle_noise_levels(const Image& tile, const NoiseSettings& s);

}  // namespace loom
