// loom-bake eval average, and eval bsdf --evaluator average: the repeat-averaged closures
// (average_closures.h, average_fit.h), what the shaders render where a pixel covers whole
// repeats, and their distance from the model averaged over the repeat.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/atlas_bsdf.h"
#include "loom/average_fit.h"

using nlohmann::json;

namespace loom::cli {

int eval_average_closures(const Atlas& atlas, bool average, std::array<double, 2> uv,
                          const std::vector<std::pair<shading::vec3, shading::vec3>>& pairs) {
  const Image& table = atlas.map("average_closures");
  float scale = 1;  // over the repeat the yarn coverage's scale averages to 1
  if (!average) {
    const AtlasBsdf bsdf(atlas, Evaluator::Model);
    const float u = float(uv[0] - std::floor(uv[0])), v = float(uv[1] - std::floor(uv[1]));
    scale = shading::average_closures_yarn_scale(
        bsdf.open(u, v), atlas.manifest.at("average").at("gap_mean").get<float>());
  }
  for (const auto& [wi, wo] : pairs) {
    const std::array<float, 3> fc = average_closures_eval(table, wo, wi);
    const float c = std::max(std::fabs(wi.z), 1e-6f);
    std::cout << json{{"f", {scale * fc[0] / c, scale * fc[1] / c, scale * fc[2] / c}},
                      {"f_cos", {scale * fc[0], scale * fc[1], scale * fc[2]}},
                      {"evaluator", "average"},
                      {"tier", atlas.manifest.value("tier", "")}}
                     .dump()
              << std::endl;
  }
  return 0;
}

void add_eval_average(CLI::App& eval, Commands& out) {
  struct Args {
    std::string atlas;
    int points = 256, views = 48, sphere = 24;
  };
  auto a = std::make_shared<Args>();
  auto* c = eval.add_subcommand(
      "average", "the repeat-averaged closures against the model averaged over the repeat "
                 "(relative L1 over the sphere, views off the table's nodes)");
  c->add_option("--atlas", a->atlas, "atlas directory")->required();
  c->add_option("--points", a->points, "points of the repeat averaged (a jittered lattice)")
      ->check(CLI::Range(1, 65536));
  c->add_option("--views", a->views, "view directions over both sides")
      ->check(CLI::Range(1, 1024));
  c->add_option("--sphere", a->sphere, "light directions: an n x 2n grid over the sphere")
      ->check(CLI::Range(4, 256));
  out.push_back({c, [a] {
    const Atlas atlas = load_atlas(a->atlas);
    const AverageError e = average_closures_error(atlas, a->points, a->views, a->sphere);
    std::cout << json{{"mean_relative_l1", e.l1_mean},
                      {"worst_relative_l1", e.l1_worst},
                      {"mean_energy_error", e.energy_mean},
                      {"per_texel_closures_mean_relative_l1", e.texel_closures_l1_mean},
                      {"views", e.views},
                      {"points", a->points},
                      {"tier", atlas.manifest.value("tier", "")},
                      {"fit", atlas.manifest.at("average")}}
                     .dump()
              << std::endl;
    return 0;
  }});
}

}  // namespace loom::cli
