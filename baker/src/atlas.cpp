#include "loom/atlas.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <signal.h>
#include <openssl/evp.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <map>
#include <optional>
#include <cstdio>
#include <fmt/format.h>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "loom/absorption.h"
#include "loom/albedo_lut.h"
#include "loom/colour.h"
#include "loom/diffraction_tables.h"
#include "loom/double_layer.h"
#include "loom/raywave_bsdf.h"
#include "loom/shading.h"
#include "loom/speckle_noise.h"
#include "loom/ply_tables.h"

namespace fs = std::filesystem;
using nlohmann::json;
OIIO_NAMESPACE_USING

namespace loom {

namespace {

std::string hex_digest(EVP_MD_CTX* ctx) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_DigestFinal_ex(ctx, md, &len);
  EVP_MD_CTX_free(ctx);
  std::string out;
  for (unsigned i = 0; i < len; ++i) out += fmt::format("{:02x}", md[i]);
  return out;
}

/// Writes an image as half EXR (node mode, C++ evaluator) and as a tiled mip-mapped .tx.
void write_map(const Image& img, const fs::path& dir, const std::string& name, bool half,
               const char* wrap, std::vector<std::string> channel_names) {
  // Files name their channels R, G, B, A: OpenEXR stores channels sorted by name and Blender
  // maps EXR channels by these names, so semantic names would reorder or drop channels. The
  // meaning of each channel is in the manifest.
  (void)channel_names;
  ImageSpec spec(img.width, img.height, img.channels, TypeDesc::FLOAT);
  spec.channelnames = {"R", "G", "B", "A"};
  spec.channelnames.resize(size_t(img.channels));
  spec.alpha_channel = -1;  // data, not coverage: no premultiplication anywhere
  ImageBuf buf(spec);
  // Flip rows: our row 0 is the bottom (v = 0), files have row 0 at the top.
  for (int iy = 0; iy < img.height; ++iy) {
    int fy = img.height - 1 - iy;
    buf.set_pixels(ROI(0, img.width, fy, fy + 1, 0, 1, 0, img.channels), TypeDesc::FLOAT,
                   img.px(0, iy));
  }
  buf.set_write_format(half ? TypeDesc::HALF : TypeDesc::FLOAT);
  fs::path exr = dir / (name + ".exr");
  if (!buf.write(exr.string(), TypeUnknown, "openexr"))
    throw std::runtime_error(fmt::format("writing {}: {}", exr.string(), buf.geterror()));
  ImageSpec config;
  config.tile_width = 64;
  config.tile_height = 64;
  config.tile_depth = 1;
  config.set_format(half ? TypeDesc::HALF : TypeDesc::FLOAT);
  config.attribute("wrapmodes", wrap);
  config.attribute("maketx:filtername", "box");
  config.attribute("maketx:fileformatname", "tiff");
  fs::path tx = dir / (name + ".tx");
  if (!ImageBufAlgo::make_texture(ImageBufAlgo::MakeTxTexture, buf, tx.string(), config))
    throw std::runtime_error(fmt::format("make_texture {}: {}", tx.string(), OIIO::geterror()));
}

/// What an OpenEXR node file must be before OpenEXR reads it: the baker's kind of file, checked
/// from its header's bytes. OpenEXR allocates what a header declares before it reads it (an
/// attribute's size, a preview's pixels, the chunk table of a data window), so a few corrupted
/// bytes could make it allocate gigabytes (fuzz_texture found a 41-byte file claiming a 450 MB
/// string attribute: 20 s and 700 MB). The choices: one part, scan lines (the baker writes no
/// tiled, deep or multi-part EXR), a header in the first 64 KiB whose every attribute fits in the
/// file, no preview image or ID manifest (their sizes are stored inside them), a data window
/// within kMaxMapSide x 2 kMaxMapSide, and a lossless compression (none, RLE, ZIPS, ZIP, PIZ).
/// Returns "" or the reason.
std::string exr_header_problem(const std::string& bytes) {
  constexpr size_t kMaxHeader = 64 * 1024;
  const uintmax_t file_size = bytes.size();
  const std::string b = bytes.substr(0, kMaxHeader);
  const auto u8 = [&](size_t i) { return static_cast<unsigned char>(b[i]); };
  const auto i32 = [&](size_t i) {
    return int32_t(uint32_t(u8(i)) | uint32_t(u8(i + 1)) << 8 | uint32_t(u8(i + 2)) << 16 |
                   uint32_t(u8(i + 3)) << 24);
  };
  if (b.size() < 8 || u8(0) != 0x76 || u8(1) != 0x2f || u8(2) != 0x31 || u8(3) != 0x01)
    return "not an OpenEXR file (no magic number)";
  const uint32_t version = uint32_t(i32(4));
  if ((version & 0xff) != 2) return fmt::format("OpenEXR version {} (not 2)", version & 0xff);
  if (version & ~uint32_t(0x4ff))
    return "a tiled, deep or multi-part OpenEXR file (the baker writes single-part scan lines)";
  // A C string of at most 255 bytes at i: its end, or npos.
  const auto cstr_end = [&](size_t i) {
    const size_t e = b.find('\0', i);
    return e == std::string::npos || e - i > 255 ? std::string::npos : e;
  };
  bool window = false;
  size_t i = 8;
  for (;;) {
    if (i >= b.size()) return "the header does not end within its first 64 KiB";
    if (b[i] == '\0') break;  // end of the header
    const size_t name_end = cstr_end(i);
    const size_t type_end = name_end == std::string::npos ? name_end : cstr_end(name_end + 1);
    if (type_end == std::string::npos || type_end + 4 >= b.size())
      return "a header attribute is cut off or has an over-long name";
    const std::string name = b.substr(i, name_end - i);
    const std::string type = b.substr(name_end + 1, type_end - name_end - 1);
    const int32_t size = i32(type_end + 1);
    const size_t value = type_end + 5;
    if (size < 0 || uintmax_t(size) > file_size - value || value + size_t(size) > b.size())
      return fmt::format("header attribute \"{}\" declares {} bytes, more than the header "
                         "holds",
                         name, size);
    if (type == "preview" || type == "idmanifest")
      return fmt::format("header attribute \"{}\" of type {} (the baker writes none)", name, type);
    if (name == "dataWindow") {
      if (type != "box2i" || size != 16) return "dataWindow is not a box2i";
      const int64_t w = int64_t(i32(value + 8)) - i32(value) + 1;
      const int64_t h = int64_t(i32(value + 12)) - i32(value + 4) + 1;
      if (w < 1 || h < 1 || w > kMaxMapSide || h > 2 * kMaxMapSide)
        return fmt::format("data window {} x {} (allowed: 1 to {} x 1 to {})", w, h,
                           kMaxMapSide, 2 * kMaxMapSide);
      window = true;
    }
    if (name == "compression" && (type != "compression" || size != 1 || u8(value) > 4))
      return "compression is not a lossless one (none, RLE, ZIPS, ZIP, PIZ)";
    if (name == "tiles") return "a tiled OpenEXR file (the baker writes scan lines)";
    i = value + size_t(size);
  }
  if (!window) return "the header has no dataWindow";
  return "";
}

/// OpenImageIO 2.4's IOMemReader with its bounds made safe: its seek takes any offset and its
/// pread tests `size + offset > buffer size`, which wraps for a negative offset, so a file whose
/// OpenEXR line-offset table holds 2^64 - 1 (OpenEXR only refuses 0) made it copy from before
/// the buffer (found in review; AtlasRejection.NegativeOffsetsInAFileAreRefused keeps it).
struct BoundedMemReader : Filesystem::IOMemReader {
  using Filesystem::IOMemReader::IOMemReader;
  bool seek(int64_t offset) override {
    return offset >= 0 && uint64_t(offset) <= size() && Filesystem::IOMemReader::seek(offset);
  }
  size_t pread(void* buf, size_t n, int64_t offset) override {
    if (offset < 0 || uint64_t(offset) >= size()) return 0;
    return Filesystem::IOMemReader::pread(buf, std::min(n, size() - size_t(offset)), offset);
  }
  size_t read(void* buf, size_t n) override {  // through the bounded pread, whatever the base does
    const size_t got = pread(buf, n, m_pos);
    m_pos += int64_t(got);
    return got;
  }
};

struct OpenedAtlasFile {
  std::unique_ptr<BoundedMemReader> proxy;  // outlives `in` (members end in reverse)
  std::unique_ptr<ImageInput> in;
};

/// The one OpenImageIO reader for a file of the atlas: OpenEXR for the node files (".exr"),
/// TIFF for maketx's tiled textures (".tx"), whatever the bytes say. Choice: ImageInput::open
/// would try every format OIIO knows when the named one fails, so a corrupted file could reach
/// any of its readers; the atlas only ever holds these two. It reads the bytes in memory
/// (IOMemReader), never the file again.
OpenedAtlasFile open_atlas_file(const AtlasFile& f) {
  const fs::path& p = f.path;
  const bool exr = p.extension() == ".exr";
  if (exr)
    if (const std::string why = exr_header_problem(f.bytes); !why.empty())
      throw std::runtime_error(fmt::format("{}: not an OpenEXR file the baker writes: {}",
                                           p.string(), why));
  OpenedAtlasFile o;
  o.proxy = std::make_unique<BoundedMemReader>(f.bytes.data(), f.bytes.size());
  o.in = ImageInput::create(exr ? "openexr" : "tiff");
  if (!o.in)
    throw std::runtime_error(fmt::format("{}: OpenImageIO has no {} reader: {}", p.string(),
                                         exr ? "OpenEXR" : "TIFF", OIIO::geterror()));
  ImageSpec spec;
  bool ok = false;
  try {
    ok = o.in->set_ioproxy(o.proxy.get()) && o.in->open(p.string(), spec);
  } catch (const std::exception& e) {
    throw std::runtime_error(fmt::format("{}: cannot be read as {}: {}", p.string(),
                                         exr ? "OpenEXR" : "TIFF", e.what()));
  }
  if (!ok) {
    std::string err = o.in->geterror();
    if (err.empty()) err = OIIO::geterror();
    throw std::runtime_error(fmt::format("{}: cannot be read as {}: {}", p.string(),
                                         exr ? "OpenEXR" : "TIFF",
                                         err.empty() ? "no reason given" : err));
  }
  const ImageSpec& s = o.in->spec();
  if (s.deep || s.depth != 1 || s.width <= 0 || s.height <= 0 || s.width > kMaxMapSide ||
      s.height > 2 * kMaxMapSide || s.nchannels < 1 || s.nchannels > 4)
    throw std::runtime_error(fmt::format(
        "{}: a {}{}x{}x{} image, not what the baker writes (1 to 4 channels, at most {} x {})",
        p.string(), s.deep ? "deep " : "", s.width, s.height, s.nchannels, kMaxMapSide,
        2 * kMaxMapSide));
  return o;
}

uint64_t dir_bytes(const fs::path& d) {
  uint64_t n = 0;
  for (auto& e : fs::directory_iterator(d))
    if (e.is_regular_file()) n += e.file_size();
  return n;
}

/// A directory that holds a manifest of a Loom atlas (any schema version).
bool is_loom_atlas_dir(const fs::path& d) {
  std::ifstream in(d / "manifest.json");
  if (!in) return false;
  try {
    json m = json::parse(in);
    return m.is_object() && m.contains("schema") && m["schema"].is_string() &&
           m["schema"].get<std::string>().rfind("loom.atlas/", 0) == 0;
  } catch (const std::exception&) {
    return false;
  }
}

/// Removes temporaries of bakes of `dir` whose process is gone (killed with SIGKILL, power loss):
/// ".<name>.tmp-<pid>-<random>" beside it, <pid> no longer running.
void sweep_stale_temporaries(const fs::path& dir) {
  const std::string prefix = "." + dir.filename().string() + ".tmp-";
  std::error_code ec;
  for (auto& e : fs::directory_iterator(dir.parent_path(), ec)) {
    std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
    if (pid <= 0 || (::kill(pid_t(pid), 0) != 0 && errno == ESRCH)) fs::remove_all(e.path(), ec);
  }
}

const char* const kSurfaceMaps[] = {"ply_frame",   "ply_normal",      "yarn_info",
                                   "albedo_reflect", "albedo_transmit", "spec_params",
                                   "horizon_0",   "horizon_1",       "albedo_lut"};

/// j[key] when j is an object holding a string there, else "" (for manifests not yet validated,
/// whose fields may have any type).
std::string string_field(const json& j, const char* key) {
  if (!j.is_object()) return "";
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : "";
}

bool plain_filename(const std::string& f) {
  return !f.empty() && f.find('/') == std::string::npos && f.find('\\') == std::string::npos &&
         f != "." && f != ".." && f.find('\0') == std::string::npos;
}

}  // namespace

