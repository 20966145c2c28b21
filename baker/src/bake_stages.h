// The stages of a bake (bake.cpp runs them in order): each takes what it needs from the
// BakeContext and the stages before it, hands the maps and tables it makes to the AtlasWriter,
// and returns its part of the manifest. Internal to the baker.
#pragma once
#include <array>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>

#include "loom/atlas_writer.h"
#include "loom/spec.h"
#include "loom/colour.h"
#include "loom/ply_maps.h"

namespace loom {

struct BakeContext {
  const FabricSpec& spec;
  const nlohmann::json& canonical_spec;
  const ColourConverter& cc;
  const ProgressFn& progress_fn;  ///< BakeOptions::progress (may be empty)
  AtlasWriter& out;
  /// A colour-only change of a ray-wave spec: a valid atlas (directory, manifest) with the same
  /// simulation key, whose colour-independent tables are copied rather than computed.
  std::optional<std::pair<std::filesystem::path, nlohmann::json>> source;

  void progress(const std::string& stage, double fraction) const {
    if (progress_fn) progress_fn(stage, fraction);
  }
};

/// Geometry maps, horizons and the closure LUT (the surface tier; every atlas has them).
/// Returns the repeat's size and yarn counts for the manifest.
nlohmann::json bake_surface_stage(const BakeContext& ctx);

/// Everything of the ray-wave tier (the manifest's "raywave" section): ply tables, double layer,
/// diffraction, noise, colour from absorption and the render tables (bake_raywave.cpp).
nlohmann::json bake_raywave_stages(const BakeContext& ctx, const std::string& simulation_key);

/// Aperture diffraction (section 4) through the gaps and past the ply edges: the manifest's
/// raywave.diffraction (bake_wave.cpp).
nlohmann::json bake_diffraction_stage(const BakeContext& ctx);
/// Speckle noise tiles (section 5): the manifest's raywave.noise (bake_wave.cpp).
nlohmann::json bake_noise_stage(const BakeContext& ctx);

}  // namespace loom
