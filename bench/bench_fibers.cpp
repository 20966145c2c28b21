// Google Benchmark: the fiber tier's look-ups (Luan et al. 2017, section 4) on woven patches of
// growing size, realization-minimising against full realization: time per look-up of the same
// seeded points, and the bytes each stores (counters). The whole-process memory curve up to
// 2,000 yarns is bench/fiber_scaling.sh.
#include <benchmark/benchmark.h>

#include "loom/fiber_lookup.h"
#include "loom/spec.h"
#include "loom/woven_patch.h"

namespace {

constexpr int kPoints = 4096;

template <class Lookup>
void run(benchmark::State& st) {
  auto spec = loom::load_spec("plain").spec;
  auto patch = loom::make_woven_patch(spec, int(st.range(0)));
  Lookup l(patch);
  auto pts = loom::fiber_test_points(patch, kPoints, 7);
  size_t i = 0, covered = 0;
  for (auto _ : st) {
    auto h = l.lookup(pts[i]);
    covered += h.covered;
    benchmark::DoNotOptimize(h);
    if (++i == pts.size()) i = 0;
  }
  st.counters["bytes"] = double(l.bytes());
  st.counters["lookups_per_s"] = benchmark::Counter(double(st.iterations()), benchmark::Counter::kIsRate);
  st.SetLabel(std::to_string(st.range(0)) + " yarns, plain preset");
}

void BM_FiberLookupMinimising(benchmark::State& st) { run<loom::FiberLookup>(st); }
void BM_FiberLookupRealized(benchmark::State& st) { run<loom::RealizedFibers>(st); }
BENCHMARK(BM_FiberLookupMinimising)->Arg(10)->Arg(50)->Arg(200)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FiberLookupRealized)->Arg(10)->Arg(50)->Arg(200)->Unit(benchmark::kMicrosecond);

}  // namespace