std::string sha256_string(const std::string& s) {
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
  EVP_DigestUpdate(ctx, s.data(), s.size());
  return hex_digest(ctx);
}

std::string sha256_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + p.string());
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
  std::vector<char> buf(1 << 16);
  while (in) {
    in.read(buf.data(), std::streamsize(buf.size()));
    EVP_DigestUpdate(ctx, buf.data(), size_t(in.gcount()));
  }
  return hex_digest(ctx);
}

AtlasFile read_atlas_file(const fs::path& dir, const std::string& name) {
  using Kind = AtlasFileError::Kind;
  AtlasFile f;
  f.path = dir / name;
  const std::string ps = f.path.string();
  if (!plain_filename(name))
    throw AtlasFileError(Kind::Unreadable, fmt::format("{}: not a plain file name", ps));
  // O_NOFOLLOW: a link as the last component fails with ELOOP; O_NONBLOCK: a FIFO does not
  // wait for a writer (and is refused below); the directory is resolved as the user named it.
  const int fd = ::open(ps.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    struct stat lst {};
    if (err == ELOOP && ::lstat(ps.c_str(), &lst) == 0 && S_ISLNK(lst.st_mode))
      throw AtlasFileError(Kind::SymbolicLink,
                           fmt::format("{} is a symbolic link; an atlas's files must be regular "
                                       "files in its directory",
                                       ps));
    if (err == ENOENT || err == ENOTDIR)
      throw AtlasFileError(Kind::Missing, fmt::format("{} is missing", ps));
    throw AtlasFileError(Kind::Unreadable,
                         fmt::format("{} cannot be opened: {}", ps, std::strerror(err)));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0)
    throw AtlasFileError(Kind::Unreadable,
                         fmt::format("{} cannot be read: {}", ps, std::strerror(errno)));
  if (!S_ISREG(st.st_mode))
    throw AtlasFileError(Kind::NotRegular, fmt::format("{} is not a regular file", ps));
  (void)::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);  // reads of a file may block
  if (uint64_t(st.st_size) > kMaxAtlasFileBytes)
    throw AtlasFileError(Kind::Unreadable,
                         fmt::format("{} holds {} bytes, more than an atlas file may ({})", ps,
                                     uint64_t(st.st_size), kMaxAtlasFileBytes));
  try {
    f.bytes.resize(size_t(st.st_size));
  } catch (const std::bad_alloc&) {
    throw AtlasFileError(Kind::Unreadable, fmt::format("{}: no memory for its {} bytes", ps,
                                                       uint64_t(st.st_size)));
  }
  size_t got = 0;
  while (got < f.bytes.size()) {
    const ssize_t n = ::read(fd, f.bytes.data() + got, f.bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0)
      throw AtlasFileError(Kind::Unreadable,
                           fmt::format("{} cannot be read: {}", ps, std::strerror(errno)));
    if (n == 0) break;  // shorter than fstat said (truncated meanwhile): what was read is it
    got += size_t(n);
  }
  f.bytes.resize(got);
  return f;
}

Image read_atlas_image(const AtlasFile& f) {
  const OpenedAtlasFile o = open_atlas_file(f);
  ImageInput& in = *o.in;
  const fs::path& p = f.path;
  const ImageSpec& s = in.spec();
  Image img(s.width, s.height, s.nchannels);
  std::vector<float> tmp(img.data.size());
  bool ok = false;
  try {
    ok = in.read_image(0, 0, 0, s.nchannels, TypeDesc::FLOAT, tmp.data());
  } catch (const std::exception& e) {
    throw std::runtime_error(fmt::format("{}: reading its pixels failed: {}", p.string(), e.what()));
  }
  if (!ok) {
    std::string err = in.geterror();
    throw std::runtime_error(fmt::format("{}: reading its pixels failed: {}", p.string(),
                                         err.empty() ? "(no reason given)" : err));
  }
  for (int iy = 0; iy < img.height; ++iy) {
    int fy = img.height - 1 - iy;
    std::copy_n(&tmp[size_t(fy) * img.width * img.channels], size_t(img.width) * img.channels,
                img.px(0, iy));
  }
  return img;
}

std::array<int, 3> atlas_image_header(const AtlasFile& f) {
  const OpenedAtlasFile o = open_atlas_file(f);
  return {o.in->spec().width, o.in->spec().height, o.in->spec().nchannels};
}

