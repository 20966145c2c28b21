#include "loom/woven_patch.h"

#include <fmt/format.h>

#include <stdexcept>

#include "loom/weave.h"

namespace loom {

WovenSpacing woven_spacing(const FabricSpec& s) {
  return {1e4 / s.weft_per_cm, 1e4 / s.warp_per_cm};  // yarns per cm -> um between yarns
}

Vec3d woven_vertex(const FabricSpec& s, const Weave& w, bool warp, int64_t index, int64_t m) {
  const auto [sx, sy] = woven_spacing(s);
  const double h = 0.125 * (s.warp.yarn_diameter_um + s.weft.yarn_diameter_um);
  const int64_t r = warp ? index : m, c = warp ? m : index;
  const bool over = w.at(int(r % w.rows()), int(c % w.cols())) != 0;  // warp on top
  if (warp) return {(double(m) + 0.5) * sx, (double(index) + 0.5) * sy, over ? h : -h};
  return {(double(index) + 0.5) * sx, (double(m) + 0.5) * sy, over ? -h : h};
}

std::vector<PatchYarn> make_woven_patch(const FabricSpec& s, int yarns) {
  if (yarns < 2 || yarns > kMaxPatchYarns)
    throw std::invalid_argument(
        fmt::format("yarns: {} is out of range, allowed [2, {}]", yarns, kMaxPatchYarns));
  const Weave w = make_weave(s.weave);
  const int n_warp = (yarns + 1) / 2, n_weft = yarns - n_warp;
  std::vector<PatchYarn> out;
  out.reserve(size_t(yarns));
  for (int r = 0; r < n_warp; ++r) {
    std::vector<Vec3d> pts;
    for (int c = -1; c <= std::max(n_weft, 1); ++c) pts.push_back(woven_vertex(s, w, true, r, c));
    out.push_back({YarnCurve(std::move(pts), {0, 0, 1}), ply_params_from_yarn(s.warp), true,
                   uint32_t(out.size())});
  }
  for (int c = 0; c < n_weft; ++c) {
    std::vector<Vec3d> pts;
    for (int r = -1; r <= std::max(n_warp, 1); ++r) pts.push_back(woven_vertex(s, w, false, c, r));
    out.push_back({YarnCurve(std::move(pts), {0, 0, 1}), ply_params_from_yarn(s.weft), false,
                   uint32_t(out.size())});
  }
  return out;
}

}  // namespace loom
