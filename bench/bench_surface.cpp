// Google Benchmark: the surface tier's bake stages per quality preset, and BSDF evaluation cost
// of the model against the closure mixture (what a shading point pays in each evaluator).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "loom/closure_lut.h"
#include "loom/atlas.h"
#include "loom/bake.h"
#include "loom/evaluator.h"

namespace {

loom::FabricSpec spec_at(int q) {
  auto r = loom::parse_spec(loom::preset("default"));
  r.spec.quality = loom::Quality(q);
  for (auto* y : {&r.spec.warp, &r.spec.weft}) y->color_linear = {0.4, 0.1, 0.1};
  return r.spec;
}

void BM_PlyMaps(benchmark::State& st) {
  auto spec = spec_at(int(st.range(0)));
  for (auto _ : st) benchmark::DoNotOptimize(loom::bake_surface_maps(spec));
  st.SetLabel(loom::to_string(spec.quality));
}
BENCHMARK(BM_PlyMaps)->DenseRange(0, 3)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ClosureLut(benchmark::State& st) {
  auto spec = spec_at(int(st.range(0)));
  for (auto _ : st) benchmark::DoNotOptimize(loom::bake_closure_lut(spec));
  st.SetLabel(loom::to_string(spec.quality));
}
BENCHMARK(BM_ClosureLut)->DenseRange(0, 3)->Unit(benchmark::kMillisecond)->UseRealTime();

const loom::Atlas& atlas() {
  static loom::Atlas a = [] {
    auto dir = std::filesystem::temp_directory_path() / "loom_bench_default.atlas";
    loom::bake_atlas(spec_at(1), dir, {});
    return loom::load_atlas(dir);
  }();
  return a;
}

void BM_Eval(benchmark::State& st) {
  const auto& a = atlas();
  auto ev = st.range(0) ? loom::Evaluator::Closures : loom::Evaluator::Model;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> U(-1, 1);
  std::vector<loom::SurfacePoint> pts;
  std::vector<loom::shading::vec3> dirs;
  for (int k = 0; k < 1024; ++k) {
    pts.push_back(loom::sample_surface(a, U(rng), U(rng)));
    dirs.push_back(loom::shading::normalize(loom::shading::vec3(U(rng), U(rng), U(rng))));
  }
  size_t k = 0;
  for (auto _ : st) {
    auto& p = pts[k & 1023];
    benchmark::DoNotOptimize(loom::eval_bsdf(a, p, dirs[k & 1023], dirs[(k * 7 + 3) & 1023], ev));
    ++k;
  }
  st.SetLabel(st.range(0) ? "closures" : "model");
}
BENCHMARK(BM_Eval)->Arg(0)->Arg(1);

}  // namespace

BENCHMARK_MAIN();
