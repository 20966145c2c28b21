// The atlas's files: reading one whole and once (read_atlas_file), decoding it with the one
// OpenImageIO reader its kind allows (OpenEXR node files, maketx's TIFF textures), writing a map
// as both, and the hashes the manifest holds.
#include "loom/atlas_files.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <openssl/evp.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fmt/format.h>
#include <fstream>
#include <memory>
#include <stdexcept>

namespace fs = std::filesystem;
OIIO_NAMESPACE_USING

namespace loom {

namespace {

constexpr const char* kAtlasFileDate = "2000:01:01 00:00:00";

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
  // A fixed date, not the time of the bake, which OpenImageIO would write otherwise: the same
  // spec and baker give the same bytes (scripts/same_atlases.sh compares them).
  spec.attribute("DateTime", kAtlasFileDate);
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
  config.attribute("DateTime", kAtlasFileDate);
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

}  // namespace

bool plain_atlas_file_name(const std::string& f) {
  return !f.empty() && f.find('/') == std::string::npos && f.find('\\') == std::string::npos &&
         f != "." && f != ".." && f.find('\0') == std::string::npos;
}

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
  if (!plain_atlas_file_name(name))
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

}  // namespace loom
