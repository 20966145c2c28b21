// ASG block fitting of simulated ply scattering (ray-wave supplement section 1, Eq. S.3-S.12).
//
// f_0^high over the (theta_i^m, h^n) grid (M = 2M' + 1, N = 2N' + 1 samples) is split into
// M' x N' fitting blocks of 3 x 3 slices (S.3). Each slice of a block is a sum of L lobes (S.4)
// whose parameters are bilinear in the four corner parameter sets (S.5); those are optimised
// jointly with Ceres (Levenberg-Marquardt, analytic derivatives from asg_eval_grad). Evaluation
// between samples interpolates the corner sets bilinearly (S.6-S.8). For sigma_k > 0 the lobes
// stay fixed and per-block scale-downs s_{l,k} are fitted (S.9), s_{l,0} = 1, interpolated
// between levels (S.10-S.12) with the weight of absorption_curve.h (linear in the ply's simulated
// energy, which S.10's linear weight in sigma overshoots by up to 4x on the presets' levels).
//
// Choices where the text is silent:
//  * Shared corners. The supplement fits every block on its own, so a corner slice shared by
//    two blocks gets two different lobe sets and the lobes jump at block borders. Loom stores one
//    parameter set per corner node (theta_i^{2m}, h^{2n}) and fits the blocks in raster order:
//    a block optimises its corners jointly, holding fixed the corners an earlier block already
//    fitted. The representation is therefore continuous across block borders, lobe l is the same
//    lobe everywhere (correspondence for free), and each block is still the joint 3 x 3 fit of S.4.
//  * Initialisation: the first corner greedily (peak of the remaining data, half-maximum widths,
//    then a single-slice fit); every later corner starts from its fitted neighbour.
//  * Angles: theta_z is bounded to [-pi/2, pi/2]; phi_z and phi_xy are left unbounded, so that a
//    lobe that crosses phi = +-pi keeps a continuous (unwrapped) value and S.7 interpolates it
//    along the short way; asg_eval is 2 pi periodic in both.
//  * Objective: solid-angle weighted least squares, sum_bins Omega_b (model - data)^2, on the
//    simulation's (theta_o, phi_o) bins (pooled 2 x 2 when the grid is finer than 32 x 64).
//    Fit error: normalised RMSE = sqrt(sum Omega (model - data)^2 / sum Omega data^2) per block
//    and over all slices.
//  * Scale-downs at the nodes, not per block. S.9 gives every block its own s_{l,k}, so with
//    absorption the model steps where two blocks meet (measured on twill at draft: 0.5 % of f at
//    a border of h). Loom keeps one s_{l,k} per corner node, like the lobes, and interpolates it
//    between the nodes with the lobes' bilinear weights (S.7), so the model is continuous in
//    (theta_i, h) at every sigma; a block's slices are fitted with the interpolated scales, i.e.
//    with the model the evaluators use.
//  * Scale-downs: one bounded least squares per level over all slices and nodes together,
//    0 <= s_{l,k} <= s_{l,k-1} (monotone in sigma by construction; the data are, since every
//    path is weighted by exp(-sigma l)), solved by projected Gauss-Seidel on the normal
//    equations from s_{.,k-1}. Beyond sigma_{K-1} the last scale-downs are kept (the data there
//    are close to zero anyway).
//  * Energy cap. Least squares on the bins may trade energy for shape: on the white twill's warp
//    ply at draft, the slice theta_i = -80 deg, h = -1/3 got lobes holding 1.86 of the beam where
//    the simulation scattered 0.82 into f_high, and the energy residual (asg_residual.h) never
//    takes energy from the lobes. After the fit of f_0, no slice's lobes hold more than its
//    data: the energy of a slice's lobes (asg_integral of S.7's interpolated lobes) is linear in
//    its corners' amplitudes c, so scaling the c of every corner that carries weight there by
//    data / lobes brings the slice down to its data and no other slice up; slices are taken from
//    the largest excess, each checked again before it is scaled. What the cap removes becomes
//    residual. Between the slices the interpolated lobes are not bounded this way.
//  * f_refl: the same block scheme with its own (small) lobe count and no absorption levels.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "loom/absorption_curve.h"
#include "loom/ply_scattering.h"

