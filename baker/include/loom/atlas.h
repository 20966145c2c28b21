// The atlas: the contract between the baker and every evaluator (OSL, node mode, C++).
//
// A directory holding `manifest.json` (schema "loom.atlas/1") and, per map, a tiled mip-mapped
// OpenImageIO texture `<name>.tx` (read by OSL's texture()) and a plain half-float OpenEXR
// `<name>.exr` with identical texels (read by Blender image nodes in node mode and by the C++
// evaluator). Row 0 of every file is the top (v = 1); maps tile over one weave repeat.
// Publication is atomic: the atlas is written to a temporary sibling and renamed into place.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "loom/ply_maps.h"
#include "loom/spec.h"

namespace loom {

inline constexpr const char* kAtlasSchema = "loom.atlas/1";
inline constexpr const char* kBakerVersion = "0.1.0";

struct ColourConversion;

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

/// Validation of an atlas directory: schema, files, hashes, sizes, paths. Empty = valid.
std::vector<std::string> validate_atlas(const std::filesystem::path& dir,
                                        nlohmann::json* manifest_out = nullptr);

std::string sha256_file(const std::filesystem::path& p);
std::string sha256_string(const std::string& s);

/// An atlas loaded into memory for the C++ evaluators.
struct Atlas {
  nlohmann::json manifest;
  std::vector<std::string> names;  ///< map names, same order as images
  std::vector<Image> images;       ///< rows bottom-up (flipped back from the files)
  Image albedo_lut;
  const Image& map(const std::string& name) const;
};

/// Loads (after validating) an atlas; throws std::runtime_error listing the problems.
Atlas load_atlas(const std::filesystem::path& dir);

}  // namespace loom
