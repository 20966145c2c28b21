// Fibers realized for a region of the fabric (fiber_region.h): regions that overlap give the same
// fibers, budgets hold, bad regions are refused, and the curves are written whole or not at all.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <tuple>

#include "loom/fiber_lookup.h"
#include "loom/fiber_region.h"
#include "loom/spec.h"
#include "test_util.h"

namespace {

loom::FabricSpec hairy_spec() {
  auto r = loom::parse_spec_text(R"({"schema": "loom.fabric/1", "weave": {"pattern": "twill"},
    "yarn": {"plies": 3, "fibers_per_ply": 20, "yarn_diameter_um": 320, "ply_diameter_um": 160,
             "fiber_diameter_um": 14, "loop_flyaways_per_mm": 4, "hair_flyaways_per_mm": 6},
    "density": {"warp_per_cm": 30, "weft_per_cm": 26}})");
  EXPECT_TRUE(r.ok());
  return r.spec;
}

using Key = std::tuple<uint32_t, uint16_t, uint64_t, uint8_t>;

std::map<Key, size_t> index_curves(const loom::FiberCurves& c) {
  std::map<Key, size_t> m;
  for (size_t i = 0; i < c.curves(); ++i) m[{c.yarn[i], c.ply[i], c.fiber[i], c.hair[i]}] = i;
  return m;
}

}  // namespace

TEST(FiberRegion, OverlappingRegionsGiveTheSameFibers) {
  auto s = hairy_spec();
  auto a = loom::realize_fiber_region(s, {0, 0, 1500, 1500});
  auto b = loom::realize_fiber_region(s, {700, 400, 2600, 2100});
  auto ia = index_curves(a), ib = index_curves(b);
  size_t compared = 0, hairs = 0;
  double worst = 0;
  for (auto& [key, i] : ia) {
    auto it = ib.find(key);
    if (it == ib.end()) continue;
    size_t j = it->second;
    size_t na = a.first[i + 1] - a.first[i], nb = b.first[j + 1] - b.first[j];
    if (std::get<3>(key)) {  // hairs: compare those whole in both
      if (na != nb) continue;
      for (size_t v = 0; v < na; ++v)
        for (int d = 0; d < 3; ++d)
          worst = std::max(worst, double(std::abs(a.points[3 * (a.first[i] + v) + d] -
                                                  b.points[3 * (b.first[j] + v) + d])));
      ++hairs;
      continue;
    }
    // Regular fibers: vertices with the same grid index k.
    int64_t k0 = std::max(a.first_k[i], b.first_k[j]);
    int64_t k1 = std::min(a.first_k[i] + int64_t(na), b.first_k[j] + int64_t(nb)) - 1;
    for (int64_t k = k0; k <= k1; ++k) {
      size_t va = a.first[i] + size_t(k - a.first_k[i]), vb = b.first[j] + size_t(k - b.first_k[j]);
      for (int d = 0; d < 3; ++d)
        worst = std::max(worst, double(std::abs(a.points[3 * va + d] - b.points[3 * vb + d])));
      ++compared;
    }
  }
  EXPECT_GT(compared, 10000u);
  EXPECT_GT(hairs, 10u);
  EXPECT_LT(worst, 1e-3);  // um: float rounding of coordinates of a few thousand um
}

