// The files of an atlas (atlas.h): each read whole and once, decoded by the one reader its kind
// allows, written as a node file (OpenEXR) and a texture (maketx's tiled TIFF), and hashed.
#pragma once
#include <array>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "loom/ply_maps.h"

namespace loom {

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

/// A plain file name, the only kind an atlas names: not empty, no '/', '\\' or NUL, not "." or
/// "..".
bool plain_atlas_file_name(const std::string& name);

std::string sha256_file(const std::filesystem::path& p);
std::string sha256_string(const std::string& s);

}  // namespace loom