namespace loom {

/// The six parameters q of one lobe (Eq. S.1, S.2).
struct AsgLobe {
  double theta_z = 0, phi_z = 0, phi_xy = 0, mu1 = 1, mu2 = 1, c = 0;
};

struct AsgFitSettings {
  int lobes = 3;               ///< L
  int max_iterations = 40;     ///< Levenberg-Marquardt iterations per block
  double mu_max = 5000;        ///< upper bound on mu1, mu2
  int threads = 0;             ///< Ceres threads (0: hardware concurrency)
  /// With two lobes or more, half of them (rounded down) stay on the backward side of the ply
  /// (towards the beam's source in its cross-section) and the rest on the forward side. Choice
  /// where the text is silent: least squares alone spends every lobe on the forward peak, which
  /// holds most of the energy, and drops the broad backscatter (measured on the cream cotton
  /// twill ply at draft: 16 % of the energy scattered backward, 0.1 % in the fitted lobes),
  /// so cloth seen from the lit side came out nearly black.
  bool split_sides = true;
};

/// Lobe count and iterations of a quality preset, for f_high (refl = false) or f_refl.
AsgFitSettings asg_fit_settings(Quality q, bool refl);

/// Fitted lobe tables over the (theta_i, h) grid and absorption levels.
struct AsgTable {
  int lobes = 0;
  std::vector<double> theta_i, h, sigmas;  ///< the simulation's grids (radians, -, 1/mm)
  /// Corner nodes: (M' + 1) x (N' + 1), each `lobes` lobes: nodes[(i * (N' + 1) + j) * L + l].
  std::vector<AsgLobe> nodes;
  /// Scale-downs at the corner nodes, per level: scale[((k * (M' + 1) + i) * (N' + 1) + j) * L
  /// + l], k = 0 is 1; interpolated between the nodes with the lobes' weights (S.7).
  std::vector<double> scale;
  double& scale_at(int k, int i, int j, int l) {
    return scale[((size_t(k) * size_t(node_rows()) + size_t(i)) * size_t(node_cols()) + size_t(j)) *
                     size_t(lobes) + size_t(l)];
  }
  double scale_at(int k, int i, int j, int l) const {
    return const_cast<AsgTable*>(this)->scale_at(k, i, j, l);
  }
  std::vector<double> block_nrmse;  ///< per block, f_0
  double nrmse = 0;                 ///< over all slices, f_0
  std::vector<double> nrmse_per_sigma;  ///< over all slices, per absorption level
  /// Energy residual (asg_residual.h): what the lobes miss of the simulated energy, per slice
  /// (theta_i^m, h^n), absorption level k and side (0 backward, 1 forward):
  /// residual[((m * N + n) * K + k) * 2 + side], N = h.size(). Empty: not computed.
  std::vector<double> residual;
  /// The ply's sigma -> energy curve, the interpolation variable between levels
  /// (absorption_curve.h: sigma_interval). Empty: S.10's weight, linear in sigma.
  AbsorptionCurve absorption;
  int node_rows() const { return int(theta_i.size() / 2) + 1; }
  int node_cols() const { return int(h.size() / 2) + 1; }
  const AsgLobe& node(int i, int j, int l) const {
    return nodes[(size_t(i) * size_t(node_cols()) + size_t(j)) * size_t(lobes) + size_t(l)];
  }
};

/// The sharpest lobe a fit on a grid of rows x cols (theta_o, phi_o) bins can resolve: mu such
/// that the lobe's angular standard deviation 1 / sqrt(2 mu) is half a bin, mu = 2 / d^2 with d
/// the larger of the bins' elevation and equatorial azimuth widths. Choice where the text is
/// silent: S.4's least squares sees a lobe only at the bins' centres, so a lobe narrower than a
/// bin can sit between centres with any amplitude: its energy is then unconstrained (white silk
/// organza at `final`: lobes of mu ~ 1000 holding 2.4-4x the simulated energy, so the presets
/// did not converge towards `reference`). At half a bin the centres' Riemann sum of a lobe
/// equals its integral within 3 % wherever it sits. Fits cap mu1, mu2 at
/// min(AsgFitSettings::mu_max, this) on the grid they fit (after pooling), so a finer fit grid
/// allows sharper lobes: 117 at draft and final (24 x 48 bins, final's 48 x 96 pooled), 208 at
/// preview and reference (32 x 64, reference's 64 x 128 pooled), a standard deviation of 3.8
/// and 2.8 degrees.
double asg_resolvable_mu(int rows, int cols);

/// Fit f_high (all absorption levels) of a simulation.
AsgTable asg_fit_high(const PlySimResult& sim, const AsgFitSettings& s);
/// Fit f_refl of a simulation (one level, no scale-downs).
AsgTable asg_fit_refl(const PlySimResult& sim, const AsgFitSettings& s);

/// Bilinear weights of the corners (0,0), (0,1), (1,0), (1,1) of a block at fractions (r, s)
/// (S.5).
std::array<double, 4> asg_corner_weights(double r, double s);
/// The lobes at (theta_i, h, sigma) by S.6, S.7, S.10, S.11 (scale folded into c); queries
/// outside the grids are clamped to it.
std::vector<AsgLobe> asg_table_lobes(const AsgTable& t, double theta_i, double h, double sigma);
/// S.8 / S.12: the fitted scattering density at ply-space direction wo.
double asg_table_eval(const AsgTable& t, double theta_i, double h, double sigma, const Vec3d& wo);
/// Sum of S.1 over lobes.
double asg_mixture_eval(const std::vector<AsgLobe>& lobes, const Vec3d& wo);

}  // namespace loom
