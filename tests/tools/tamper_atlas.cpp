// loom_tamper_atlas: a copy of an atlas whose surface maps hold texels the baker never writes,
// re-hashed so that it still validates. For the tests of what the shaders do with such texels
// (osl/include/loom/texel_guard.h): node mode against the C++ evaluators on the same texels
// (tests/blender/test_parity.py), and renders that must stay finite.
//
//   loom_tamper_atlas SRC DST --mode range|nonfinite [--only MAP]
//
// `range`: finite values outside the baker's ranges (albedos above 1 and below 0, gap coverage
// and yarn kind out of range, h beyond +-1, horizon sines beyond +-1, zero and degenerate ply
// frames, a normal below the cloth, a vertical tangent, fitted closure factors below 0 and above
// their maximum). `nonfinite`: NaN and +-Inf in
// the same channels. Every fifth texel of each map is changed (a fixed pattern: the result is
// deterministic), cycling through the map's variants below; the other texels keep their values.
// Only maps the atlas has are changed; --only changes that one map alone (to find which map a
// difference comes from). DST must not exist. Exit status 0; 1 with a message (and no DST) when
// the copy fails; CLI11's for bad arguments.
#include <fmt/format.h>

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "loom/atlas.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();
// A channel left as the baker wrote it.
constexpr float kKeep = -12345.0f;

using Variants = std::vector<std::vector<float>>;  // per variant: one value per channel

/// The finite out-of-range texels, per map (channels as in the manifest; ply_maps.h).
std::map<std::string, Variants> range_variants() {
  return {
      // t.xyz, height: zero tangent; vertical tangent (along the cloth normal: no glossy normal);
      // a long tangent (only normalised); height far out of range (read by neither shader's
      // math today, guarded all the same).
      {"ply_frame", {{0, 0, 0, kKeep}, {0, 0, 3.5f, kKeep}, {3.0f, 0.5f, 0.2f, 9000.0f}}},
      // n.xyz, h: zero normal; normal below the cloth; h beyond both ends.
      {"ply_normal", {{0, 0, 0, 3.0f}, {0.2f, 0.1f, -0.9f, -4.0f}, {kKeep, kKeep, kKeep, 2.5f}}},
      // kind, along, ply_id, gap
      {"yarn_info", {{5.0f, 3.0f, -2.0f, 1.6f}, {-1.0f, -0.5f, 4.0f, -0.7f}}},
      // k_rd.rgb, k_rs
      {"albedo_reflect", {{1.8f, -0.4f, 0.5f, 2.5f}, {-0.3f, 3.0f, 1.2f, -0.6f}}},
      // k_td.rgb, k_ts
      {"albedo_transmit", {{-1.0f, 3.0f, 0.2f, -0.7f}, {2.0f, -0.2f, 1.5f, 1.9f}}},
      // roughness, optical thickness, blend, ior (roughness only above the range: a lobe far
      // sharper than any the baker writes makes the renders' comparison a matter of luck)
      {"spec_params", {{4.0f, -5.0f, 1.7f, 0.2f}, {kKeep, 2e4f, -2.0f, 7.0f}}},
      // horizon sines
      {"horizon_0", {{3.0f, -4.0f, 1.5f, -1.5f}}},
      {"horizon_1", {{-2.0f, 2.0f, kKeep, 6.0f}}},
      // The fitted closures' factors (0 to LOOM_FITTED_MAX_WEIGHT) and the horizon strip's sines.
      {"fitted_closures", {{-3.0f, 80.0f, 1e4f, -0.5f}, {60.0f, -1.0f, kKeep, 55.0f}}},
      {"horizon_strip", {{3.0f, -4.0f, kKeep, kKeep}, {-2.0f, 2.0f, kKeep, kKeep}}},
  };
}

