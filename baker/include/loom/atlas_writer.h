// Writing an atlas (atlas.h): the bake's stages hand their maps and tables to one AtlasWriter,
// which writes each as a node file and a texture into a temporary sibling of the destination,
// records its manifest entry, and at the end hashes the files, writes the manifest and publishes
// the directory atomically (renamed into place, or exchanged with an older atlas).
#pragma once
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "loom/atlas.h"

namespace loom {

class AtlasWriter {
 public:
  /// Sweeps the temporaries of dead bakes of `dir` and creates this bake's temporary beside it.
  explicit AtlasWriter(const std::filesystem::path& dir);
  /// Removes the temporary unless it was published.
  ~AtlasWriter();
  AtlasWriter(const AtlasWriter&) = delete;
  AtlasWriter& operator=(const AtlasWriter&) = delete;

  /// Writes `img` as `<name>.exr` and `<name>.tx` (half or float, wrap mode `wrap`) and records
  /// its manifest entry: `entry` (channels, range, units, description, tiling, ...) with the file
  /// names, format and size added.
  void write(const Image& img, const std::string& name, bool half, const char* wrap,
             nlohmann::json entry);
  /// As write(), for a table of the ray-wave tier: the entry gets each channel's range of
  /// values, unitless channels and `tiling` (its wrap mode).
  void write_table(const Image& img, const std::string& name,
                   const std::vector<std::string>& channels, const std::string& description,
                   bool half = false, const char* tiling = "clamp");
  /// Copies a texture's two files and its entry from another valid atlas (a colour-only change).
  void copy(const std::filesystem::path& atlas, const nlohmann::json& manifest,
            const std::string& name);
  bool has(const std::string& name) const { return textures_.contains(name); }

  /// The textures' entries with their files' hashes, as the manifest holds them.
  nlohmann::json hashed_textures() const;
  /// The atlas as written so far, with `manifest` (its textures hashed_textures()), loaded as
  /// every reader loads it: for the stages that fit what the atlas renders (average_fit.h).
  Atlas load_written(const nlohmann::json& manifest) const;
  /// Writes manifest.json and publishes the temporary as the destination: renamed into place,
  /// or exchanged atomically with the older atlas there, which is then removed. If a valid atlas
  /// with `bake_key` appeared there meanwhile (a concurrent bake of the same spec) and `force`
  /// is off, it is kept and true is returned.
  bool publish(const nlohmann::json& manifest, const std::string& bake_key, bool force);

 private:
  std::filesystem::path dir_, tmp_;
  nlohmann::json textures_ = nlohmann::json::object();
  bool published_ = false;
};

/// What may be baked over: nothing, an empty directory or a Loom atlas (any schema version);
/// throws std::runtime_error naming `dir` for anything else (a user's folder, a file, a link).
void check_bake_destination(const std::filesystem::path& dir);

/// Bytes of the regular files in `dir`.
uint64_t atlas_dir_bytes(const std::filesystem::path& dir);

}  // namespace loom
