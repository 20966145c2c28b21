// Atlases that must be refused, with a message naming the field or file: textures corrupted
// behind a matching hash, path fields that leave the atlas directory, symbolic links, and
// ray-wave manifests whose fields have the wrong type (validate_atlas's contract, atlas.h).
#include <fmt/format.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "loom/atlas.h"
#include "loom/raywave_bsdf.h"
#include "test_util.h"

namespace fs = std::filesystem;
using nlohmann::json;
using loom::test::copy_atlas_dir;
using loom::test::draft_atlas;
using loom::test::edit_atlas_manifest;

namespace {

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& e : v) s += e + "\n";
  return s;
}

bool has(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

/// The message of the std::runtime_error that load_atlas (and, for ray-wave atlases,
/// load_raywave) throws for `dir`; "" and a test failure if it loads.
std::string load_error(const fs::path& dir) {
  try {
    const loom::Atlas a = loom::load_atlas(dir);
    if (a.manifest.value("tier", "") == "raywave") (void)loom::load_raywave(a);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  ADD_FAILURE() << dir << " loaded";
  return "";
}

/// Sets the manifest's hash of texture `name`'s `key` file to the file's current sha256.
void rehash(const fs::path& dir, const std::string& name, const std::string& key) {
  edit_atlas_manifest(dir, [&](json& m) {
    json& t = m["textures"][name];
    t[key == "file" ? "sha256" : "node_sha256"] =
        loom::sha256_file(dir / t[key].get<std::string>());
  });
}

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::string& b) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << b;
}

}  // namespace

TEST(AtlasRejection, CorruptedTextureBehindAMatchingHashFailsToLoadNamingTheFile) {
  const fs::path& plain = draft_atlas("plain", "surface");
  const std::string file = "ply_frame.exr";
  const std::string bytes = read_bytes(plain / file);
  ASSERT_GT(bytes.size(), 1000u);
  struct Variant {
    const char* what;
    std::string bytes;
  } variants[] = {
      {"truncated to half", bytes.substr(0, bytes.size() / 2)},
      {"truncated after the header", bytes.substr(0, 400)},
      {"truncated to 8 bytes", bytes.substr(0, 8)},
      {"empty", ""},
      {"pixel data overwritten", [&] {
         std::string b = bytes;
         for (size_t k = b.size() / 2; k < b.size() / 2 + 256; ++k) b[k] = char(0x5a);
         return b;
       }()},
      {"last bytes overwritten", [&] {
         std::string b = bytes;
         for (size_t k = b.size() - 64; k < b.size(); ++k) b[k] = char(~b[k]);
         return b;
       }()},
      {"not an image", std::string(bytes.size(), 'x')},
  };
  for (const auto& v : variants) {
    const fs::path d = copy_atlas_dir(plain, "corrupt_behind_hash.atlas");
    write_bytes(d / file, v.bytes);
    rehash(d, "ply_frame", "node_file");
    const std::string e = load_error(d);
    EXPECT_TRUE(has(e, (d / file).string())) << v.what << ": " << e;
    EXPECT_TRUE(has(e, "ply_frame")) << v.what << ": " << e;
  }
  // The tiled texture's header is read by validation: a truncated one is refused there.
  for (size_t keep : {size_t(0), size_t(8), size_t(100)}) {
    const fs::path d = copy_atlas_dir(plain, "corrupt_tx_behind_hash.atlas");
    write_bytes(d / "ply_frame.tx", read_bytes(plain / "ply_frame.tx").substr(0, keep));
    rehash(d, "ply_frame", "file");
    const std::string e = joined(loom::validate_atlas(d));
    EXPECT_TRUE(has(e, "textures.ply_frame: " + (d / "ply_frame.tx").string())) << keep << ": " << e;
  }
}