TEST(FiberRegion, CurvesStayInTheirYarnsAndTheRegion) {
  auto s = hairy_spec();
  loom::FiberRegion r{-400, 250, 900, 1300};
  auto c = loom::realize_fiber_region(s, r);
  ASSERT_GT(c.curves(), 100u);
  const double reach = loom::yarn_reach(loom::ply_params_from_yarn(s.warp));
  const double h = 0.125 * (s.warp.yarn_diameter_um + s.weft.yarn_diameter_um);
  const double pad = reach + 2 * 1e4 / std::min(s.warp_per_cm, s.weft_per_cm);
  for (size_t v = 0; v < c.vertices(); ++v) {
    float x = c.points[3 * v], y = c.points[3 * v + 1], z = c.points[3 * v + 2];
    ASSERT_TRUE(std::isfinite(x) && std::isfinite(y) && std::isfinite(z));
    EXPECT_LE(std::abs(z), h + reach);
    EXPECT_GE(x, r.x0 - pad);
    EXPECT_LE(x, r.x1 + pad);
    EXPECT_GE(y, r.y0 - pad);
    EXPECT_LE(y, r.y1 + pad);
  }
  // Hairs and regular fibers both present; curve ranges consistent.
  size_t hair = 0;
  for (size_t i = 0; i < c.curves(); ++i) {
    hair += c.hair[i];
    EXPECT_GE(c.first[i + 1] - c.first[i], 2u);
  }
  EXPECT_GT(hair, 10u);
  EXPECT_LT(hair, c.curves());
  EXPECT_EQ(c.first.back(), c.vertices());
}

TEST(FiberRegion, BudgetsAndBadRegionsAreRefused) {
  auto s = hairy_spec();
  loom::FiberRegion r{0, 0, 1000, 1000};
  auto c = loom::realize_fiber_region(s, r);
  uint64_t est = loom::estimate_region_vertices(s, r);
  EXPECT_GE(est, c.vertices());  // an upper bound...
  EXPECT_LE(est, 2 * c.vertices());  // ...and not a loose one
  try {
    loom::realize_fiber_region(s, r, c.vertices() / 2);
    ADD_FAILURE() << "no error over the budget";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max-vertices"), std::string::npos);
  }
  const double nan = std::nan("");
  for (loom::FiberRegion bad : {loom::FiberRegion{0, 0, 0, 100}, loom::FiberRegion{0, 0, 100, -5},
                                loom::FiberRegion{nan, 0, 100, 100},
                                loom::FiberRegion{0, 0, 1e12, 100}}) {
    try {
      loom::realize_fiber_region(s, bad);
      ADD_FAILURE() << "no error for a bad region";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind("region:", 0), 0u) << e.what();
    }
  }
}

TEST(FiberRegion, WrittenWholeOrNotAtAll) {
  namespace fs = std::filesystem;
  auto s = hairy_spec();
  loom::FiberRegion r{0, 0, 600, 600};
  auto c = loom::realize_fiber_region(s, r);
  fs::path dir = loom::test::scratch("fiber_region/out");
  loom::write_fiber_curves(c, s, r, dir);
  auto m = nlohmann::json::parse(std::ifstream(dir / "manifest.json"));
  EXPECT_EQ(m["schema"], "loom.fibers/1");
  EXPECT_EQ(m["vertices"].get<size_t>(), c.vertices());
  EXPECT_EQ(fs::file_size(dir / "points.f32"), c.vertices() * 12);
  EXPECT_EQ(fs::file_size(dir / "first.u32"), (c.curves() + 1) * 4);
  // Re-written in place with another region: replaced whole.
  auto c2 = loom::realize_fiber_region(s, {0, 0, 300, 300});
  loom::write_fiber_curves(c2, s, {0, 0, 300, 300}, dir);
  EXPECT_EQ(fs::file_size(dir / "points.f32"), c2.vertices() * 12);
  for (auto& e : fs::directory_iterator(dir.parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".out.tmp-"), std::string::npos);
  // The command: a bad region exits 2, names the field, writes nothing.
  fs::path bad = loom::test::scratch("fiber_region/bad");
  std::string out;
  int rc = loom::test::run(loom::test::bake_exe() + " fibers --spec plain --region 0,0,-1,5 --out " +
                               bad.string() + " 2>&1",
                           &out);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("--region"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(bad));
  rc = loom::test::run(loom::test::bake_exe() + " fibers --spec plain --region 0,0,600,600 --out " +
                           bad.string() + " --max-vertices 1000 2>&1",
                       &out);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("--max-vertices"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(bad));
}