Image read_atlas_image(const fs::path& p) {
  return read_atlas_image(read_atlas_file(p.parent_path(), p.filename().string()));
}

std::array<int, 3> atlas_image_header(const fs::path& p) {
  return atlas_image_header(read_atlas_file(p.parent_path(), p.filename().string()));
}

void write_atlas_map(const Image& img, const fs::path& dir, const std::string& name, bool half,
                     const char* wrap) {
  write_map(img, dir, name, half, wrap, {});
}

namespace {

/// The type and range checks of the manifest's fields that the deep readers (load_ply_tables,
/// load_raywave, the shading tables) take as they are: `errors` gets one message naming the
/// field for each problem.
struct FieldChecks {
  std::vector<std::string>& errors;

  /// parent[key] if parent is an object holding it, else null.
  static const json& at(const json& parent, const char* key) {
    static const json null;
    if (!parent.is_object()) return null;
    const auto it = parent.find(key);
    return it == parent.end() ? null : *it;
  }
  bool string(const json& parent, const char* key, const std::string& path, bool required) {
    const json& v = at(parent, key);
    if (v.is_string() || (v.is_null() && !required && !parent.contains(key))) return true;
    errors.push_back(fmt::format("{}: expected a string{}", path, v.is_null() ? " (missing)" : ""));
    return false;
  }
  bool integer(const json& parent, const char* key, const std::string& path, long long lo,
               long long hi, bool required = true) {
    const json& v = at(parent, key);
    if (!required && !parent.contains(key)) return true;
    if (v.is_number_integer() && v.get<long long>() >= lo && v.get<long long>() <= hi &&
        !(v.is_number_unsigned() && v.get<unsigned long long>() > (unsigned long long)hi))
      return true;
    errors.push_back(fmt::format("{}: expected an integer in [{}, {}]{}", path, lo, hi,
                                 v.is_null() ? " (missing)" : ", not " + v.dump()));
    return false;
  }
  bool number(const json& parent, const char* key, const std::string& path, double lo, double hi,
              bool required = true) {
    const json& v = at(parent, key);
    if (!required && !parent.contains(key)) return true;
    if (v.is_number() && v.get<double>() >= lo && v.get<double>() <= hi) return true;
    errors.push_back(fmt::format("{}: expected a number in [{}, {}]{}", path, lo, hi,
                                 v.is_null() ? " (missing)" : ", not " + v.dump()));
    return false;
  }
  /// An array of min_n to max_n numbers in [lo, hi], strictly increasing if `increasing`.
  bool numbers(const json& parent, const char* key, const std::string& path, size_t min_n,
               size_t max_n, double lo, double hi, bool increasing) {
    const json& v = at(parent, key);
    bool ok = v.is_array() && v.size() >= min_n && v.size() <= max_n;
    for (size_t k = 0; ok && k < v.size(); ++k)
      ok = v[k].is_number() && v[k].get<double>() >= lo && v[k].get<double>() <= hi &&
           (!increasing || k == 0 || v[k].get<double>() > v[k - 1].get<double>());
    if (ok) return true;
    errors.push_back(fmt::format("{}: expected {} to {} numbers in [{}, {}]{}", path, min_n, max_n,
                                 lo, hi, increasing ? ", increasing" : ""));
    return false;
  }
};

/// What load_ply_tables and load_raywave read besides the texture names (checked by the caller):
/// their types, and for the integers the ranges that keep the readers' arithmetic in range.
/// The readers check the values' meaning themselves (grids, lobe counts, curves, image sizes).
void check_raywave_fields(const json& m, std::vector<std::string>& errors) {
  FieldChecks c{errors};
  const json& rw = FieldChecks::at(m, "raywave");
  const json& repeat = FieldChecks::at(m, "repeat");
  c.integer(repeat, "warp_yarns", "repeat.warp_yarns", 1, kMaxMapSide);
  c.integer(repeat, "weft_yarns", "repeat.weft_yarns", 1, kMaxMapSide);
  const json& yarns = FieldChecks::at(rw, "yarns");
  for (const char* yarn : {"warp", "weft"}) {
    const json& y = FieldChecks::at(yarns, yarn);
    if (!y.is_object()) continue;  // reported by the caller
    const std::string p = fmt::format("raywave.yarns.{}", yarn);
    c.string(y, "yarn", p + ".yarn", false);
    for (const char* which : {"high", "refl"})
      c.number(FieldChecks::at(y, which), "nrmse", fmt::format("{}.{}.nrmse", p, which), 0, 1e30,
               false);
    const json& ab = FieldChecks::at(y, "absorption");
    if (!ab.is_object()) {
      errors.push_back(p + ".absorption: expected an object (the yarn's absorption)");
      continue;
    }
    c.numbers(ab, "sigma_rgb_per_mm", p + ".absorption.sigma_rgb_per_mm", 3, 3, 0, 1e30, false);
    const json& curve = FieldChecks::at(ab, "curve");
    if (!curve.is_object())
      errors.push_back(p + ".absorption.curve: expected an object");
    else
      c.integer(curve, "rays", p + ".absorption.curve.rays", 0, (1LL << 62), false);
  }
  const json& dl = FieldChecks::at(rw, "double_layer");
  c.integer(dl, "theta_count", "raywave.double_layer.theta_count", 1, 2 * kMaxMapSide);
  c.integer(dl, "phi_count", "raywave.double_layer.phi_count", 1, kMaxMapSide);
  c.numbers(dl, "sigma_per_mm", "raywave.double_layer.sigma_per_mm", 1, 2 * kMaxMapSide, 0, 1e30,
            true);
  c.number(dl, "blend", "raywave.double_layer.blend", 0, 1, false);
  c.string(FieldChecks::at(rw, "shading"), "sigma_interpolation",
           "raywave.shading.sigma_interpolation", false);
  const json& dif = FieldChecks::at(rw, "diffraction");
  const json& dfiles = FieldChecks::at(dif, "files");
  if (dfiles.is_object() && dfiles.contains("gap")) {
    c.integer(dif, "tile_size", "raywave.diffraction.tile_size", 2, kMaxMapSide);
    c.number(dif, "spot_s", "raywave.diffraction.spot_s", 0, 1e30);
    c.numbers(dif, "gap_fraction", "raywave.diffraction.gap_fraction", 2, 2, 0, 1, false);
    if (!dfiles.contains("gap_sampling"))
      errors.push_back("raywave.diffraction.files.gap_sampling: missing (the gap table needs it)");
  }
  const json& nz = FieldChecks::at(rw, "noise");
  const json& nfiles = FieldChecks::at(nz, "files");
  if (nfiles.is_object() && (nfiles.contains("refl") || nfiles.contains("high"))) {
    if (!nfiles.contains("refl") || !nfiles.contains("high"))
      errors.push_back("raywave.noise.files: expected both \"refl\" and \"high\", or neither");
    c.integer(nz, "levels", "raywave.noise.levels", 0, 64);
    c.integer(nz, "instances", "raywave.noise.instances", 1, 2 * kMaxMapSide);
    c.integer(nz, "theta_count", "raywave.noise.theta_count", 1, kMaxMapSide);
  }
}

}  // namespace

