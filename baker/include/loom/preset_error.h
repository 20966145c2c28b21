// The error of a quality preset: an atlas's BSDF against the BSDF of the same fabric baked at
// another preset (the `reference`), both by the C++ model evaluator (the closures play no part:
// their own error is the closure-mapping error, evaluator.h). This is the accuracy side of the
// speed/accuracy trade (scripts/trade.sh).
//
// Choices (the papers compare renders, not presets):
//   * Points: positions (u, v) of the weave repeat on a jittered n x n lattice, n the nearest
//     integer to sqrt(points) (a fixed hash, so every run and both atlases use the same ones).
//     The presets' maps differ in resolution, so a point is read from each atlas at the same (u, v) as its shader reads it:
//     the surface tier bilinearly (Linear image textures), the ray-wave tier from the nearest
//     texel (Closest).
//   * Views: a spherical Fibonacci set over both sides of the cloth; light directions: a
//     midpoint grid of sphere_n x 2 sphere_n over the sphere; the quantity compared is f |cos L|
//     (green), the open gaps' delta and diffraction left out (no quadrature resolves them; the
//     gap coverage itself is in f as (1 - c)).
//   * `pointwise`: mean and worst over (point, view) of  int |f_a - f_r| dL / int f_r dL.
//     Speckle noise tiles of different presets are different random fields, so this includes
//     the difference of two noise realisations as well as of the tables.
//   * `average`: the same relative L1 of the BSDFs averaged over the points (what a pixel
//     covering many repeats sees), mean over views: the number the trade plots.
//   * `energy`: mean over views of the relative difference of the averaged directional albedos.
//   * Views the reference sends nothing to (grazing) are not counted; `views` says how many were.
#pragma once
#include <utility>
#include <vector>

#include "loom/atlas.h"
#include "loom/shading.h"

namespace loom {

/// Where preset_error() looks: the (u, v) points of the repeat, the views and the light
/// directions (each of solid angle `dw`).
struct PresetErrorSampling {
  std::vector<std::pair<float, float>> uv;
  std::vector<shading::vec3> views, lights;
  double dw = 0;
};
PresetErrorSampling preset_error_sampling(int points, int views, int sphere_n);

struct PresetError {
  double pointwise_mean = 0, pointwise_worst = 0, average = 0, energy = 0;
  int points = 0, views = 0;
};

/// Throws std::runtime_error when the two atlases are not of the same tier or not of the same
/// weave repeat (what is compared must be the same fabric), and when nothing could be compared
/// (no view the reference sends light to, or every point an open gap).
PresetError preset_error(const Atlas& a, const Atlas& reference, int points = 64, int views = 12,
                         int sphere_n = 48);

}  // namespace loom
