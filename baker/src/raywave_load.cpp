// Loading a ray-wave atlas for the baker's evaluators (raywave_bsdf.h: load_raywave): the ply
// tables, the double-layer grids and the render tables as the shaders read them, each checked
// against the manifest's grids.
#include <fmt/format.h>
#include <stdexcept>

#include "loom/raywave_bsdf.h"

namespace loom {

using nlohmann::json;

RaywaveData load_raywave(const Atlas& a) {
  RaywaveData d;
  const json& m = a.manifest;
  if (m.value("tier", "") != "raywave" || !m.contains("raywave"))
    throw std::runtime_error("not a ray-wave atlas (bake with \"model\": {\"tier\": \"raywave\"})");
  const json& rw = m["raywave"];
  if (!rw.contains("shading") || !rw["shading"].is_object())
    throw std::runtime_error("raywave.shading: missing (an atlas from before ray-wave shading: "
                             "re-bake it)");
  if (rw["shading"].value("sigma_interpolation", "") != kSigmaInterpolation)
    throw std::runtime_error("raywave.shading.sigma_interpolation: the render tables interpolate "
                             "between absorption levels otherwise than this loom-bake (an atlas "
                             "from an older loom-bake: re-bake it)");
  for (int y = 0; y < 2; ++y) {
    const char* yarn = y == 0 ? "warp" : "weft";
    d.yarn[y] = load_ply_tables(a, yarn);
    const json& e = d.yarn[y].entry;
    const json& s = e["absorption"]["sigma_rgb_per_mm"];
    for (int c = 0; c < 3; ++c) {
      d.sigma_rgb[y][size_t(c)] = s.at(size_t(c)).get<double>();
      if (!(d.sigma_rgb[y][size_t(c)] >= 0))
        throw std::runtime_error(fmt::format("raywave.yarns.{}.absorption.sigma_rgb_per_mm: {} is "
                                             "negative (allowed: 0 or more, 1/mm)",
                                             yarn, d.sigma_rgb[y][size_t(c)]));
    }
    d.nodes_high[y] = &a.map(e["files"]["high"].get<std::string>());
    d.nodes_refl[y] = &a.map(e["files"]["refl"].get<std::string>());
    d.tint[y] = &a.map(e["files"]["tint"].get<std::string>());
    if (!e["files"].contains("residual"))
      throw std::runtime_error(fmt::format("raywave.yarns.{}.files.residual: missing (an atlas from "
                                           "an older loom-bake: re-bake it)", yarn));
    d.residual[y] = &a.map(e["files"]["residual"].get<std::string>());
    const int M = int(d.yarn[y].high.theta_i.size()), N = int(d.yarn[y].high.h.size());
    if (d.residual[y]->width != 2 * N || d.residual[y]->height != M)
      throw std::runtime_error(fmt::format("raywave.yarns.{}.files.residual: image is {}x{}, the "
                                           "grids say {}x{}", yarn, d.residual[y]->width,
                                           d.residual[y]->height, 2 * N, M));
  }
  const json& dl = rw["double_layer"];
  d.blend = dl.value("blend", 0.5);
  for (int side = 0; side < 2; ++side) {
    const char* key = side == 0 ? "front" : "back";
    DoubleLayerGrid& g = d.layers[side];
    g.table = a.map(dl["files"][key].get<std::string>());
    g.theta_count = dl["theta_count"];
    g.phi_count = dl["phi_count"];
    g.sigmas = dl["sigma_per_mm"].get<std::vector<double>>();
    g.absorption = layer_absorption_curve(rw);
    if (g.table.width != g.phi_count || g.table.height != g.theta_count * int(g.sigmas.size()))
      throw std::runtime_error(fmt::format("raywave.double_layer: table {} is {}x{}, the grids say "
                                           "{}x{}", key, g.table.width, g.table.height,
                                           g.phi_count, g.theta_count * g.sigmas.size()));
    d.factors[side] = &a.map(rw["shading"]["factors"][key].get<std::string>());
    if (d.factors[side]->width != LOOM_DOUBLE_LAYER_BLOCKS * (g.phi_count + 2) ||
        d.factors[side]->height != g.theta_count)
      throw std::runtime_error(fmt::format(
          "raywave.shading.factors.{}: table is {}x{}, the grids say {}x{}", key,
          d.factors[side]->width, d.factors[side]->height,
          LOOM_DOUBLE_LAYER_BLOCKS * (g.phi_count + 2), g.theta_count));
  }
  d.microfacet_albedo = &a.map(rw["shading"]["microfacet_albedo"].get<std::string>());
  if (!rw["shading"].contains("asg_integral"))
    throw std::runtime_error("raywave.shading.asg_integral: missing (an atlas from an older "
                             "loom-bake: re-bake it)");
  d.asg_integral = &a.map(rw["shading"]["asg_integral"].get<std::string>());
  if (d.asg_integral->width != LOOM_ASG_INTEGRAL_LUT_SIZE ||
      d.asg_integral->height != LOOM_ASG_INTEGRAL_LUT_SIZE)
    throw std::runtime_error(fmt::format("raywave.shading.asg_integral: the LUT is {}x{}, not {}x{}",
                                         d.asg_integral->width, d.asg_integral->height,
                                         LOOM_ASG_INTEGRAL_LUT_SIZE, LOOM_ASG_INTEGRAL_LUT_SIZE));
  // Gap diffraction (diffraction_sampling.h), when the atlas has a gap table.
  const json& dif = rw.value("diffraction", json());
  if (dif.value("mode", "") == "tables" && dif.contains("files") && dif["files"].contains("gap")) {
    if (!dif["files"].contains("gap_sampling") || !dif.contains("spot_s") ||
        !dif.contains("gap_fraction"))
      throw std::runtime_error("raywave.diffraction: no gap sampling table (an atlas from an "
                               "older loom-bake: re-bake it)");
    GapDiffraction& g = d.diffraction;
    const Image& img = a.map(dif["files"]["gap"].get<std::string>());
    const int size = dif.value("tile_size", 0);
    if (img.channels != 3)
      throw std::runtime_error("raywave.diffraction: the gap table is not RGB");
    g.table = diffraction_table_from_rgb(img.width, img.height, img.data.data(), size);
    g.sampling = &a.map(dif["files"]["gap_sampling"].get<std::string>());
    if (g.sampling->width != LOOM_DIFFRACTION_ICDF_SIZE * g.table.tiles_x ||
        g.sampling->height != (size + 1) * g.table.tiles_y || g.sampling->channels != 3)
      throw std::runtime_error(fmt::format(
          "raywave.diffraction: the gap sampling table is {}x{}, the gap table says {}x{}",
          g.sampling->width, g.sampling->height, LOOM_DIFFRACTION_ICDF_SIZE * g.table.tiles_x,
          (size + 1) * g.table.tiles_y));
    g.spot_s = dif["spot_s"].get<double>();
    for (int k = 0; k < 2; ++k) g.gap_fraction[k] = dif["gap_fraction"].at(size_t(k)).get<float>();
    g.yarns[0] = m.at("repeat").at("weft_yarns").get<int>();
    g.yarns[1] = m.at("repeat").at("warp_yarns").get<int>();
    for (int t = 0; t < g.table.tiles_x * g.table.tiles_y; ++t)
      for (int c = 0; c < 3; ++c)
        g.sampler.push_back(
            diffraction_sampler(g.table, t % g.table.tiles_x, t / g.table.tiles_x, c, g.spot_s));
    g.present = true;
  }
  // Speckle noise (speckle_noise.h), when the atlas has the tiles.
  const json& nz = rw.value("noise", json());
  if (nz.is_object() && nz.contains("files") && nz["files"].contains("refl")) {
    if (nz.value("levels", 0) != LOOM_NOISE_LEVELS)
      throw std::runtime_error("raywave.noise: no blur levels (an atlas from an older loom-bake: "
                               "re-bake it)");
    SpeckleNoise& n = d.noise;
    n.instances = nz.value("instances", 1);
    const int T = nz.value("theta_count", 0);
    n.refl = &a.map(nz["files"]["refl"].get<std::string>());
    n.high = &a.map(nz["files"]["high"].get<std::string>());
    for (const Image* img : {n.refl, n.high})
      if (img->width != 2 * T || img->height != T * n.instances * LOOM_NOISE_LEVELS)
        throw std::runtime_error(fmt::format("raywave.noise: a tile is {}x{}, the manifest says "
                                             "{}x{}", img->width, img->height, 2 * T,
                                             T * n.instances * LOOM_NOISE_LEVELS));
    n.present = true;
  }
  return d;
}

}  // namespace loom
