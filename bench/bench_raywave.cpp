// Google Benchmark: the ray-wave baker's ply scattering simulation (rays per second, one thread
// per slice, as the bake runs it), the ASG block fit per quality preset, and the ray-wave BSDF at
// a shading point: the set-up per view (what a shader does once per shading point: look-ups and
// closure parameters) and one evaluation, model against closure mixture.
#include <benchmark/benchmark.h>
#include <tbb/task_arena.h>

#include <filesystem>
#include <random>

#include "loom/asg_fit.h"
#include "loom/atlas.h"
#include "loom/bake.h"
#include "loom/ply_scattering.h"
#include "loom/raywave_bsdf.h"

namespace {

loom::PlyParams default_ply() { return loom::ply_params_from_yarn(loom::YarnSpec{}); }

void BM_PlySimSlice(benchmark::State& st) {
  auto p = default_ply();
  loom::PlyGeometry g(p, loom::make_ply_fibers(p, 0, 0));
  auto s = loom::ply_sim_settings(loom::Quality::Preview);
  s.rays_per_slice = 20000;
  const double theta = st.range(0) * M_PI / 180;
  uint64_t rays = 0;
  for (auto _ : st) {
    benchmark::DoNotOptimize(loom::simulate_ply_slice(g, 1.55, s, theta, 0.0, 1));
    rays += uint64_t(s.rays_per_slice);
  }
  st.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
  st.SetLabel("theta_i " + std::to_string(st.range(0)) + " deg, one thread");
}
BENCHMARK(BM_PlySimSlice)->Arg(0)->Arg(45)->Arg(80)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PlySimAll(benchmark::State& st) {
  auto p = default_ply();
  auto s = loom::ply_sim_settings(loom::Quality(st.range(0)));
  uint64_t rays = 0;
  for (auto _ : st) {
    auto r = loom::simulate_ply_scattering(p, 1.55, s);
    rays += r.rays;
  }
  st.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
  st.SetLabel(loom::to_string(loom::Quality(st.range(0))));
}
BENCHMARK(BM_PlySimAll)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

void BM_AsgFit(benchmark::State& st) {
  auto q = loom::Quality(st.range(0));
  auto sim = loom::simulate_ply_scattering(default_ply(), 1.55, loom::ply_sim_settings(q));
  double nrmse = 0;
  for (auto _ : st) {
    auto t = loom::asg_fit_high(sim, loom::asg_fit_settings(q, false));
    nrmse = t.nrmse;
  }
  st.counters["nrmse"] = nrmse;
  st.SetLabel(std::string(loom::to_string(q)) + ", L = " +
              std::to_string(loom::asg_fit_settings(q, false).lobes));
}
BENCHMARK(BM_AsgFit)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

/// Fit error against the lobe count L on one simulation (the preview preset's grids).
void BM_AsgFitLobes(benchmark::State& st) {
  static const loom::PlySimResult sim = loom::simulate_ply_scattering(
      default_ply(), 1.55, loom::ply_sim_settings(loom::Quality::Preview));
  auto s = loom::asg_fit_settings(loom::Quality::Preview, false);
  s.lobes = int(st.range(0));
  double nrmse = 0;
  for (auto _ : st) nrmse = loom::asg_fit_high(sim, s).nrmse;
  st.counters["nrmse"] = nrmse;
  st.SetLabel("L = " + std::to_string(s.lobes));
}
BENCHMARK(BM_AsgFitLobes)->DenseRange(1, 6)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

/// A ray-wave atlas of the default fabric at `preview` quality, baked once.
struct RaywaveFixture {
  loom::Atlas atlas;
  loom::RaywaveData data;
  std::vector<loom::SurfacePoint> points;
  std::vector<loom::shading::vec3> dirs;
};
const RaywaveFixture& raywave_fixture() {
  static RaywaveFixture f = [] {
    auto r = loom::parse_spec(loom::preset("default"), "preview");
    r.spec.tier = loom::Tier::Raywave;
    auto dir = std::filesystem::temp_directory_path() / "loom_bench_raywave.atlas";
    loom::bake_atlas(r.spec, dir, {});
    RaywaveFixture x{loom::load_atlas(dir), {}, {}, {}};
    x.data = loom::load_raywave(x.atlas);
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> U(-1, 1);
    for (int k = 0; k < 1024; ++k) {
      x.points.push_back(loom::sample_surface(x.atlas, U(rng), U(rng)));
      x.dirs.push_back(loom::shading::normalize(loom::shading::vec3(U(rng), U(rng), U(rng))));
    }
    return x;
  }();
  return f;
}

void BM_RaywaveSetup(benchmark::State& st) {
  const auto& f = raywave_fixture();
  auto ev = st.range(0) ? loom::Evaluator::Closures : loom::Evaluator::Model;
  size_t k = 0;
  for (auto _ : st) {
    benchmark::DoNotOptimize(loom::RaywavePoint(f.data, f.points[k & 1023], f.dirs[k & 1023], ev));
    ++k;
  }
  st.SetLabel(st.range(0) ? "closures" : "model");
}
BENCHMARK(BM_RaywaveSetup)->Arg(0)->Arg(1);

void BM_RaywaveEval(benchmark::State& st) {
  const auto& f = raywave_fixture();
  auto ev = st.range(0) ? loom::Evaluator::Closures : loom::Evaluator::Model;
  std::vector<loom::RaywavePoint> pts;
  for (int k = 0; k < 64; ++k) pts.emplace_back(f.data, f.points[size_t(k)], f.dirs[size_t(k)], ev);
  size_t k = 0;
  for (auto _ : st) {
    benchmark::DoNotOptimize(pts[k & 63].eval(f.dirs[(k * 7 + 3) & 1023]));
    ++k;
  }
  st.SetLabel(st.range(0) ? "closures" : "model");
}
BENCHMARK(BM_RaywaveEval)->Arg(0)->Arg(1);

}  // namespace
