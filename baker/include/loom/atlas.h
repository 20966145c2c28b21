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

/// One file of an atlas, read whole and once: what validate_atlas hashes is what load_atlas
/// decodes (no window between a check and a read in which the file could be swapped).
struct AtlasFile {
  std::filesystem::path path;  ///< for messages
  std::string bytes;
};

/// Why read_atlas_file refused a file; what() names the file and says so.
struct AtlasFileError : std::runtime_error {
  enum class Kind { Missing, SymbolicLink, NotRegular, Unreadable } kind;
  AtlasFileError(Kind k, const std::string& what) : std::runtime_error(what), kind(k) {}
};

/// Reads `name` (a plain file name) in the atlas directory `dir` with open(2)'s O_NOFOLLOW on the
/// name itself, so a symbolic link is refused at the read, not only by an earlier check; the
/// directory may be reached through a link. Throws AtlasFileError naming the file and why:
/// missing, a symbolic link, not a regular file (a FIFO is opened without blocking and refused),
/// larger than kMaxAtlasFileBytes, or a read error.
AtlasFile read_atlas_file(const std::filesystem::path& dir, const std::string& name);

/// The largest atlas file read_atlas_file reads, 1 GiB: a float map of kMaxMapSide x 2
/// kMaxMapSide x 4 channels is 512 MiB uncompressed, its mip-mapped .tx about 4/3 of that. The
/// file is read whole before its hash is checked, so this bounds what a manifest naming a huge
/// (or sparse) file can make validation allocate.
inline constexpr uint64_t kMaxAtlasFileBytes = uint64_t(1) << 30;

/// read_atlas_image and atlas_image_header on bytes already read; the format comes from the file
/// name's extension. The path overloads below read the file with read_atlas_file first, so they
/// too refuse a symbolic link and anything but a regular file.
Image read_atlas_image(const AtlasFile& file);
std::array<int, 3> atlas_image_header(const AtlasFile& file);

/// Reads an atlas map or table file (a node_file, OpenEXR) into an Image, rows bottom-up (flipped
/// back from the file). Throws std::runtime_error naming the file for anything but an image the
/// baker could have written: missing, not OpenEXR (no other reader of OpenImageIO is tried),
/// truncated or corrupted, deep or volume, 0 or more than 4 channels, larger than kMaxMapSide x
/// 2 kMaxMapSide. Arbitrary bytes give an image or that error (tests/fuzz/fuzz_texture.cpp).
Image read_atlas_image(const std::filesystem::path& file);

/// Width, height and channels of an atlas file from its header alone: OpenEXR for ".exr", TIFF
/// (maketx's tiled, mip-mapped .tx) for any other name; the same refusals as read_atlas_image.
std::array<int, 3> atlas_image_header(const std::filesystem::path& file);

/// Writes an image (rows bottom-up) as an atlas map in `dir`: `<name>.exr` (half or float
/// OpenEXR, channels R, G, B, A, row 0 at the top) and `<name>.tx` (tiled mip-mapped TIFF for
/// OSL, wrap mode `wrap`). Throws std::runtime_error.
void write_atlas_map(const Image& img, const std::filesystem::path& dir, const std::string& name,
                     bool half, const char* wrap);

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