TEST(AtlasRejection, AnImageOfAnotherFormatOrSizeBehindAMatchingHashIsRefused) {
  const fs::path& plain = draft_atlas("plain", "surface");
  // A valid image of the wrong size, written by the baker's own writer.
  fs::path d = copy_atlas_dir(plain, "resized.atlas");
  loom::write_atlas_map(loom::Image(3, 5, 4), d, "ply_frame", true, "periodic");
  rehash(d, "ply_frame", "node_file");
  rehash(d, "ply_frame", "file");
  std::string e = joined(loom::validate_atlas(d));
  EXPECT_TRUE(has(e, "ply_frame.exr is 3x5x4, the manifest says otherwise")) << e;
  // The TIFF texture's bytes under the OpenEXR name: only OpenEXR is read for a node file.
  d = copy_atlas_dir(plain, "tiff_as_exr.atlas");
  fs::copy_file(d / "ply_frame.tx", d / "ply_frame.exr", fs::copy_options::overwrite_existing);
  rehash(d, "ply_frame", "node_file");
  e = joined(loom::validate_atlas(d));
  EXPECT_TRUE(has(e, (d / "ply_frame.exr").string() + ": not an OpenEXR file the baker writes: "
                                                      "not an OpenEXR file (no magic number)"))
      << e;
}

TEST(AtlasRejection, ExrHeadersTheBakerNeverWritesAreRefusedBeforeOpenExrReadsThem) {
  // OpenEXR allocates what a header declares before reading it; read_atlas_image checks the
  // header's bytes first (atlas.cpp: exr_header_problem). Each edit of a baked node file:
  const fs::path& plain = draft_atlas("plain", "surface");
  const std::string bytes = read_bytes(plain / "ply_frame.exr");
  // The offset of the value of the attribute `name` of type `type`.
  const auto value_of = [&](const char* name, const char* type) {
    const std::string key = std::string(name) + '\0' + type + '\0';
    const size_t k = bytes.find(key);
    EXPECT_NE(k, std::string::npos) << name;
    return k + key.size() + 4;
  };
  const auto put32 = [](std::string& b, size_t k, uint32_t v) {
    for (int j = 0; j < 4; ++j) b[k + size_t(j)] = char((v >> (8 * j)) & 0xff);
  };
  const size_t date = value_of("capDate", "string"), window = value_of("dataWindow", "box2i");
  struct Edit {
    const char* what;
    std::function<void(std::string&)> edit;
    const char* message;
  } edits[] = {
      {"tiled flag", [&](std::string& b) { b[5] = char(b[5] | 0x02); }, "tiled, deep or multi-part"},
      {"multi-part flag", [&](std::string& b) { b[5] = char(b[5] | 0x10); },
       "tiled, deep or multi-part"},
      {"version 1", [&](std::string& b) { b[4] = 1; }, "OpenEXR version 1"},
      {"a 450 MB attribute", [&](std::string& b) { put32(b, date - 4, 0x1b000013); },
       "\"capDate\" declares 452984851 bytes"},
      {"a negative attribute size", [&](std::string& b) { put32(b, date - 4, 0xffffffff); },
       "\"capDate\" declares -1 bytes"},
      {"a data window of 100000 columns", [&](std::string& b) { put32(b, window + 8, 99999); },
       "data window 100000 x 32"},
      {"an inverted data window", [&](std::string& b) { put32(b, window + 8, 0xfffffff0); },
       "data window -15 x 32"},
      {"DWAA compression",
       [&](std::string& b) { b[value_of("compression", "compression")] = 8; },
       "not a lossless one"},
      {"a preview attribute",
       [&](std::string& b) {
         b.replace(date - 4 - 15, 15, std::string("capDat\0preview\0", 15));
       },
       "\"capDat\" of type preview"},
      {"cut in the header",
       [&](std::string& b) { b.resize(value_of("screenWindowWidth", "float")); },
       "\"screenWindowWidth\" declares 4 bytes"},
  };
  for (const auto& ed : edits) {
    std::string b = bytes;
    ed.edit(b);
    const fs::path p = loom::test::scratch("exr_header") / "t.exr";
    fs::create_directories(p.parent_path());
    write_bytes(p, b);
    try {
      (void)loom::read_atlas_image(p);
      ADD_FAILURE() << ed.what << ": read";
    } catch (const std::runtime_error& e) {
      EXPECT_TRUE(has(e.what(), p.string() + ": not an OpenEXR file the baker writes"))
          << ed.what << ": " << e.what();
      EXPECT_TRUE(has(e.what(), ed.message)) << ed.what << ": " << e.what();
    }
  }
  // The file as baked reads.
  const fs::path p = loom::test::scratch("exr_header_ok") / "t.exr";
  fs::create_directories(p.parent_path());
  write_bytes(p, bytes);
  EXPECT_EQ(loom::read_atlas_image(p).width, 32);
}

