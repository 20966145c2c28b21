// The bake: a validated spec into an atlas (atlas.h), published atomically.
#pragma once
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "loom/atlas.h"
#include "loom/spec.h"

namespace loom {

struct BakeOptions {
  std::string ocio_config;  ///< path of an OCIO config (Blender's); empty: Loom's built-in one
  ProgressFn progress;
  bool force = false;  ///< re-bake even if a valid atlas of the same spec is at the destination
  /// Ray-wave atlases whose colour-independent tables may be reused (see raywave_simulation_key);
  /// besides these, the destination and its sibling directories are looked at.
  std::vector<std::filesystem::path> reuse_from;
};

struct BakeResult {
  std::filesystem::path dir;
  bool reused = false;  ///< the destination already held a valid atlas of this spec
  double seconds = 0;
  uint64_t bytes = 0;
  /// A ray-wave bake that copied its ply tables, double-layer, diffraction and noise tables
  /// and absorption curves from another atlas (a colour-only change): that atlas. Else empty.
  std::filesystem::path reused_simulation;
};

/// What a ray-wave atlas's colour-independent tables depend on: the canonical spec without its
/// name and yarn colours, the colour conversion (diffraction's RGB integration uses it) and the
/// baker binary. Atlases with equal keys hold identical tables.
std::string raywave_simulation_key(nlohmann::json canonical_spec, const std::string& colour,
                                   const std::string& baker_id);

/// Bakes a validated spec into `dir`. Throws std::runtime_error with a clear message on failure;
/// on failure nothing is left at `dir` that was not there before.
BakeResult bake_atlas(FabricSpec spec, const std::filesystem::path& dir, const BakeOptions& opt);

}  // namespace loom