namespace {

/// validate_atlas, keeping in `node_files` (when given) the bytes of every texture's node_file
/// it hashed and checked, by texture name, for load_atlas to decode.
std::vector<std::string> validate_atlas_files(const fs::path& dir, json* manifest_out,
                                              std::map<std::string, AtlasFile>* node_files) {
  std::vector<std::string> errors;
  fs::path mp = dir / "manifest.json";
  AtlasFile manifest_file;
  try {
    manifest_file = read_atlas_file(dir, "manifest.json");
  } catch (const AtlasFileError& e) {
    if (e.kind == AtlasFileError::Kind::SymbolicLink)
      return {fmt::format("{}: is a symbolic link; an atlas's files must be regular files in its "
                          "directory",
                          mp.string())};
    if (e.kind == AtlasFileError::Kind::Missing)
      return {fmt::format("{}: missing or unreadable (not an atlas)", mp.string())};
    return {fmt::format("{} (not an atlas)", e.what())};
  }
  json m;
  try {
    m = json::parse(manifest_file.bytes);
  } catch (const std::exception& e) {
    return {fmt::format("{}: not valid JSON: {}", mp.string(), e.what())};
  }
  if (!m.is_object() || !m.contains("schema") || !m["schema"].is_string())
    return {fmt::format("{}: no \"schema\" field", mp.string())};
  if (m["schema"] != kAtlasSchema)
    return {fmt::format("{}: schema {} is not supported; this baker reads \"{}\" (re-bake the "
                        "atlas)",
                        mp.string(), m["schema"].dump(), kAtlasSchema)};
  if (!m.contains("textures") || !m["textures"].is_object() || m["textures"].empty())
    return {fmt::format("{}: no \"textures\"", mp.string())};
  for (auto& [name, t] : m["textures"].items()) {
    if (!t.is_object()) {
      errors.push_back(fmt::format("textures.{}: expected an object", name));
      continue;
    }
    for (const char* key : {"file", "node_file"}) {
      if (!t.contains(key) || !t[key].is_string() || !plain_filename(t[key].get<std::string>())) {
        errors.push_back(fmt::format("textures.{}.{}: must be a plain file name inside the atlas "
                                     "directory",
                                     name, key));
        continue;
      }
      fs::path f = dir / t[key].get<std::string>();
      std::string hkey = std::string(key) == "file" ? "sha256" : "node_sha256";
      // Choice: no symbolic links at all, to a file inside the atlas or outside it. Only the
      // ones leaving the directory are a danger (an atlas from elsewhere reading any file the
      // user can), but a link inside is never written by the baker, and refusing every link at
      // the read itself (read_atlas_file: O_NOFOLLOW) leaves no window for a swap.
      AtlasFile file;
      try {
        file = read_atlas_file(dir, t[key].get<std::string>());
      } catch (const AtlasFileError& e) {
        using Kind = AtlasFileError::Kind;
        if (e.kind == Kind::SymbolicLink)
          errors.push_back(fmt::format("textures.{}.{}: {} is a symbolic link; an atlas's files "
                                       "must be regular files in its directory",
                                       name, key, f.string()));
        else if (e.kind == Kind::Missing || e.kind == Kind::NotRegular)
          errors.push_back(fmt::format("textures.{}: {} is missing{}", name, f.string(),
                                       e.kind == Kind::NotRegular ? " (not a regular file)" : ""));
        else
          errors.push_back(fmt::format("textures.{}: {}", name, e.what()));
        continue;
      }
      if (!t.contains(hkey) || !t[hkey].is_string() || sha256_string(file.bytes) != t[hkey]) {
        errors.push_back(
            fmt::format("textures.{}: {} does not match its sha256 (corrupted or changed)", name,
                        f.string()));
        continue;
      }
      std::array<int, 3> s{};
      try {
        s = atlas_image_header(file);
      } catch (const std::runtime_error& e) {
        errors.push_back(fmt::format("textures.{}: {}", name, e.what()));
        continue;
      }
      if (!t.contains("size") || t["size"] != json::array({s[0], s[1]}) ||
          !t.contains("channels") || !t["channels"].is_array() ||
          int(t["channels"].size()) != s[2]) {
        errors.push_back(fmt::format("textures.{}: {} is {}x{}x{}, the manifest says otherwise",
                                     name, f.string(), s[0], s[1], s[2]));
        continue;
      }
      if (node_files && std::string(key) == "node_file") (*node_files)[name] = std::move(file);
    }
  }
  // The contract the evaluators rely on: every map, four channels, one size for all maps, and
  // the albedo LUT's layout.
  const auto& tex = m["textures"];
  std::optional<json> map_size;
  for (const char* name : kSurfaceMaps) {
    if (!tex.contains(name)) {
      errors.push_back(fmt::format("textures.{}: missing from the manifest", name));
      continue;
    }
    const json& t = tex[name];
    if (!t.is_object() || !t.contains("size") || !t.contains("channels") ||
        !t["channels"].is_array() || t["channels"].size() != 4) {
      errors.push_back(fmt::format("textures.{}: expected 4 channels and a size", name));
      continue;
    }
    if (std::string(name) == "albedo_lut") {
      if (t["size"] != json::array({LOOM_ALBEDO_LUT_SIZE,
                                    2 * LOOM_LUT_SLICES * LOOM_ALBEDO_LUT_SIZE}))
        errors.push_back(fmt::format("textures.albedo_lut: size {} is not {} x {} (another "
                                     "baker's layout: re-bake the atlas)",
                                     t["size"].dump(), LOOM_ALBEDO_LUT_SIZE,
                                     2 * LOOM_LUT_SLICES * LOOM_ALBEDO_LUT_SIZE));
    } else if (!map_size) {
      map_size = t["size"];
    } else if (*map_size != t["size"]) {
      errors.push_back(fmt::format("textures.{}: size {} differs from the other maps' {}", name,
                                   t["size"].dump(), map_size->dump()));
    }
  }
  if (m.contains("tier") && !m["tier"].is_string())
    errors.push_back(fmt::format("tier: expected a string, not {}", m["tier"].dump()));
  // Ray-wave atlases: every yarn's tables are textures of this atlas.
  if (m.contains("tier") && m["tier"] == "raywave") {
    if (!m.contains("raywave") || !m["raywave"].is_object() || !m["raywave"].contains("yarns") ||
        !m["raywave"]["yarns"].is_object()) {
      errors.push_back("raywave: missing (a ray-wave atlas lists its ply tables there)");
    } else {
      for (const char* yarn : {"warp", "weft"}) {
        const json& y = m["raywave"]["yarns"].value(yarn, json());
        if (!y.is_object() || !y.contains("files") || !y["files"].is_object()) {
          errors.push_back(fmt::format("raywave.yarns.{}: missing or without \"files\"", yarn));
          continue;
        }
        if (!y.contains("node_layout") || y["node_layout"] != kAsgNodeLayout)
          errors.push_back(fmt::format("raywave.yarns.{}.node_layout: {} is not this baker's \"{}\" "
                                       "(another baker's layout: re-bake the atlas)",
                                       yarn, y.value("node_layout", json("missing")).dump(),
                                       kAsgNodeLayout));
        for (const char* f : {"high", "high_scale", "refl", "tint", "high_residual",
                              "refl_residual", "residual"}) {
          const json& name = y["files"].value(f, json());
          if (!name.is_string() || !tex.contains(name.get<std::string>()))
            errors.push_back(fmt::format("raywave.yarns.{}.files.{}: not a texture of the atlas",
                                         yarn, f));
        }
      }
      const json& dl = m["raywave"].value("double_layer", json());
      for (const char* f : {"front", "back"}) {
        const json& name = dl.is_object() && dl.contains("files") && dl["files"].is_object()
                               ? dl["files"].value(f, json())
                               : json();
        if (!name.is_string() || !tex.contains(name.get<std::string>()))
          errors.push_back(fmt::format("raywave.double_layer.files.{}: not a texture of the atlas",
                                       f));
      }
      // Shading tables at the yarn colours.
      const json& sh = m["raywave"].value("shading", json());
      for (const char* f : {"front", "back"}) {
        const json& name = sh.is_object() && sh.contains("factors") && sh["factors"].is_object()
                               ? sh["factors"].value(f, json())
                               : json();
        if (!name.is_string() || !tex.contains(name.get<std::string>()))
          errors.push_back(fmt::format("raywave.shading.factors.{}: not a texture of the atlas", f));
      }
      if (!sh.is_object() || !sh.contains("factors_layout") ||
          sh["factors_layout"] != kLayerFactorsLayout)
        errors.push_back(fmt::format(
            "raywave.shading.factors_layout: {} is not this baker's \"{}\" (double-layer factors "
            "of another baker: re-bake the atlas)",
            sh.is_object() && sh.contains("factors_layout") ? sh["factors_layout"].dump()
                                                            : std::string("missing"),
            kLayerFactorsLayout));
      if (!sh.is_object() || !sh.value("microfacet_albedo", json()).is_string() ||
          !tex.contains(sh["microfacet_albedo"].get<std::string>()))
        errors.push_back("raywave.shading.microfacet_albedo: not a texture of the atlas");
      // Noise: the listed tiles (none when wave.noise is off) are textures of the atlas.
      const json& noise = m["raywave"].value("noise", json());
      if (!noise.is_object() || !noise.contains("files") || !noise["files"].is_object())
        errors.push_back("raywave.noise.files: missing");
      else
        for (auto& [k, name] : noise["files"].items())
          if (!name.is_string() || !tex.contains(name.get<std::string>()))
            errors.push_back(fmt::format("raywave.noise.files.{}: not a texture of the atlas", k));
      // Diffraction: "tables" lists its files; "delta" (the non-wave variant) has none.
      const json& dif = m["raywave"].value("diffraction", json());
      const json& mode_j = FieldChecks::at(dif, "mode");
      const std::string mode = mode_j.is_string() ? mode_j.get<std::string>() : "";
      if (mode != "tables" && mode != "delta") {
        errors.push_back("raywave.diffraction.mode: expected \"tables\" or \"delta\"");
      } else if (mode == "tables") {
        const json& files = dif.value("files", json());
        if (!files.is_object() || !files.contains("edge"))
          errors.push_back("raywave.diffraction.files: missing (needs at least \"edge\")");
        else
          for (auto& [k, name] : files.items())
            if (!name.is_string() || !tex.contains(name.get<std::string>()))
              errors.push_back(
                  fmt::format("raywave.diffraction.files.{}: not a texture of the atlas", k));
      }
      check_raywave_fields(m, errors);
    }
  }
  if (manifest_out) *manifest_out = m;
  return errors;
}

}  // namespace