TEST(AtlasRejection, NonFiniteRaywaveTableBehindAMatchingHashIsRefusedNamingTheTable) {
  const fs::path& rw = draft_atlas("plain", "raywave");
  const fs::path d = copy_atlas_dir(rw, "nan_table.atlas");
  const json m = json::parse(std::ifstream(d / "manifest.json"));
  const std::string high = m["raywave"]["yarns"]["warp"]["files"]["high"];
  loom::Image img = loom::read_atlas_image(d / (high + ".exr"));
  img.data[5] = std::numeric_limits<float>::quiet_NaN();
  loom::write_atlas_map(img, d, high, false, "clamp");
  rehash(d, high, "node_file");
  rehash(d, high, "file");
  ASSERT_TRUE(loom::validate_atlas(d).empty()) << joined(loom::validate_atlas(d));
  const std::string e = load_error(d);
  EXPECT_TRUE(has(e, "high nodes: non-finite lobe parameter")) << e;
}

TEST(AtlasRejection, PathFieldsLeavingTheAtlasAreRefusedNamingTheField) {
  const fs::path& plain = draft_atlas("plain", "surface");
  const json bad_names[] = {"../ply_frame.exr", "../../../etc/passwd", "/etc/passwd",
                            (plain / "ply_frame.exr").string(), "sub/ply_frame.exr", "..", ".",
                            "", "a\\b.exr", std::string("ply_frame.exr\0x", 15), 42, nullptr,
                            json::array({"ply_frame.exr"})};
  for (const char* key : {"file", "node_file"})
    for (const json& bad : bad_names) {
      const fs::path d = copy_atlas_dir(plain, "escape.atlas");
      edit_atlas_manifest(d, [&](json& m) { m["textures"]["ply_frame"][key] = bad; });
      const auto errors = loom::validate_atlas(d);
      const std::string e = joined(errors);
      EXPECT_TRUE(has(e, fmt::format("textures.ply_frame.{}: must be a plain file name inside "
                                     "the atlas directory",
                                     key)))
          << key << " = " << bad.dump() << ": " << e;
      EXPECT_TRUE(has(load_error(d), "textures.ply_frame." + std::string(key)));
    }
  // Every other field naming a file of a ray-wave atlas names it by its texture's key: a path
  // there is no texture of the atlas.
  const fs::path& rw = draft_atlas("plain", "raywave");
  const std::vector<std::pair<json::json_pointer, std::string>> refs = {
      {json::json_pointer("/raywave/yarns/warp/files/high"), "raywave.yarns.warp.files.high"},
      {json::json_pointer("/raywave/yarns/weft/files/residual"),
       "raywave.yarns.weft.files.residual"},
      {json::json_pointer("/raywave/double_layer/files/front"),
       "raywave.double_layer.files.front"},
      {json::json_pointer("/raywave/shading/factors/back"), "raywave.shading.factors.back"},
      {json::json_pointer("/raywave/shading/microfacet_albedo"),
       "raywave.shading.microfacet_albedo"},
      {json::json_pointer("/raywave/shading/asg_integral"), "raywave.shading.asg_integral"},
      {json::json_pointer("/raywave/noise/files/refl"), "raywave.noise.files.refl"},
      {json::json_pointer("/raywave/diffraction/files/edge"), "raywave.diffraction.files.edge"}};
  for (const auto& [pointer, field] : refs)
    for (const char* bad : {"../../etc/passwd", "/etc/passwd", "ply_frame.exr"}) {
      const json::json_pointer& ptr = pointer;  // a structured binding is not capturable in C++17
      const fs::path d = copy_atlas_dir(rw, "escape_raywave.atlas");
      edit_atlas_manifest(d, [&](json& m) {
        ASSERT_TRUE(m.contains(ptr)) << ptr.to_string();
        m[ptr] = bad;
      });
      const std::string e = joined(loom::validate_atlas(d));
      EXPECT_TRUE(has(e, field + ": not a texture of the atlas")) << field << " = " << bad << ": "
                                                                  << e;
    }
}

