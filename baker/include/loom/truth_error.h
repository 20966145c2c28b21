// An atlas against the fibers (issue 35): its model and its closures (what Cycles renders) next
// to the fiber-level truth of the same fabric (fiber_truth.h), over the whole sphere.
//
// Set-up (each choice stated once):
//  * Views V: a spherical Fibonacci set on both sides of the cloth (fibonacci_views). For each,
//    the truth is traced with the light from V; by reciprocity its tally at wo, f(V, wo)
//    |cos wo|, is what Cycles' eval returns for the view V and a light from wo, which is what
//    the atlas is asked for (AtlasBsdf::at(u, v, V) at L = wo).
//  * The atlas's side: f(wo, V) |cos wo| averaged over each of the truth's bins (sub x sub
//    stratified midpoints) and over `points` points of the repeat (a jittered lattice,
//    preset_error_sampling): the repeat-averaged BSDF in the truth's own bins, so that both
//    sides are blurred alike by the bins.
//  * The gaps' delta (and the ray-wave tier's diffraction about it) is no density: the truth
//    leaves its `direct` light out of the tally and the atlas its open fraction; both count in
//    the transmitted albedo.
//  * relative_l1: sum over bins and RGB of |atlas - truth| over the sum of truth, per view;
//    its mean over the views. albedo_error: |A_atlas - A_truth| / A_truth with A the
//    directional albedo (reflect + transmit, RGB summed), mean over views; reflect_ratio and
//    transmit_ratio: atlas / truth per hemisphere (RGB summed), geometric mean over views (below
//    1 the atlas is darker than the fibers).
//  * noise_l1: the truth's own Monte Carlo part of relative_l1. The rays of a view are traced as
//    two halves of independent seeds a and b; the truth is their mean, and E|(a + b)/2 - mu| =
//    E|a - b| / 2 for independent halves of equal variance (Gaussian bins), so sum |a - b| / 2
//    over the sum of the truth estimates how far the truth itself is from converged. An
//    atlas's relative_l1 near noise_l1 means "as good as this many rays can tell".
#pragma once
#include <array>
#include <functional>
#include <vector>

#include "loom/atlas.h"
#include "loom/fiber_truth.h"
#include "loom/shading.h"
#include "loom/spec.h"

namespace loom {

struct TruthErrorSettings {
  int views = 6;
  int points = 256;
  int sub = 3;           ///< stratified samples per bin side for the atlas
  TruthSettings truth;   ///< rays per view (both halves together), res, seed, min_yarns
};

/// One evaluator (the model or the closures) against the truth.
struct TruthComparison {
  double relative_l1 = 0, albedo_error = 0, reflect_ratio = 0, transmit_ratio = 0;
};

struct TruthView {
  shading::vec3 view;
  std::array<double, 3> truth_reflect{}, truth_transmit{};  ///< transmit includes direct
  double truth_direct = 0, noise_l1 = 0;
  double open = 0;  ///< the atlas's open fraction (mean over the points)
  struct Side {
    std::array<double, 3> reflect{}, transmit{};  ///< transmit includes the open fraction
    double relative_l1 = 0;
  } model, closures;
};

struct TruthError {
  TruthComparison model, closures;
  double noise_l1 = 0;  ///< mean over the views
  std::vector<TruthView> views;
};

/// Throws std::runtime_error when the atlas is not of `spec`'s weave repeat.
TruthError truth_error(const Atlas& a, const FabricSpec& spec, const TruthErrorSettings& s);

// The pieces, exposed for the tests.

/// f(wo) |cos wo| (RGB) averaged over each bin of the truth's layout (fiber_truth.h: res x res,
/// rows uniform in cos theta from -1, columns in phi from -pi) by sub x sub midpoints, added
/// with `weight` into `bins` (res x res x 3).
void add_bin_averages(const std::function<std::array<float, 3>(shading::vec3)>& f, int res,
                      int sub, double weight, std::vector<double>& bins);

/// What a tally in that layout sends to the hemisphere z > 0 (upper) or z < 0, per channel
/// (res even: the rows split at z = 0).
std::array<double, 3> hemisphere_sum(const std::vector<double>& bins, int res, bool upper);

/// The truth from two half traces of independent seeds: the mean of their tallies (res x res x
/// RGB) and its Monte Carlo relative L1 (header comment: noise_l1).
struct TruthTally {
  std::vector<double> density;
  double noise_l1 = 0;
};
TruthTally combine_halves(const TruthResult& a, const TruthResult& b);

/// sum |a - b| / sum b over every bin and channel (0 when b sums to 0 and a equals it).
double relative_l1(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace loom