/// NaN and infinities in the same maps.
std::map<std::string, Variants> nonfinite_variants() {
  return {
      {"ply_frame", {{kNaN, 0, 0, kNaN}, {kInf, 0, 0, kInf}}},
      {"ply_normal", {{kNaN, kNaN, kNaN, kNaN}, {0, 0, -kInf, kInf}}},
      {"yarn_info", {{kNaN, kNaN, kNaN, kNaN}, {kInf, -kInf, kInf, -kInf}}},
      {"albedo_reflect", {{kNaN, kInf, -kInf, kNaN}, {kInf, kNaN, 0.5f, kInf}}},
      {"albedo_transmit", {{kInf, kNaN, -kInf, kInf}, {kNaN, 0.2f, kNaN, kNaN}}},
      {"spec_params", {{kNaN, kNaN, kNaN, kNaN}, {kInf, kInf, -kInf, kInf}}},
      {"horizon_0", {{kNaN, kInf, -kInf, kNaN}}},
      {"horizon_1", {{kInf, kNaN, kNaN, -kInf}}},
      {"fitted_closures", {{kNaN, kInf, -kInf, kNaN}, {kInf, kNaN, 0.5f, kInf}}},
      {"horizon_strip", {{kNaN, kInf, kKeep, kKeep}, {-kInf, kNaN, kKeep, kKeep}}},
  };
}

int run(const fs::path& src, const fs::path& dst, const std::string& mode, const std::string& only,
        bool& created) {
  if (fs::exists(dst)) throw std::runtime_error(dst.string() + " exists");
  if (!loom::validate_atlas(src).empty())
    throw std::runtime_error(src.string() + " is not a valid atlas (loom-bake validate)");
  const json src_manifest = json::parse(std::ifstream(src / "manifest.json"));
  if (dst.has_parent_path()) fs::create_directories(dst.parent_path());
  created = true;
  fs::copy(src, dst, fs::copy_options::recursive);
  json m = src_manifest;
  const auto variants = mode == "range" ? range_variants() : nonfinite_variants();
  int changed_maps = 0;
  for (const auto& [name, vars] : variants) {
    if (!m["textures"].contains(name) || (!only.empty() && name != only)) continue;
    json& t = m["textures"][name];
    loom::Image img = loom::read_atlas_image(dst / t["node_file"].get<std::string>());
    size_t k = 0;
    for (int iy = 0; iy < img.height; ++iy)
      for (int ix = 0; ix < img.width; ++ix) {
        if ((ix * 7 + iy * 3) % 5 != 0) continue;
        const std::vector<float>& v = vars[k++ % vars.size()];
        float* p = img.px(ix, iy);
        for (int c = 0; c < img.channels && c < int(v.size()); ++c)
          if (v[size_t(c)] != kKeep) p[c] = v[size_t(c)];
      }
    const std::string wrap = t.value("tiling", "periodic");
    loom::write_atlas_map(img, dst, name, t.value("format", "half") == "half", wrap.c_str());
    t["sha256"] = loom::sha256_file(dst / t["file"].get<std::string>());
    t["node_sha256"] = loom::sha256_file(dst / t["node_file"].get<std::string>());
    ++changed_maps;
  }
  if (changed_maps == 0)
    throw std::runtime_error(src.string() + " has none of the maps to change" +
                             (only.empty() ? "" : " (" + only + ")"));
  std::ofstream(dst / "manifest.json", std::ios::trunc) << m.dump(1);
  if (auto errors = loom::validate_atlas(dst); !errors.empty())
    throw std::runtime_error("the tampered atlas does not validate: " + errors.front());
  fmt::print("{}: {} maps changed ({})\n", dst.string(), changed_maps, mode);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"A re-hashed copy of an atlas holding texels the baker never writes"};
  std::string src, dst, mode, only;
  app.add_option("SRC", src, "the atlas to copy")->required()->check(CLI::ExistingDirectory);
  app.add_option("DST", dst, "the tampered copy (must not exist)")->required();
  app.add_option("--mode", mode, "range (finite, out of range) or nonfinite (NaN, +-Inf)")
      ->required()
      ->check(CLI::IsMember({"range", "nonfinite"}));
  app.add_option("--only", only, "change this map alone");
  CLI11_PARSE(app, argc, argv);
  bool created = false;
  try {
    return run(src, dst, mode, only, created);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "loom_tamper_atlas: %s\n", e.what());
    std::error_code ec;
    if (created) fs::remove_all(dst, ec);  // nothing half-written
    return 1;
  }
}