TEST(AtlasRejection, SymbolicLinksAreRefusedInsideAndOutside) {
  const fs::path& plain = draft_atlas("plain", "surface");
  // A texture linked to a copy outside the atlas and to one inside it (the same bytes: the hash
  // matches either way).
  for (const bool outside : {true, false}) {
    const fs::path d = copy_atlas_dir(plain, outside ? "link_out.atlas" : "link_in.atlas");
    const fs::path target = outside ? d.parent_path() / "outside_ply_frame.exr"
                                    : d / "ply_frame_copy.exr";
    fs::remove(target);
    fs::rename(d / "ply_frame.exr", target);
    fs::create_symlink(outside ? target : fs::path("ply_frame_copy.exr"), d / "ply_frame.exr");
    ASSERT_EQ(loom::sha256_file(d / "ply_frame.exr"), loom::sha256_file(target));
    const std::string e = joined(loom::validate_atlas(d));
    EXPECT_TRUE(has(e, "textures.ply_frame.node_file: " + (d / "ply_frame.exr").string() +
                           " is a symbolic link"))
        << e;
    EXPECT_TRUE(has(load_error(d), "is a symbolic link"));
  }
  // A linked manifest.json, to the very manifest it was.
  {
    const fs::path d = copy_atlas_dir(plain, "link_manifest.atlas");
    const fs::path real = d.parent_path() / "real_manifest.json";
    fs::remove(real);
    fs::rename(d / "manifest.json", real);
    fs::create_symlink(real, d / "manifest.json");
    const std::string e = joined(loom::validate_atlas(d));
    EXPECT_TRUE(has(e, "manifest.json: is a symbolic link")) << e;
  }
  // A directory where a texture should be.
  {
    const fs::path d = copy_atlas_dir(plain, "dir_texture.atlas");
    fs::remove(d / "ply_frame.exr");
    fs::create_directory(d / "ply_frame.exr");
    const std::string e = joined(loom::validate_atlas(d));
    EXPECT_TRUE(has(e, "ply_frame.exr is missing (not a regular file)")) << e;
  }
  // Choice: the atlas directory itself may be reached through a link.
  const fs::path link = loom::test::scratch("linked_dir.atlas");
  fs::create_directory_symlink(plain, link);
  EXPECT_TRUE(loom::validate_atlas(link).empty()) << joined(loom::validate_atlas(link));
}

TEST(AtlasRejection, FilesLargerThanTheCapAreRefusedBeforeTheyAreRead) {
  // A review finding (stop 26, never observed): a manifest naming a huge or sparse file made
  // validate_atlas allocate its whole size (std::bad_alloc, an exception the readers must not
  // throw). read_atlas_file refuses anything above kMaxAtlasFileBytes by its size, before any
  // allocation: here a sparse file one byte over the cap (no disk used) in place of a map.
  const fs::path d = copy_atlas_dir(draft_atlas("plain", "surface"), "too_large.atlas");
  const fs::path big = d / "ply_frame.exr";
  fs::remove(big);
  {
    const int fd = ::open(big.c_str(), O_CREAT | O_WRONLY, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::ftruncate(fd, off_t(loom::kMaxAtlasFileBytes + 1)), 0);
    ::close(fd);
  }
  try {
    (void)loom::read_atlas_file(d, "ply_frame.exr");
    ADD_FAILURE() << "a file over the cap was read";
  } catch (const loom::AtlasFileError& e) {
    EXPECT_EQ(int(e.kind), int(loom::AtlasFileError::Kind::Unreadable));
    EXPECT_TRUE(has(e.what(), big.string())) << e.what();
    EXPECT_TRUE(has(e.what(), "more than an atlas file may")) << e.what();
  }
  const std::string e = joined(loom::validate_atlas(d));
  EXPECT_TRUE(has(e, "ply_frame.exr") && has(e, "more than an atlas file may")) << e;
  EXPECT_THROW((void)loom::load_atlas(d), std::runtime_error);
}