std::vector<std::string> validate_atlas(const fs::path& dir, json* manifest_out) {
  return validate_atlas_files(dir, manifest_out, nullptr);
}

std::string raywave_simulation_key(json canon, const std::string& colour,
                                   const std::string& baker_id) {
  canon.erase("name");
  for (const char* y : {"warp", "weft"})
    if (canon.contains(y) && canon[y].is_object()) canon[y].erase("color");
  return sha256_string(canon.dump() + colour + baker_id);
}

namespace {

/// Textures of a ray-wave atlas that do not depend on the yarn colours.
bool colour_independent_texture(const std::string& name) {
  for (const char* prefix : {"ply_high_", "ply_refl_", "double_layer_", "diffraction_", "noise_",
                             "microfacet_albedo"})
    if (name.rfind(prefix, 0) == 0) return true;
  return false;
}

/// A valid ray-wave atlas among the candidates whose simulation key is `key`: the given
/// directories, the destination, then the destination's siblings (the add-on's cache keeps
/// every atlas in one directory). Returns its directory and manifest.
std::optional<std::pair<fs::path, json>> find_simulation(const std::string& key, const fs::path& dir,
                                                         const std::vector<fs::path>& extra) {
  std::vector<fs::path> cands(extra.begin(), extra.end());
  cands.push_back(dir);
  std::error_code ec;
  int scanned = 0;
  for (fs::directory_iterator it(dir.parent_path(), ec), end; !ec && it != end; it.increment(ec)) {
    if (++scanned > 512) break;  // a crowded directory is not worth a long search
    const auto name = it->path().filename().string();
    if (!name.empty() && name[0] != '.' && it->path() != dir) cands.push_back(it->path());
  }
  for (const fs::path& c : cands) {
    std::ifstream in(c / "manifest.json");
    if (!in) continue;
    json m = json::parse(in, nullptr, false);
    if (m.is_discarded() || !m.is_object() || !m.contains("raywave") ||
        string_field(m["raywave"], "simulation_key") != key)
      continue;
    if (!validate_atlas(c, &m).empty()) continue;
    return std::pair{fs::absolute(c), m};
  }
  return std::nullopt;
}

}  // namespace

