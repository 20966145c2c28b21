#include "loom/fiber_region.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>

#include "loom/atlas.h"
#include "loom/fiber_lookup.h"
#include "loom/publish_dir.h"
#include "loom/procedural_ply.h"
#include "loom/weave.h"
#include "loom/woven_patch.h"
#include "loom/yarn_curve.h"

namespace loom {
namespace {

namespace fs = std::filesystem;

uint64_t mix(uint64_t x) {  // SplitMix64
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// The global geometry of the unbounded fabric (woven_patch.h's, indexed from any yarn).
struct Fabric {
  FabricSpec spec;
  Weave w;
  double sx, sy;
  PlyParams warp, weft;
  explicit Fabric(const FabricSpec& s)
      : spec(s),
        w(make_weave(s.weave)),
        sx(woven_spacing(s).x),
        sy(woven_spacing(s).y),
        warp(ply_params_from_yarn(s.warp)),
        weft(ply_params_from_yarn(s.weft)) {}
  int period(bool is_warp) const { return is_warp ? w.cols() : w.rows(); }
  double step(bool is_warp) const { return is_warp ? sx : sy; }
  /// Vertex m of warp row / weft column `idx`.
  Vec3d vertex(bool is_warp, int64_t idx, int64_t m) const {
    return woven_vertex(spec, w, is_warp, idx, m);
  }
  YarnCurve curve(bool is_warp, int64_t idx, int64_t m0, int64_t m1) const {
    std::vector<Vec3d> pts;
    for (int64_t m = m0; m <= m1; ++m) pts.push_back(vertex(is_warp, idx, m));
    return YarnCurve(std::move(pts), {0, 0, 1});
  }
  /// Arc length of the unbounded yarn at its vertex m, from kRegionOrigin periods before m = 0.
  double global_z(bool is_warp, int64_t idx, int64_t m) const {
    const int P = period(is_warp);
    YarnCurve c = curve(is_warp, idx, -1, P + 1);  // pieces 1..P: interior tangents
    std::vector<double> prefix(size_t(P) + 1, 0.0);
    for (int i = 0; i < P; ++i)
      prefix[size_t(i) + 1] = prefix[size_t(i)] + c.z_at_vertex(i + 2) - c.z_at_vertex(i + 1);
    int64_t g = m + kRegionOrigin * P;  // >= 0 for regions within range
    return double(g / P) * prefix[size_t(P)] + prefix[size_t(g % P)];
  }
  /// The fibers' z step here: fiber_step, and at most a 16th of the crossing spacing, so that
  /// the curves, straight between vertices in the fabric, follow the yarn's bends.
  double region_step(bool is_warp) const {
    return std::min(fiber_step(is_warp ? warp : weft), step(is_warp) / 16);
  }
  uint32_t seed(bool is_warp, int64_t idx) const {
    return uint32_t(2 * (idx + kRegionOrigin) + (is_warp ? 0 : 1));
  }
};

struct RegionYarn {
  bool warp;
  int64_t idx, m0, m1;  ///< curve vertices m0..m1; fibers over pieces m0+1 .. m1-1
};

std::vector<RegionYarn> region_yarns(const Fabric& F, const FiberRegion& r) {
  std::vector<RegionYarn> out;
  for (bool warp : {true, false}) {
    const PlyParams& p = warp ? F.warp : F.weft;
    const double reach = yarn_reach(p);
    // Across: the yarn centres within reach of the region; along: the region plus reach.
    double a0 = warp ? r.y0 : r.x0, a1 = warp ? r.y1 : r.x1;
    double b0 = warp ? r.x0 : r.y0, b1 = warp ? r.x1 : r.y1;
    double sa = warp ? F.sy : F.sx, sb = F.step(warp);
    int64_t i0 = int64_t(std::floor((a0 - reach) / sa - 0.5)), i1 = int64_t(std::ceil((a1 + reach) / sa - 0.5));
    int64_t m0 = int64_t(std::floor((b0 - reach) / sb - 0.5)) - 1;
    int64_t m1 = int64_t(std::ceil((b1 + reach) / sb - 0.5)) + 1;
    for (int64_t i = i0; i <= i1; ++i) {
      double c = (double(i) + 0.5) * sa;
      if (c < a0 - reach || c > a1 + reach) continue;
      out.push_back({warp, i, m0, m1});
    }
  }
  return out;
}

void check_region(const Fabric& F, const FiberRegion& r) {
  const double lim_x = double(kRegionOrigin - 8) * F.sx, lim_y = double(kRegionOrigin - 8) * F.sy;
  auto bad = [](double a, double b, double lim) {
    return !(std::isfinite(a) && std::isfinite(b)) || !(a < b) || a < -lim || b > lim;
  };
  if (bad(r.x0, r.x1, lim_x))
    throw std::invalid_argument(fmt::format(
        "region: x0 < x1 must be finite and within [{:.6g}, {:.6g}] um (got {}, {})", -lim_x,
        lim_x, r.x0, r.x1));
  if (bad(r.y0, r.y1, lim_y))
    throw std::invalid_argument(fmt::format(
        "region: y0 < y1 must be finite and within [{:.6g}, {:.6g}] um (got {}, {})", -lim_y,
        lim_y, r.y0, r.y1));
}

}  // namespace

size_t FiberCurves::bytes() const {
  return points.size() * 4 + first.size() * 4 + radius.size() * 4 + hair.size() + yarn.size() * 4 +
         ply.size() * 2 + fiber.size() * 8 + first_k.size() * 8;
}

uint64_t estimate_region_vertices(const FabricSpec& s, const FiberRegion& r) {
  Fabric F(s);
  check_region(F, r);
  double total = 0;
  for (const auto& y : region_yarns(F, r)) {
    const PlyParams& p = y.warp ? F.warp : F.weft;
    const double dz = F.region_step(y.warp);
    // Arc length over the chord: at most 1.25 for these bends (h <= spacing / 2). The hairs'
    // count is their mean: the walk below enforces the budget exactly.
    double len = 1.25 * double(y.m1 - y.m0) * F.step(y.warp);
    double plies = std::max(p.plies, 1);
    total += plies * p.fibers * (len / dz + 2);
    if (p.hair_density > 0)
      total += plies * p.hair_density * (len + p.hair_length_max) *
               (0.5 * (p.hair_length_min + p.hair_length_max) / dz + 3);  // mean hair
  }
  return uint64_t(std::min(total, 1.8e19));
}

FiberCurves realize_fiber_region(const FabricSpec& s, const FiberRegion& r,
                                 uint64_t max_vertices) {
  Fabric F(s);
  check_region(F, r);
  const uint64_t est = estimate_region_vertices(s, r);
  if (est > max_vertices)
    throw std::invalid_argument(fmt::format(
        "max-vertices: the region needs about {} fiber vertices, more than the {} allowed; "
        "choose a smaller region or raise --max-vertices",
        est, max_vertices));
  FiberCurves out;
  out.first.push_back(0);
  auto push = [&](const YarnCurve& c, Vec3d yp) {
    Vec3d q = c.to_fabric(yp);
    out.points.insert(out.points.end(), {float(q.x), float(q.y), float(q.z)});
    if (out.vertices() > max_vertices)
      throw std::invalid_argument(fmt::format(
          "max-vertices: the region needs more than the {} fiber vertices allowed", max_vertices));
  };
  auto close_curve = [&](const PlyParams& p, bool hair, uint32_t seed, uint32_t ply, uint64_t id,
                         int64_t k0) {
    if (out.vertices() - out.first.back() < 2) {  // a lone vertex is no curve
      out.points.resize(size_t(out.first.back()) * 3);
      return;
    }
    out.first.push_back(uint32_t(out.vertices()));
    out.radius.push_back(float(p.fiber_radius));
    out.hair.push_back(hair ? 1 : 0);
    out.yarn.push_back(seed);
    out.ply.push_back(uint16_t(ply));
    out.fiber.push_back(id);
    out.first_k.push_back(k0);
  };
  for (const auto& y : region_yarns(F, r)) {
    const PlyParams& p = y.warp ? F.warp : F.weft;
    const uint32_t seed = F.seed(y.warp, y.idx);
    YarnCurve c = F.curve(y.warp, y.idx, y.m0, y.m1);
    c.set_z_at_vertex(1, F.global_z(y.warp, y.idx, y.m0 + 1));
    const double z_lo = c.z_at_vertex(1), z_hi = c.z_at_vertex(c.pieces() - 1);
    const double dz = F.region_step(y.warp);
    ++out.yarns;
    for (uint32_t ply = 0; ply < uint32_t(std::max(p.plies, 1)); ++ply) {
      int64_t k0 = int64_t(std::ceil(z_lo / dz)), k1 = int64_t(std::floor(z_hi / dz));
      for (uint32_t j = 0; j < uint32_t(p.fibers); ++j) {
        Fiber f = make_fiber(p, seed, ply, j);
        for (int64_t k = k0; k <= k1; ++k) {
          Vertex2f v = regular_vertex(p, seed, ply, j, f, k, dz);
          push(c, {v.x, v.y, double(k) * dz});
        }
        close_curve(p, false, seed, ply, j, k0);
      }
      if (p.hair_density <= 0) continue;
      // Hairs: blocks of kHairBlockUm along the yarn, each its own Poisson draw.
      int64_t b0 = int64_t(std::floor((z_lo - p.hair_length_max) / kHairBlockUm));
      int64_t b1 = int64_t(std::floor(z_hi / kHairBlockUm));
      for (int64_t b = b0; b <= b1; ++b) {
        std::mt19937_64 g(mix(mix(uint64_t(seed) << 20 | ply) ^ uint64_t(b)));
        auto rnd = [&] { return double(g() >> 11) * (1.0 / 9007199254740992.0); };
        uint32_t n = poisson_count(p.hair_density * kHairBlockUm, rnd);
        for (uint32_t j = 0; j < n; ++j) {
          Hair h = draw_hair(p, double(b) * kHairBlockUm, kHairBlockUm, rnd);
          if (h.z2 < z_lo || h.z1 > z_hi) continue;
          int64_t nv = hair_vertex_count(h, dz);
          for (int64_t m = 0; m < nv; ++m) {
            double z = hair_vertex_z(h, dz, m);
            if (z < z_lo || z > z_hi) continue;  // cut at the region's yarn ends
            Vertex2f v = hair_vertex(p, ply, h, z);
            push(c, {v.x, v.y, z});
          }
          close_curve(p, true, seed, ply, uint64_t(b) << 32 | j, 0);  // the block's global index
        }
      }
    }
  }
  return out;
}

void write_fiber_curves(const FiberCurves& c, const FabricSpec& s, const FiberRegion& r,
                        const fs::path& dir_in) {
  const fs::path dir = fs::absolute(dir_in).lexically_normal();
  fs::create_directories(dir.parent_path());
  std::random_device rd;
  fs::path tmp = dir.parent_path() /
                 fmt::format(".{}.tmp-{}-{:08x}", dir.filename().string(), getpid(), rd());
  fs::create_directory(tmp);
  try {
    auto write = [&](const char* name, const void* data, size_t bytes) {
      std::ofstream o(tmp / name, std::ios::binary);
      o.write(static_cast<const char*>(data), std::streamsize(bytes));
      o.close();  // the last write happens here: check after it
      if (!o) throw std::runtime_error(fmt::format("writing {} failed", name));
    };
    write("points.f32", c.points.data(), c.points.size() * 4);
    write("first.u32", c.first.data(), c.first.size() * 4);
    write("radius.f32", c.radius.data(), c.radius.size() * 4);
    write("hair.u8", c.hair.data(), c.hair.size());
    std::vector<uint8_t> warp(c.yarn.size());
    for (size_t i = 0; i < warp.size(); ++i) warp[i] = (c.yarn[i] & 1u) == 0 ? 1 : 0;
    write("warp.u8", warp.data(), warp.size());
    size_t hairs = 0;
    for (auto h : c.hair) hairs += h;
    nlohmann::json m{
        {"schema", "loom.fibers/1"},
        {"spec_sha256", sha256_string(canonical_spec(s).dump())},
        {"region_um", {r.x0, r.y0, r.x1, r.y1}},
        {"frame", "fabric plane: x along the warp, y along the weft, z the cloth normal; um"},
        {"yarns", c.yarns},
        {"curves", c.curves()},
        {"hair_curves", hairs},
        {"vertices", c.vertices()},
        {"files",
         {{"points", {{"file", "points.f32"}, {"type", "float32"}, {"shape", {c.vertices(), 3}}}},
          {"first", {{"file", "first.u32"}, {"type", "uint32"}, {"shape", {c.first.size()}}}},
          {"radius", {{"file", "radius.f32"}, {"type", "float32"}, {"shape", {c.curves()}}}},
          {"hair", {{"file", "hair.u8"}, {"type", "uint8"}, {"shape", {c.curves()}}}},
          {"warp", {{"file", "warp.u8"}, {"type", "uint8"}, {"shape", {c.curves()}}}}}},
        {"byte_order", "little"}};
    {
      std::ofstream o(tmp / "manifest.json");
      o << m.dump(2) << "\n";
      o.close();
      if (!o) throw std::runtime_error("writing manifest.json failed");
    }
    if (!publish_directory(tmp, dir)) {
      exchange_directories(tmp, dir);
      fs::remove_all(tmp);  // now holds the old curves
    }
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace loom
