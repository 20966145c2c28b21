// The energy residual of an ASG fit: what the fitted lobes miss of the simulated ply scattering,
// per slice, absorption level and side of the ply.
//
// Not in the supplement. Least squares with a few lobes (S.4) fits the sharp peaks of f_high and
// leaves the broad multiply scattered part out: on the seven sample fabrics the lobes hold
// 50-60 % of the energy the simulation scatters at sigma = 0 (cream cotton twill, final: 0.50 of
// 0.96), so cloth came out far too dark. The supplement keeps the energy of multi-ply scattering
// with a diffuse residual band (S.15-S.18); Loom does the same for the fit:
//
//   R_side(m, n, k) = max(0, E_side(data) - E_side(lobes) - O_other),
//   O_other = max(0, E_other(lobes) - E_other(data))
//
// with E_side the energy a slice sends to the backward side of the ply (towards the source in
// the ply's cross-section, y > 0 in ply space, as AsgFitSettings::split_sides) or the forward
// side (y < 0): the data's by summing bins (the bins of ply_sim_bin_direction split exactly at
// y = 0), the lobes' as asg_integral times the fraction of the lobe on that side. Choices:
//  * A side where the lobes overshoot gets no residual (energy is never taken away from the
//    lobes), and what they overshoot by is left out of the other side's residual: the slice's
//    energy, lobes + residual over both sides, is then max(E(data), E(lobes)), the simulated
//    energy wherever the lobes hold no more than it. Per side, lobes + residual = data where
//    neither side overshoots. (Before, each side was filled on its own: a fit that put 1 % too
//    much backwards and 1 % too little forwards scattered 1 % more than the ply did.)
//  * The fraction is integrated in the lobe's own frame, over the disk of asg.h's integral in
//    polar coordinates: along each ray of the disk the side changes at most once, where
//    v.y = 0, so the radial integral of each side is in closed form and only the polar angle is
//    a midpoint sum (2048 nodes). A box quadrature with a hard side test (before) was off by
//    0.002 in the fraction for a broad lobe whose backward part is a thin sliver at the rim
//    (mu 0.39 x 59: 0.0077 for 0.0059), 2 % of a strongly absorbing slice's backward energy.
//  * At render time (raywave_lobes.h) the backward residual becomes diffuse reflection and the
//    forward residual diffuse transmission of the cloth, with the double-layer factors of the
//    lobes: the residual is light that has crossed many fibres and left the ply in all
//    directions.
#pragma once
#include <vector>

#include "loom/asg_fit.h"
#include "loom/ply_scattering.h"

namespace loom {

/// The fraction of lobe q's integral on the side v.n > 0 of the plane through the origin with
/// normal n (ply space, unit), by the method above with `steps` polar nodes.
double asg_side_fraction(const AsgLobe& q, const Vec3d& n, int steps);

/// The fraction of lobe q's integral on the backward side (y > 0) of the ply (2048 nodes).
double asg_backward_fraction(const AsgLobe& q);

/// The residual of table t against the data it was fitted to (f_refl if refl, else f_high at
/// every absorption level), in AsgTable::residual's layout.
std::vector<double> asg_fit_residual(const PlySimResult& sim, const AsgTable& t, bool refl);

/// The data's energy on each side of one slice (side 0 backward, 1 forward), from the bins.
void ply_sim_side_energy(const PlySimSettings& s, const float* density, double& back,
                         double& forward);

/// Residual of table t at (theta_i, h, sigma): bilinear between slices, between levels by
/// S.10 with t's absorption curve (absorption_curve.h),
/// clamped to the grids; zero if the table has none.
void asg_residual_at(const AsgTable& t, double theta_i, double h, double sigma, double& back,
                     double& forward);

}  // namespace loom