TEST(AtlasRejection, AtlasFilesAreReadOnceWithoutFollowingLinks) {
  // read_atlas_file: the refusal happens at the read itself (O_NOFOLLOW), not by a check before
  // it, and what is decoded is the bytes read then, whatever the directory holds afterwards.
  using Kind = loom::AtlasFileError::Kind;
  const fs::path d = copy_atlas_dir(draft_atlas("plain", "surface"), "read_once.atlas");
  const auto kind_of = [&](const std::string& name) {
    try {
      (void)loom::read_atlas_file(d, name);
    } catch (const loom::AtlasFileError& e) {
      EXPECT_TRUE(has(e.what(), (d / name).string())) << e.what();
      return int(e.kind);
    }
    return -1;
  };
  fs::create_symlink("ply_frame.exr", d / "link.exr");
  EXPECT_EQ(kind_of("link.exr"), int(Kind::SymbolicLink));
  EXPECT_EQ(kind_of("absent.exr"), int(Kind::Missing));
  fs::create_directory(d / "dir.exr");
  EXPECT_EQ(kind_of("dir.exr"), int(Kind::NotRegular));
  // A FIFO with no writer: refused at once (a blocking open would wait for ever).
  ASSERT_EQ(::mkfifo((d / "fifo.exr").c_str(), 0600), 0);
  EXPECT_EQ(kind_of("fifo.exr"), int(Kind::NotRegular));
  EXPECT_EQ(kind_of("../read_once.atlas"), int(Kind::Unreadable));  // not a plain file name

  // The bytes are the file's, and decoding them reads nothing again: the file is replaced by
  // a link to another map after the read, and the image is still the first file's.
  const loom::AtlasFile f = loom::read_atlas_file(d, "ply_frame.exr");
  {
    std::ifstream in(d / "ply_frame.exr", std::ios::binary);
    const std::string disk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_EQ(f.bytes, disk);
  }
  const loom::Image before = loom::read_atlas_image(d / "ply_frame.exr");
  fs::remove(d / "ply_frame.exr");
  fs::create_symlink("ply_normal.exr", d / "ply_frame.exr");
  const loom::Image after = loom::read_atlas_image(f);
  EXPECT_EQ(after.width, before.width);
  EXPECT_EQ(after.data, before.data);
  EXPECT_NE(loom::read_atlas_image(d / "ply_normal.exr").data, before.data)
      << "the test needs two different maps";
  EXPECT_THROW((void)loom::read_atlas_image(d / "ply_frame.exr"), loom::AtlasFileError);

  // load_atlas's two steps: a map validated, then swapped on disk (here: a link to another map,
  // which validation would refuse), comes out as the map that was validated.
  const fs::path d2 = copy_atlas_dir(draft_atlas("plain", "surface"), "read_once2.atlas");
  nlohmann::json m;
  std::map<std::string, loom::AtlasFile> files;
  ASSERT_EQ(joined(loom::validate_atlas(d2, &m, &files)), "");
  fs::remove(d2 / "ply_frame.exr");
  fs::create_symlink("ply_normal.exr", d2 / "ply_frame.exr");
  ASSERT_FALSE(loom::validate_atlas(d2).empty());
  const loom::Atlas a = loom::atlas_from_files(d2, m, files);
  EXPECT_EQ(a.map("ply_frame").data, before.data);
  EXPECT_NE(a.map("ply_normal").data, before.data);
}

