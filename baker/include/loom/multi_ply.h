// Multi-ply scattering (ray-wave supplement section 2, Eq. S.13-S.19): the ply that faces the
// light scatters as a single ply; its neighbours shadow part of that light, scatter it once more
// (the "convolution" procedure) and pass on the rest as a diffuse residual band.
//
//   f_multi = f_direct + sum_p f_p^conv + f_resi                                        (S.13)
//
// Geometry (2D, in the plane normal to ply 0, lengths in units of the ply silhouette radius):
// ply 0 is centred at the origin with the yarn centre straight away from the light, at
// (0, -d), d = ply centre radius / silhouette radius; ply p sits at d (r_p - r_0) where r_p is
// ply p's radial direction, rotated by 2 pi p / P about the yarn axis; every ply is a circle of
// radius 1. Ply p's axis is the helix tangent cos(a) Y + sin(a) tau_p (a: the spec's ply twist
// angle, signed by the twist direction; Y the yarn axis, tau_p = Y x r_p), which fixes its
// incident angle and its frame (step 2.3: directions are carried between the plies' frames).
//
// Choices where the text is silent:
//  * Shadow tests start on the beam's chord through ply 0 (x = h, J points evenly over y), so the
//    visibility V(h, phi) and the hit fractions r_p(phi) of step (2.1) are averages over where
//    the light leaves ply 0; a start inside another ply counts as hitting it.
//  * The incident position on ply p is the signed offset of the hit point from ply p's centre
//    along ply p's own x axis (step 2.2); for the shadow test of step (4) the secondary light
//    leaves ply p from the point at the hit's offset across the 2D ray, on the chord through
//    ply p's centre. Incident directions are pooled into about 16 x 16 cells of the outgoing
//    grid (energy-weighted mean direction and offsets) for the convolution.
//  * Light that crosses a ply without meeting a fiber is a forward delta: ply 0's may hit ply p,
//    ply p's continues in its direction (both are kept, so at sigma = 0 no energy is lost).
//  * f_1 of Eq. S.19 is a Gaussian in theta_o of standard deviation kResidualWidth centred at
//    -theta_i, f_2 uniform in phi_o; c(theta_i, h, sigma) makes it integrate to Eq. S.18.
//  * Everything works on the simulated histograms (at every absorption level), and returns a
//    simulation of the same shape: the multi-ply yarn's "ply" then goes through the same ASG fit
//    and double-layer steps as a single ply. First-surface reflection that is not shadowed stays
//    f_refl; everything else is f_high.
#pragma once
#include "loom/ply_scattering.h"
#include "loom/spec.h"

namespace loom {

struct MultiPlyGeometry {
  int plies = 2;
  double centre_distance = 0.7;  ///< ply centre radius / silhouette radius
  double twist = 0.44;           ///< signed ply twist angle (radians)
  int origins = 8;               ///< J: shadow-test start points along the chord
};

inline constexpr double kResidualWidth = 0.3;  ///< radians, f_1 of Eq. S.19

/// The geometry of a yarn spec for a simulated ply (silhouette radius from the simulation).
MultiPlyGeometry multi_ply_geometry(const YarnSpec& y, const PlySimResult& single);

/// Energy bookkeeping of one slice (Eq. S.15-S.18), at one absorption level.
struct MultiPlyEnergy {
  double s1 = 0, s2 = 0, s3 = 0, residual = 0, direct = 0;
};

/// Eq. S.13 for every slice and absorption level of `single`. `energies`, if given, receives
/// the bookkeeping per slice and level ([slice * K + k]).
PlySimResult multi_ply_scattering(const PlySimResult& single, const MultiPlyGeometry& g,
                                  std::vector<MultiPlyEnergy>* energies = nullptr);

}  // namespace loom