BakeResult bake_atlas(FabricSpec spec, const fs::path& dir_in, const BakeOptions& opt) {
  auto t0 = std::chrono::steady_clock::now();
  fs::path dir = fs::absolute(dir_in).lexically_normal();
  if (dir.filename().empty()) dir = dir.parent_path();
  ColourConverter cc(opt.ocio_config);
  for (YarnSpec* y : {&spec.warp, &spec.weft})
    y->color_linear = y->color_space == "srgb" ? cc.srgb_to_linear(y->color_input) : y->color_input;
  const json canon = canonical_spec(spec);
  const std::string spec_hash = sha256_string(canon.dump());
  // What decides whether an existing atlas can be reused: the spec, the colour conversion and
  // the very baker binary that made it (a rebuilt baker may bake the same spec differently, and a
  // version number that someone must remember to bump would let stale atlases through).
  static const std::string baker_id = [] {
    std::error_code ec;
    auto exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string(kBakerVersion) : sha256_file(exe);
  }();
  const std::string bake_key = sha256_string(canon.dump() + cc.describe().dump() + baker_id);

  BakeResult res;
  res.dir = dir;
  if (fs::exists(fs::symlink_status(dir))) {
    json m;
    if (!opt.force && validate_atlas(dir, &m).empty() && string_field(m, "bake_key") == bake_key) {
      res.reused = true;
      res.bytes = dir_bytes(dir);
      return res;
    }
    // Whatever --force says, only an empty directory or a Loom atlas (of any schema version) is
    // ever replaced: the destination may be a user's folder.
    if (fs::is_symlink(dir) || !fs::is_directory(dir))
      throw std::runtime_error(fmt::format("{} exists and is not a directory; refusing to "
                                           "replace it",
                                           dir.string()));
    if (!fs::is_empty(dir) && !is_loom_atlas_dir(dir))
      throw std::runtime_error(fmt::format("{} exists, is not empty and is not a Loom atlas; "
                                           "refusing to replace it",
                                           dir.string()));
  }
  fs::create_directories(dir.parent_path());
  sweep_stale_temporaries(dir);
  std::random_device rd;
  fs::path tmp = dir.parent_path() /
                 fmt::format(".{}.tmp-{}-{:08x}", dir.filename().string(), getpid(), rd());
  fs::create_directory(tmp);
  try {
    // A colour-only change of a ray-wave spec: an atlas with the same simulation key (the
    // destination's previous bake, a sibling in the cache, or --reuse) holds every table that
    // does not depend on the colours; they are copied instead of computed.
    const std::string sim_key = raywave_simulation_key(canon, cc.describe().dump(), baker_id);
    const auto source = spec.tier != Tier::Raywave || opt.force
                            ? std::nullopt
                            : find_simulation(sim_key, dir, opt.reuse_from);
    json textures = json::object();
    const auto copy_texture = [&](const std::string& name) {
      const json& t = source->second["textures"][name];
      for (const char* key : {"file", "node_file"})
        fs::copy_file(source->first / t[key].get<std::string>(), tmp / t[key].get<std::string>());
      textures[name] = t;
    };
    SurfaceMaps maps = bake_surface_maps(spec, opt.progress, /*horizons=*/!source);
    Image lut = source ? Image() : bake_albedo_lut(spec, opt.progress);
    for (size_t k = 0; k < maps.images.size(); ++k) {
      const MapInfo& mi = maps.info[k];
      if (source && mi.name.rfind("albedo_", 0) != 0) {  // only the albedo maps hold colour
        copy_texture(mi.name);
        continue;
      }
      write_map(maps.images[k], tmp, mi.name, true, "periodic", mi.channels);
      textures[mi.name] = {{"file", mi.name + ".tx"},
                           {"node_file", mi.name + ".exr"},
                           {"channels", mi.channels},
                           {"range", mi.range},
                           {"units", mi.units},
                           {"format", "half"},
                           {"size", {maps.images[k].width, maps.images[k].height}},
                           {"tiling", "periodic"},
                           {"period_uv", {1.0, 1.0}},
                           {"description", mi.description}};
      if (opt.progress) opt.progress("write", double(k + 1) / (maps.images.size() + 1));
    }
    if (source) {
      copy_texture("albedo_lut");  // directional albedos per unit colour
    } else {
      write_map(lut, tmp, "albedo_lut", false, "clamp", {"A_rs", "A_ggx", "A_ts", "one"});
      textures["albedo_lut"] = {
        {"file", "albedo_lut.tx"},
        {"node_file", "albedo_lut.exr"},
        {"channels", {"A_rs", "A_ggx", "A_ts", "one"}},
        {"range", {{0, 2}, {0, 2}, {0, 2}, {1, 1}}},
        {"units", {"", "", "", ""}},
        {"format", "float"},
        {"size", {lut.width, lut.height}},
        {"tiling", "clamp"},
        {"description",
         fmt::format("directional albedos per unit k for the closure weights (closure_mapping.h):"
                     " rows kind-major (warp, then weft, from the bottom), then {0} slices of the "
                     "ply tangent elevation t_z in [0, {1}], then {2} rows of cos theta_view (row "
                     "j at max(j/{3}, {4})); columns: view azimuth about t over [0, pi]",
                     LOOM_LUT_SLICES, LOOM_LUT_TZ_MAX, LOOM_ALBEDO_LUT_SIZE,
                     LOOM_ALBEDO_LUT_SIZE - 1, kLutMinCos)}};
    }
    json raywave;
    if (spec.tier == Tier::Raywave) {
      raywave = {{"status", "ply tables (Eq. S.1-S.12, multi-ply S.13-S.19) and double-layer "
                            "factors (S.20), aperture diffraction (S.34, S.35), speckle noise tiles "
                            "(S.37, S.38), absorption spectra from the yarn colours (S.42) and the "
                            "render tables at those colours baked; shading evaluates the lobes, the "
                            "double-layer factors, the gaps' diffraction and the speckle noise per "
                            "lobe; ply-edge diffraction at render time is not yet"},
                 {"yarns", json::object()}};
      // The ply tables do not depend on the yarn colour (colour is absorption, applied through
      // the tables' levels): a weft that differs only in colour shares the warp's tables.
      json canon_warp = canon["warp"], canon_weft = canon["weft"];
      canon_warp.erase("color");
      canon_weft.erase("color");
      std::optional<PlyTables> yarn_tables[2];
      auto add_table = [&](const Image& img, const std::string& name,
                           std::vector<std::string> channels, const std::string& what,
                           bool half = false, const char* tiling = "clamp") {
        write_map(img, tmp, name, half, tiling, channels);
        json range = json::array();
        for (int c = 0; c < img.channels; ++c) {
          float lo = INFINITY, hi = -INFINITY;
          for (size_t i = size_t(c); i < img.data.size(); i += size_t(img.channels))
            lo = std::min(lo, img.data[i]), hi = std::max(hi, img.data[i]);
          range.push_back({lo, hi});
        }
        textures[name] = {{"file", name + ".tx"},
                          {"node_file", name + ".exr"},
                          {"channels", channels},
                          {"range", range},
                          {"units", std::vector<std::string>(channels.size(), "")},
                          {"format", half ? "half" : "float"},
                          {"size", {img.width, img.height}},
                          {"tiling", tiling},
                          {"description", what}};
      };
      // A colour-only change: the colour-independent tables come from `source` (found above).
      std::optional<AbsorptionCurve> curves[2];
      double sigma_max[2] = {0, 0};
      if (source) {
        const json& sm = source->second;
        const json status = raywave["status"];
        raywave = sm["raywave"];
        raywave["status"] = status;
        raywave["reused_from"] = source->first.string();
        for (auto& [name, t] : sm["textures"].items())
          if (colour_independent_texture(name)) copy_texture(name);
        for (int i = 0; i < 2; ++i) {
          const char* yarn = i == 0 ? "warp" : "weft";
          const json& y = raywave["yarns"][yarn];
          curves[i] = absorption_curve_from_manifest(y, yarn);
          if (curves[i]->empty())
            throw std::runtime_error(fmt::format("reusing {}: raywave.yarns.{}.absorption.curve "
                                                 "is missing", source->first.string(), yarn));
          sigma_max[i] = y["high"]["sigma_per_mm"].back().get<double>();
        }
        res.reused_simulation = source->first;
      } else {
        for (const char* yarn : {"warp", "weft"}) {
          const bool weft_same = std::string(yarn) == "weft" && canon_weft == canon_warp;
          if (weft_same) {
            raywave["yarns"]["weft"] = raywave["yarns"]["warp"];
            raywave["yarns"]["weft"]["yarn"] = "weft";
            raywave["yarns"]["weft"]["same_as"] = "warp";
            continue;
          }
          const YarnSpec& y = std::string(yarn) == "warp" ? spec.warp : spec.weft;
          PlyTables& pt = yarn_tables[std::string(yarn) == "warp" ? 0 : 1].emplace(
              bake_ply_tables(y, spec.quality, opt.progress, std::string("plysim ") + yarn,
                              spec.components.multi_ply));
          json entry = ply_tables_manifest(pt, yarn);
          add_table(asg_nodes_image(pt.high), entry["files"]["high"],
                    {"theta_z|mu2", "phi_z|c", "phi_xy|0", "mu1|0"},
                    "f_high ASG corner nodes, two texels per (h node, lobe) in lobe-major columns, rows "
                    "theta_i nodes "
                    "(layout: baker/include/loom/ply_tables.h)");
          add_table(asg_scale_image(pt.high), entry["files"]["high_scale"], {"s"},
                    "f_high absorption scale-downs s_{l,k} per corner node, column j L + l, row i K + k "
                    "(layout: baker/include/loom/ply_tables.h)");
          add_table(asg_nodes_image(pt.refl), entry["files"]["refl"],
                    {"theta_z|mu2", "phi_z|c", "phi_xy|0", "mu1|0"},
                    "f_refl ASG corner nodes, two texels per (h node, lobe) in lobe-major columns, rows "
                    "theta_i nodes "
                    "(layout: baker/include/loom/ply_tables.h)");
          add_table(asg_residual_image(pt.high), entry["files"]["high_residual"], {"energy"},
                    "f_high energy the lobes miss (baker/include/loom/asg_residual.h), column "
                    "side N + n (0 backward, 1 forward), row m K + k");
          add_table(asg_residual_image(pt.refl), entry["files"]["refl_residual"], {"energy"},
                    "f_refl energy the lobes miss (baker/include/loom/asg_residual.h), column "
                    "side N + n (0 backward, 1 forward), row m");
          raywave["yarns"][yarn] = entry;
        }
        // Double-layer factors (Eq. S.20): warp over weft seen from the front, weft over warp
        // from the back.
        const PlySimResult& warp_sim = yarn_tables[0]->raw;
        const PlySimResult& weft_sim = yarn_tables[1] ? yarn_tables[1]->raw : warp_sim;
        const Layer warp_layer{&warp_sim, {1, 0, 0}}, weft_layer{&weft_sim, {0, 1, 0}};
        const DoubleLayerSettings dls = double_layer_settings(spec.quality);
        // components.double_layer off: one layer, B_total = B_t and F_total = F_t (k_b = 0,
        // k_f = 1: double_layer_factors.h) and no diffuse part (s = 0), without simulating the
        // second layer.
        const bool two_layers = spec.components.double_layer;
        json dl = {{"theta_count", dls.theta_count},
                   {"phi_count", dls.phi_count},
                   {"sigma_per_mm", warp_sim.settings.sigmas},
                   {"blend", two_layers ? spec.double_layer_blend : 0.0},
                   {"mode", two_layers ? "tables" : "off"},
                   {"files", {{"front", "double_layer_front"}, {"back", "double_layer_back"}}},
                   {"layout",
                    "B_t, F_t, B_total, F_total (Eq. S.20) per direction xi towards the light: "
                    "column p at azimuth (p + 0.5) 360 / phi_count deg, row k theta_count + t at "
                    "level sigma_k and angle from the normal (t + 0.5) 90 / theta_count deg; the "
                    "back table takes xi mirrored to +z"}};
        if (opt.progress) opt.progress("double layer", 0.0);
        for (int side = 0; side < 2; ++side) {
          DoubleLayerTable t;
          if (two_layers) {
            t = side == 0 ? double_layer_table(warp_layer, weft_layer, dls)
                          : double_layer_table(weft_layer, warp_layer, dls);
          } else {
            t.settings = dls;
            t.sigmas = warp_sim.settings.sigmas;
            t.values.assign(t.sigmas.size() * size_t(dls.theta_count * dls.phi_count),
                            DoubleLayerFactors{1, 1, 1, 1, 1, 1});
          }
          const int K = int(t.values.size()) / (dls.theta_count * dls.phi_count);
          Image img(dls.phi_count, dls.theta_count * K, 4);
          for (int row = 0; row < dls.theta_count * K; ++row)
            for (int c = 0; c < dls.phi_count; ++c) {
              const DoubleLayerFactors& f = t.values[size_t(row * dls.phi_count + c)];
              float* px = img.px(c, row);
              px[0] = float(f.Bt), px[1] = float(f.Ft), px[2] = float(f.Btotal), px[3] = float(f.Ftotal);
            }
          add_table(img, side == 0 ? "double_layer_front" : "double_layer_back",
                    {"B_t", "F_t", "B_total", "F_total"},
                    "double-layer reflection and transmission factors (layout: manifest "
                    "raywave.double_layer.layout)");
          if (opt.progress) opt.progress("double layer", 0.5 * (side + 1));
        }
        raywave["double_layer"] = dl;

        // Aperture diffraction (section 4) through the gaps and past the ply edges.
        if (spec.wave.diffraction) {
          if (opt.progress) opt.progress("diffraction", 0.0);
          const auto dt0 = std::chrono::steady_clock::now();
          const DiffractionSettings ds = diffraction_settings(spec.quality);
          const SpectralRgb srgb = spectral_rgb(cc, ds.step_nm);
          const double w0 = spec.wave.beam_waist_um;
          const auto gap = gap_widths(spec);
          json dif = {{"mode", "tables"},
                      {"beam_waist_um", w0},
                      {"d_cut_um", LOOM_DIFFRACTION_DCUT_WAISTS * w0},
                      {"s_max", LOOM_DIFFRACTION_S_MAX},
                      {"tile_size", ds.size},
                      {"lambda_nm", {kLambdaMinNm, kLambdaMaxNm, ds.step_nm}},
                      {"gap_um", {gap[0], gap[1]}},
                      {"files", {{"edge", "diffraction_edge"}}},
                      {"edge_tiles", ds.edge_tiles},
                      {"layout",
                       "RGB D_c(s) per unit incident power and solid angle (Eq. S.35 without the "
                       "obliquity factor), tiles of tile_size^2 texels: texel (u, r) of a tile at "
                       "|s_x| = s_max (u / (tile_size - 1))^2, |s_y| likewise with row r counted "
                       "from the bottom (v = 0) (osl/include/loom/diffraction_table.h); gap tiles: column block i, row block "
                       "j hold the beam centre offset (1 - (1 - (i, j) / (gap_offsets - 1))^2) gap_um "
                       "/ 2 from the hole's centre; edge tiles: column block j holds x_w / d_cut = j / "
                       "(edge_tiles - 1) (baker/include/loom/diffraction_tables.h)"}};
          const auto to_image = [](const DiffractionTable& t) {
            Image img(t.width(), t.height(), 3);
            std::copy(t.rgb.begin(), t.rgb.end(), img.data.begin());
            return img;
          };
          add_table(to_image(diffraction_edge_table(w0, srgb, ds)), "diffraction_edge",
                    {"r", "g", "b"}, "ply-edge aperture diffraction (section 4.3; layout: manifest "
                    "raywave.diffraction.layout)");
          if (spec.components.gaps && gap[0] > 0 && gap[1] > 0) {
            const DiffractionTable gap_table = diffraction_gap_table(gap[0], gap[1], w0, srgb, ds);
            add_table(to_image(gap_table), "diffraction_gap", {"r", "g", "b"},
                      "gap aperture diffraction (section 4.1-4.2; layout: manifest "
                      "raywave.diffraction.layout)");
            dif["files"]["gap"] = "diffraction_gap";
            dif["gap_offsets"] = ds.gap_offsets;
            // What the shaders sample at render time (osl/include/loom/diffraction_sampling.h).
            const double spot = diffraction_spot_radius(w0);
            const DiffractionSampling samp = diffraction_sampling_table(gap_table, spot);
            Image simg(samp.width, samp.height, 3);
            std::copy(samp.rgb.begin(), samp.rgb.end(), simg.data.begin());
            add_table(simg, "diffraction_gap_sampling", {"r", "g", "b"},
                      "inverse CDFs of the gap diffraction outside the central spot, and the "
                      "power there (layout: osl/include/loom/diffraction_sampling.h)");
            dif["files"]["gap_sampling"] = "diffraction_gap_sampling";
            dif["spot_s"] = spot;
            dif["gap_p_out"] = samp.p_out;  // per tile (row-major from offset (0, 0)), RGB
            dif["gap_fraction"] = {gap[0] * spec.weft_per_cm * 1e-4, gap[1] * spec.warp_per_cm * 1e-4};
          } else {
            dif["gap_absent"] = spec.components.gaps ? "the yarns touch: no open gaps"
                                                     : "components.gaps is off";
          }
          dif["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - dt0).count();
          raywave["diffraction"] = dif;
          if (opt.progress) opt.progress("diffraction", 1.0);
        } else {
          raywave["diffraction"] = {
              {"mode", "delta"},
              {"reason", "wave.diffraction is off: delta transmission (the non-wave variant)"}};
        }

        // Speckle noise tiles (section 5): reflection and higher-order scattering.
        if (spec.wave.noise) {
          if (opt.progress) opt.progress("noise", 0.0);
          const auto nt0 = std::chrono::steady_clock::now();
          const NoiseSettings ns = noise_settings(spec.quality);
          json noise = {{"theta_count", ns.theta_count},
                        {"instances", ns.instances},
                        {"band_nm", kNoiseBandsNm},
                        {"width_um", spec.wave.speckle_width_um},
                        {"segments_per_repeat", LOOM_NOISE_SEGMENTS_PER_REPEAT},
                        {"levels", LOOM_NOISE_LEVELS},
                        {"level_blur_rad", [] {
                           json b = json::array();
                           for (int l = 0; l < LOOM_NOISE_LEVELS; ++l)
                             b.push_back(shading::noise_level_blur(l));
                           return b;
                         }()},
                        {"psd", "P_1D(lambda; f) = exp(-2 (lambda f / width_um)^2), f in cycles "
                                "per radian (baker/include/loom/speckle_noise.h)"},
                        {"files", {{"refl", "noise_refl"}, {"high", "noise_high"}}},
                        {"layout",
                         "RGB = N_2D (Eq. S.38) at band_nm; u = (phi_o + pi) / 2 pi, periodic; "
                         "level l, instance j's rows (from the bottom) (l instances + j) "
                         "theta_count ... (l instances + j + 1) theta_count - 1 span theta_o "
                         "from -pi/2 to pi/2, ply space; level 0 the tile, level l blurred by "
                         "level_blur_rad[l] (osl/include/loom/speckle_noise.h)"}};
          int k = 0;
          for (const char* which : {"refl", "high"}) {
            const Image tile = speckle_noise_levels(
                speckle_noise_tile(ns, spec.wave.speckle_width_um, kNoiseSeed + uint64_t(k)), ns);
            // Half floats: the noise needs no more than 3 significant digits, and it is the
            // largest table of the atlas.
            add_table(tile, std::string("noise_") + which, {"n_r", "n_g", "n_b"},
                      std::string("speckle noise tile for ") +
                          (k == 0 ? "surface reflection (looked up at the memory-effect "
                                    "direction, Eq. S.40)"
                                  : "higher-order scattering (looked up at w_o)") +
                          "; layout: manifest raywave.noise.layout",
                      true, "periodic");
            ++k;
            if (opt.progress) opt.progress("noise", 0.5 * k);
          }
          noise["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - nt0).count();
          raywave["noise"] = noise;
        } else {
          raywave["noise"] = {{"files", json::object()},
                              {"reason", "wave.noise is off: the mean scattering, unmodulated"}};
        }
        const auto ct0 = std::chrono::steady_clock::now();
        for (int i = 0; i < 2; ++i) {
          const int src = yarn_tables[i] ? i : 0;
          if (!curves[src])
            curves[src] = absorption_curve(src == 0 ? spec.warp : spec.weft, spec.quality);
          curves[i] = curves[src];
          sigma_max[i] = yarn_tables[src]->sim.sigmas.back();
        }
        raywave["absorption_curve_seconds"] =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - ct0).count();
      }
      raywave["simulation_key"] = sim_key;
      // Colour from absorption (section 6, Eq. S.42): each yarn's colour through its ply's
      // simulated sigma -> energy curve (computed above, or reused).
      {
        if (opt.progress) opt.progress("absorption", 0.0);
        const auto at0 = std::chrono::steady_clock::now();
        const SpectralUpsampler up(cc, 5.0);
        for (int i = 0; i < 2; ++i) {
          const char* yarn = i == 0 ? "warp" : "weft";
          const AbsorptionCurve& curve = *curves[i];
          const AbsorptionFit fit = fit_absorption(curve);
          const YarnSpec& y = i == 0 ? spec.warp : spec.weft;
          const YarnAbsorption ya = yarn_absorption(y.color_linear, up, fit, curve, sigma_max[i]);
          raywave["yarns"][yarn]["absorption"] = {
              {"colour_linear", y.color_linear},
              {"sigmoid_coeffs", ya.spectrum.coeffs},
              {"lambda_nm", ya.lambda_nm},
              {"sigma_per_mm", ya.sigma_per_mm},
              {"sigma_rgb_per_mm", ya.sigma_rgb},
              {"rgb_spectrum", ya.rgb_spectrum},
              {"rgb_ply", ya.rgb_ply},
              {"s42", {{"a_mm", fit.a},
                       {"b", fit.b},
                       {"rms_log_error", fit.rms_log_error},
                       {"sigma_per_mm", ya.sigma_s42_per_mm},
                       {"rgb_ply", ya.rgb_s42}}},
              {"curve", {{"sigma_per_mm", curve.sigma_per_mm},
                         {"energy", curve.energy},
                         {"rays", curve.rays}}},
              {"notes", "sigma(lambda) maps the sigmoid spectrum (Jakob and Hanika 2019) of the "
                        "yarn colour through the ply's simulated wide-beam sigma -> energy curve "
                        "at theta_i = 0; s42 is the text's exponential fit (Eq. S.42) for "
                        "comparison (baker/include/loom/absorption.h)"}};
        }
        raywave["absorption_seconds"] =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - at0).count();
      }
      // Render tables at the yarn colours (ray-wave shading: osl/include/loom/raywave_lobes.h,
      // double_layer_factors.h), from the tables just written or copied.
      {
        if (opt.progress) opt.progress("shading tables", 0.0);
        const auto st0 = std::chrono::steady_clock::now();
        auto read_table = [&](const std::string& name) {
          return read_atlas_image(tmp / (name + ".exr"));
        };
        std::array<double, 3> sig[2];
        for (int i = 0; i < 2; ++i) {
          const char* yarn = i == 0 ? "warp" : "weft";
          json& entry = raywave["yarns"][yarn];
          for (int c = 0; c < 3; ++c)
            sig[i][size_t(c)] = entry["absorption"]["sigma_rgb_per_mm"][size_t(c)].get<double>();
          const Image nodes = read_table(entry["files"]["high"].get<std::string>());
          const Image scale = read_table(entry["files"]["high_scale"].get<std::string>());
          const Image high_res = read_table(entry["files"]["high_residual"].get<std::string>());
          const Image refl_nodes = read_table(entry["files"]["refl"].get<std::string>());
          const Image refl_res = read_table(entry["files"]["refl_residual"].get<std::string>());
          const AsgTable high = asg_table_from_images(entry, "high", nodes, &scale, &high_res);
          const AsgTable refl = asg_table_from_images(entry, "refl", refl_nodes, nullptr, &refl_res);
          const std::string name = std::string("ply_tint_") + yarn;
          add_table(ply_tint_image(high, sig[i]), name, {"s_r", "s_g", "s_b"},
                    "f_high lobe amplitude scale (Eq. S.10, S.11) at the yarn's absorption per "
                    "colour channel per corner node, column lobe (N' + 1) + h node, row theta_i node "
                    "(osl/include/loom/raywave_lobes.h)");
          entry["files"]["tint"] = name;
          const std::string rname = std::string("ply_residual_") + yarn;
          add_table(ply_residual_rgb_image(high, refl, sig[i]), rname, {"r", "g", "b"},
                    "energy residual of f_refl + f_high (baker/include/loom/asg_residual.h) at the "
                    "yarn's absorption per colour channel, column side N + n, row m "
                    "(osl/include/loom/raywave_lobes.h: raywave_residual_uv)");
          entry["files"]["residual"] = rname;
        }
        std::array<double, 3> sig_layers;
        for (int c = 0; c < 3; ++c)
          sig_layers[size_t(c)] = 0.5 * (sig[0][size_t(c)] + sig[1][size_t(c)]);
        const json& dl = raywave["double_layer"];
        json shading = {{"factors", json::object()},
                        {"factors_layout", kLayerFactorsLayout},
                        {"microfacet_albedo", "microfacet_albedo"},
                        {"layer_sigma_rgb_per_mm", sig_layers},
                        // Eq. S.10's weight between absorption levels (absorption_curve.h).
                        {"sigma_interpolation", kSigmaInterpolation}};
        for (const char* side : {"front", "back"}) {
          DoubleLayerGrid g;
          g.table = read_table(dl["files"][side].get<std::string>());
          g.theta_count = dl["theta_count"];
          g.phi_count = dl["phi_count"];
          g.sigmas = dl["sigma_per_mm"].get<std::vector<double>>();
          g.absorption = layer_absorption_curve(raywave);
          const std::string name = std::string("layer_factors_") + side;
          add_table(layer_factors_image(g, sig_layers), name, {"r", "g", "b"},
                    "per-point double-layer factors k_b = (B_total - B_t) / F_t, k_f = F_total / "
                    "F_t (Eq. S.20-S.22) at the yarns' absorption, two blocks of phi_count + 2 "
                    "columns "
                    "(osl/include/loom/double_layer_factors.h)");
          shading["factors"][side] = name;
        }
        if (!textures.contains("microfacet_albedo")) {  // (copied on a colour-only change)
          add_table(microfacet_albedo_image(), "microfacet_albedo", {"E_reflect", "E_refract", "0"},
                    "directional albedos of Cycles' Beckmann reflection and refraction closures "
                    "over (cos(N, V), sqrt(alpha)) (osl/include/loom/raywave_lobes.h)");
        }
        shading["seconds"] =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - st0).count();
        raywave["shading"] = shading;
        if (opt.progress) opt.progress("shading tables", 1.0);
      }
    }
    for (auto& [name, t] : textures.items()) {
      t["sha256"] = sha256_file(tmp / t["file"].get<std::string>());
      t["node_sha256"] = sha256_file(tmp / t["node_file"].get<std::string>());
    }
    json manifest = {
        {"schema", kAtlasSchema},
        {"baker_version", kBakerVersion},
        {"spec_sha256", spec_hash},
        {"bake_key", bake_key},
        {"spec", canon},
        {"tier", to_string(spec.tier)},
        {"quality", to_string(spec.quality)},
        {"repeat",
         {{"warp_yarns", maps.warp_yarns},
          {"weft_yarns", maps.weft_yarns},
          {"size_um", {maps.repeat_um[0], maps.repeat_um[1]}}}},
        {"texels_per_cell", texels_per_cell(spec.quality)},
        {"colour", cc.describe()},
        {"yarn_colours_linear", {{"warp", spec.warp.color_linear}, {"weft", spec.weft.color_linear}}},
        {"conventions",
         {{"frame", "tangent frame: x along the warp (u), y along the weft (v), z the normal"},
          {"rows", "row 0 of every file is the top (v = 1); Blender's v = 0 is the bottom"},
          {"uv", "one weave repeat spans uv [0,1)^2; shaders wrap uv themselves"}}},
        {"textures", textures}};
    if (!raywave.is_null()) manifest["raywave"] = raywave;
    {
      std::ofstream out(tmp / "manifest.json");
      out << manifest.dump(2) << "\n";
      if (!out) throw std::runtime_error("writing manifest.json failed");
    }
    // Publish: rename into place, or atomically exchange with an older atlas and remove it.
    if (::rename(tmp.c_str(), dir.c_str()) != 0) {
      if (errno != EEXIST && errno != ENOTEMPTY)
        throw std::runtime_error(fmt::format("cannot publish {}: {}", dir.string(),
                                             std::strerror(errno)));
      json other;
      if (!opt.force && validate_atlas(dir, &other).empty() &&
          string_field(other, "bake_key") == bake_key) {
        fs::remove_all(tmp);  // a concurrent bake of the same spec won the race
        res.reused = true;
      } else {
        if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, dir.c_str(), RENAME_EXCHANGE) != 0)
          throw std::runtime_error(fmt::format("cannot replace {}: {}", dir.string(),
                                               std::strerror(errno)));
        fs::remove_all(tmp);  // now holds the old atlas
      }
    }
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  res.bytes = dir_bytes(dir);
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