TEST(AtlasRejection, NegativeOffsetsInAFileAreRefused) {
  // OpenEXR refuses a line offset of 0 only, so an offset of 2^64 - 1 reaches the reader as a
  // seek to -1; OpenImageIO 2.4's memory reader would then copy from before its buffer (an
  // AddressSanitizer report here without atlas.cpp's BoundedMemReader). Offsets past the end
  // and before the header are refused as well. Each: an error naming the file, never a read
  // outside the bytes.
  const fs::path d = copy_atlas_dir(draft_atlas("plain", "surface"), "offsets.atlas");
  const loom::AtlasFile good = loom::read_atlas_file(d, "ply_frame.exr");
  const std::string& b = good.bytes;
  // The end of the header: attributes (name, type, int32 size, value) up to a NUL name.
  size_t i = 8;
  while (i < b.size() && b[i] != '\0') {
    const size_t name_end = b.find('\0', i), type_end = b.find('\0', name_end + 1);
    ASSERT_NE(type_end, std::string::npos);
    int32_t size = 0;
    std::memcpy(&size, b.data() + type_end + 1, 4);
    i = type_end + 5 + size_t(size);
  }
  const size_t table = i + 1;  // the line-offset table: one uint64 per chunk
  ASSERT_LT(table + 16, b.size());
  // The first chunk's offset: refused. A later chunk's: OpenEXR reads the chunks in order, and
  // a seek the reader refuses leaves it where the previous chunk ended, so the image may come
  // out whole; either way nothing outside the bytes is read (AddressSanitizer in the sanitizer
  // build) and an error names the file.
  for (const uint64_t bad : {~uint64_t(0), uint64_t(1) << 63, uint64_t(b.size()) + 1000,
                             uint64_t(3)}) {
    for (const size_t chunk : {size_t(0), size_t(1)}) {
      loom::AtlasFile f = good;
      std::memcpy(f.bytes.data() + table + 8 * chunk, &bad, 8);
      try {
        const loom::Image img = loom::read_atlas_image(f);
        EXPECT_NE(chunk, 0u) << "offset " << bad << " of the first chunk was read";
        EXPECT_EQ(img.data.size(), size_t(img.width) * size_t(img.height) * size_t(img.channels));
      } catch (const std::runtime_error& e) {
        EXPECT_TRUE(has(e.what(), good.path.string())) << e.what();
      }
    }
  }
  EXPECT_EQ(loom::read_atlas_image(good).width, loom::atlas_image_header(good)[0]);
}

