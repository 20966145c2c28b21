// The atlas: the contract between the baker and every evaluator (OSL, node mode, C++).
//
// A directory holding `manifest.json` (schema "loom.atlas/1") and, per map, a tiled mip-mapped
// OpenImageIO texture `<name>.tx` (read by OSL's texture()) and a plain half-float OpenEXR
// `<name>.exr` with identical texels (read by Blender image nodes in node mode and by the C++
// evaluator). Row 0 of every file is the top (v = 1); maps tile over one weave repeat.
// Publication is atomic: the atlas is written to a temporary sibling and renamed into place.
#pragma once
#include <array>
#include <cstdint>
#include <stdexcept>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "loom/atlas_files.h"
#include "loom/ply_maps.h"

namespace loom {

inline constexpr const char* kAtlasSchema = "loom.atlas/1";
inline constexpr const char* kBakerVersion = "0.1.0";

/// Validation of an atlas directory: schema, files, hashes, sizes, paths. Empty = valid; else one
/// message per problem, naming the manifest field (e.g. "textures.ply_frame.node_file") or file.
///
/// The contract with every reader of the manifest (load_atlas, load_ply_tables, load_raywave and
/// the ray-wave shading tables): a manifest that validates holds every field they read with the
/// type they read it as, and integers within ranges that keep their arithmetic in range, so that
/// they never meet a wrong type (no nlohmann::json exception escapes them) and may index without
/// looking; they check the values' meaning themselves and throw std::runtime_error naming the
/// field. The manifest is not hashed (its textures are), so this is what stands between an edited
/// or foreign manifest and the readers (tests/fuzz/fuzz_manifest.cpp).
///
/// Paths, the choices: every file an atlas names (textures.*.file and textures.*.node_file, the
/// only fields that name files; the raywave section names textures, by their keys) must be a
/// plain file name in the atlas directory: no '/', '\\', "." or "..", so no absolute path either.
/// The files and manifest.json must be regular files, never symbolic links, neither to a file
/// outside the directory (which would read any file the user can) nor to one inside (the baker
/// never writes one, and refusing all links needs no resolution of paths). Each file is read
/// once (read_atlas_file, which refuses a link at the open itself); the hash and the header are
/// checked on those bytes, and load_atlas decodes the same bytes, so nothing swapped in after a
/// check is ever read. The atlas directory itself may be reached through a link.
/// The textures' formats: .exr files are read as OpenEXR only and .tx files as TIFF only.
std::vector<std::string> validate_atlas(const std::filesystem::path& dir,
                                        nlohmann::json* manifest_out = nullptr);

/// j[key] when j is an object holding a string there, else "" (for manifests not yet validated,
/// whose fields may have any type).
std::string string_field(const nlohmann::json& j, const char* key);

/// An atlas loaded into memory for the C++ evaluators.
struct Atlas {
  nlohmann::json manifest;
  std::vector<std::string> names;  ///< map names, same order as images
  std::vector<Image> images;       ///< rows bottom-up (flipped back from the files)
  Image closure_lut;
  const Image& map(const std::string& name) const;
};

/// Loads (after validating) an atlas; throws std::runtime_error listing the problems. It is
/// the two steps below: validate_atlas keeping the node files' bytes, then atlas_from_files
/// decoding those very bytes.
Atlas load_atlas(const std::filesystem::path& dir);

/// validate_atlas, also handing over the bytes of every texture's node_file it hashed and
/// checked, by texture name.
std::vector<std::string> validate_atlas(const std::filesystem::path& dir,
                                        nlohmann::json* manifest_out,
                                        std::map<std::string, AtlasFile>* node_files);

/// An Atlas from a manifest and node files validate_atlas accepted and handed over: decodes the
/// bytes it is given and reads nothing from `dir` (named in messages only). Throws
/// std::runtime_error naming the texture.
Atlas atlas_from_files(const std::filesystem::path& dir, nlohmann::json manifest,
                       std::map<std::string, AtlasFile> node_files);

}  // namespace loom