const Image& Atlas::map(const std::string& name) const {
  for (size_t k = 0; k < names.size(); ++k)
    if (names[k] == name) return images[k];
  throw std::runtime_error("atlas has no map " + name);
}

Atlas load_atlas(const fs::path& dir) {
  // The node files' bytes validation hashed are the ones decoded: no second read.
  json manifest;
  std::map<std::string, AtlasFile> node_files;
  auto errors = validate_atlas_files(dir, &manifest, &node_files);
  if (!errors.empty()) {
    std::string msg = fmt::format("{} is not a valid atlas:", dir.string());
    for (auto& e : errors) msg += "\n  " + e;
    throw std::runtime_error(msg);
  }
  return atlas_from_files(dir, std::move(manifest), std::move(node_files));
}

std::vector<std::string> validate_atlas(const fs::path& dir, json* manifest_out,
                                        std::map<std::string, AtlasFile>* node_files) {
  return validate_atlas_files(dir, manifest_out, node_files);
}

Atlas atlas_from_files(const fs::path& dir, json manifest,
                       std::map<std::string, AtlasFile> node_files) {
  Atlas a;
  a.manifest = std::move(manifest);
  for (auto& [name, t] : a.manifest["textures"].items()) {
    Image img;
    try {
      const auto it = node_files.find(name);
      if (it == node_files.end())
        throw std::runtime_error("its node_file was not read (validate the atlas first)");
      img = read_atlas_image(it->second);
      it->second.bytes = std::string();  // each file's bytes are let go once decoded
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(fmt::format("{}: textures.{}: {}", dir.string(), name, e.what()));
    }
    if (name == "albedo_lut") {
      a.albedo_lut = std::move(img);
    } else {
      a.names.push_back(name);
      a.images.push_back(std::move(img));
    }
  }
  return a;
}

}  // namespace loom