TEST(AtlasRejection, RaywaveFieldsOfTheWrongTypeAreRefusedNamingTheField) {
  // validate_atlas's contract (atlas.h): the readers never meet a wrong type. Each edit would
  // have reached load_raywave or load_ply_tables as a nlohmann exception or undefined behaviour.
  const fs::path& rw = draft_atlas("plain", "raywave");
  struct Edit {
    const char* pointer;
    json value;  // null: remove the field
    const char* message;
  } edits[] = {
      {"/tier", 1, "tier: expected a string"},
      {"/raywave/yarns/warp/absorption", nullptr, "raywave.yarns.warp.absorption: expected"},
      {"/raywave/yarns/warp/absorption/sigma_rgb_per_mm", json::array({1, 2}),
       "raywave.yarns.warp.absorption.sigma_rgb_per_mm: expected 3 to 3 numbers"},
      {"/raywave/yarns/weft/absorption/sigma_rgb_per_mm/1", "x",
       "raywave.yarns.weft.absorption.sigma_rgb_per_mm"},
      {"/raywave/yarns/warp/absorption/curve", "x", "raywave.yarns.warp.absorption.curve"},
      {"/raywave/yarns/warp/absorption/curve/rays", -1,
       "raywave.yarns.warp.absorption.curve.rays: expected an integer"},
      {"/raywave/yarns/warp/absorption/curve/rays", 1e300,
       "raywave.yarns.warp.absorption.curve.rays: expected an integer"},
      {"/raywave/yarns/warp/yarn", 3, "raywave.yarns.warp.yarn: expected a string"},
      {"/raywave/yarns/warp/high/nrmse", "low", "raywave.yarns.warp.high.nrmse"},
      {"/raywave/yarns/warp/node_layout", 7, "raywave.yarns.warp.node_layout"},
      {"/raywave/double_layer/theta_count", nullptr, "raywave.double_layer.theta_count"},
      {"/raywave/double_layer/theta_count", 2.5, "raywave.double_layer.theta_count"},
      {"/raywave/double_layer/phi_count", 1e300, "raywave.double_layer.phi_count"},
      {"/raywave/double_layer/sigma_per_mm", json::array({0, 0}),
       "raywave.double_layer.sigma_per_mm"},
      {"/raywave/double_layer/blend", "half", "raywave.double_layer.blend"},
      {"/raywave/shading/sigma_interpolation", 0, "raywave.shading.sigma_interpolation"},
      // The double-layer factors of older bakers (B_total / B_t, F_total / F_t, F_total) read as
      // k_b, k_f would render wrong light: refused, with the field named.
      {"/raywave/shading/factors_layout", nullptr,
       "raywave.shading.factors_layout: missing is not this baker's \"k_b,k_f\""},
      {"/raywave/shading/factors_layout", "ratios", "raywave.shading.factors_layout"},
      {"/raywave/diffraction/mode", 5, "raywave.diffraction.mode"},
      {"/raywave/diffraction/tile_size", 0, "raywave.diffraction.tile_size"},
      {"/raywave/diffraction/gap_fraction", json::array({0.1}), "raywave.diffraction.gap_fraction"},
      {"/raywave/diffraction/spot_s", "x", "raywave.diffraction.spot_s"},
      {"/raywave/noise/files/high", nullptr, "raywave.noise.files"},
      {"/raywave/noise/instances", 4294967296LL, "raywave.noise.instances"},
      {"/raywave/noise/theta_count", -3, "raywave.noise.theta_count"},
      {"/raywave/noise/levels", "4", "raywave.noise.levels"},
      {"/repeat/warp_yarns", 0, "repeat.warp_yarns"},
      {"/repeat", nullptr, "repeat.weft_yarns"},
  };
  const json original = json::parse(std::ifstream(rw / "manifest.json"));
  for (const auto& ed : edits) {
    const json::json_pointer ptr(ed.pointer);
    if (!original.contains(ptr) && ed.value.is_null()) {
      ADD_FAILURE() << ed.pointer << " is not in the baked manifest";
      continue;
    }
    const fs::path d = copy_atlas_dir(rw, "wrong_type.atlas");
    edit_atlas_manifest(d, [&](json& m) {
      if (ed.value.is_null())
        m[ptr.parent_pointer()].erase(ptr.back());
      else
        m[ptr] = ed.value;
    });
    std::vector<std::string> errors;
    ASSERT_NO_THROW(errors = loom::validate_atlas(d)) << ed.pointer;
    EXPECT_TRUE(has(joined(errors), ed.message)) << ed.pointer << ": " << joined(errors);
    EXPECT_TRUE(has(load_error(d), ed.message)) << ed.pointer;
  }
}

TEST(AtlasRejection, AveragedClosuresOfAnotherLayoutAreRefusedNamingTheField) {
  // The repeat-averaged closures (average_fit.h): the texture a manifest names must be one of the
  // atlas's, in average_closures.h's layout, and the mean gap a coverage.
  const fs::path& plain = draft_atlas("plain", "surface");
  ASSERT_TRUE(loom::validate_atlas(plain).empty());
  const std::vector<std::pair<std::function<void(json&)>, std::string>> cases = {
      {[](json& m) { m["average"]["texture"] = "no_such_map"; },
       "average.texture: not a texture of the atlas"},
      {[](json& m) { m["average"]["texture"] = "ply_frame"; }, "textures.ply_frame: size"},
      {[](json& m) { m["average"]["texture"] = 7; }, "average.texture: expected a string"},
      {[](json& m) { m["average"]["gap_mean"] = 1.5; }, "average.gap_mean"},
      {[](json& m) { m["average"]["gap_mean"] = -0.1; }, "average.gap_mean"},
      {[](json& m) { m["average"]["gap_mean"] = "half"; }, "average.gap_mean"},
      {[](json& m) { m["average"] = 3; }, "average: expected an object"}};
  for (const auto& [edit, field] : cases) {
    const fs::path d = copy_atlas_dir(plain, "average.atlas");
    edit_atlas_manifest(d, edit);
    const std::string e = joined(loom::validate_atlas(d));
    EXPECT_TRUE(has(e, field)) << field << ": " << e;
    EXPECT_TRUE(has(load_error(d), field.substr(0, field.find(':'))));
  }
}
