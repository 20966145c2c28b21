// The fuzzers' corpora (tests/fuzz/corpus) as unit tests, so that every seed and every kept
// finding is replayed by the ordinary (and the ASan + UBSan) test run, not only by a fuzzing run:
// the manifest seeds placed in a real baked atlas, with the rejection each one must get, and the
// texture seeds read as the atlas reads its node files.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "loom/atlas.h"
#include "loom/raywave_bsdf.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace {

fs::path corpus_dir() { return loom::test::source_dir() / "tests" / "fuzz" / "corpus"; }

std::vector<fs::path> seeds(const std::string& target) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(corpus_dir() / target))
    if (e.is_regular_file()) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& e : v) s += e + "\n";
  return s;
}

}  // namespace

TEST(FuzzCorpus, ManifestSeedsAreRefusedWithTheirReason) {
  // What each hand-written seed must be refused for (fuzz_manifest's own property is weaker: a
  // message, any message). Seeds kept from fuzzing runs only need a message, or to load.
  const std::map<std::string, std::vector<std::string>> expected = {
      {"escape.json",
       {"textures.ply_frame.file: must be a plain file name inside the atlas directory",
        "textures.ply_frame.node_file: must be a plain file name inside the atlas directory"}},
      {"old_schema.json", {"schema \"loom.atlas/0\" is not supported", "re-bake"}},
      {"empty.json", {"no \"schema\" field"}},
      {"null.json", {"no \"schema\" field"}}};
  const fs::path& baked = loom::test::draft_atlas("plain", "raywave");
  int known = 0;
  for (const fs::path& seed : seeds("manifest")) {
    SCOPED_TRACE(seed.filename().string());
    const fs::path d = loom::test::copy_atlas_dir(baked, "corpus_manifest.atlas");
    fs::copy_file(seed, d / "manifest.json", fs::copy_options::overwrite_existing);
    std::vector<std::string> errors;
    ASSERT_NO_THROW(errors = loom::validate_atlas(d));
    for (const std::string& e : errors) EXPECT_FALSE(e.empty());
    const auto it = expected.find(seed.filename().string());
    if (it != expected.end()) {
      ++known;
      ASSERT_FALSE(errors.empty());
      for (const std::string& part : it->second)
        EXPECT_NE(joined(errors).find(part), std::string::npos) << part << " in\n"
                                                                << joined(errors);
    }
    if (!errors.empty()) continue;
    // Accepted: it loads, or the readers refuse it with a std::runtime_error (nothing else).
    try {
      const loom::Atlas a = loom::load_atlas(d);
      if (a.manifest.value("tier", "") == "raywave") (void)loom::load_raywave(a);
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()), "");
    }
  }
  EXPECT_EQ(known, int(expected.size()));
}

TEST(FuzzCorpus, TextureSeedsReadAsTheBakerWroteThemOrFailNamingTheFile) {
  // map.exr and lut.exr: written by fuzz_texture's initializer through write_atlas_map, texel k
  // (row-major from the bottom row) = k / 4 - 1 (half) and k / 24 (float).
  int whole = 0;
  for (const fs::path& seed : seeds("texture")) {
    SCOPED_TRACE(seed.filename().string());
    const fs::path p =
        loom::test::scratch("corpus_texture") / (seed.extension() == ".tx" ? "t.tx" : "t.exr");
    fs::create_directories(p.parent_path());
    fs::copy_file(seed, p, fs::copy_options::overwrite_existing);
    const std::string name = seed.filename().string();
    if (name == "map.exr" || name == "lut.exr") {
      const loom::Image img = loom::read_atlas_image(p);
      const bool map = name == "map.exr";
      ASSERT_EQ(img.width, map ? 4 : 3);
      ASSERT_EQ(img.height, 2);
      ASSERT_EQ(img.channels, 4);
      for (size_t k = 0; k < img.data.size(); ++k)
        EXPECT_EQ(img.data[k], map ? float(k) * 0.25f - 1.0f : float(k) / 24.0f) << k;
      ++whole;
      continue;
    }
    if (name == "map.tx" || name == "lut.tx") {
      const auto h = loom::atlas_image_header(p);
      EXPECT_EQ(h, (std::array<int, 3>{name == "map.tx" ? 4 : 3, 2, 4}));
      ++whole;
      continue;
    }
    // Truncated copies and kept findings: an image or a std::runtime_error naming the file.
    for (const fs::path& q : {p, fs::path(p).replace_extension(".exr")}) {
      if (q != p) fs::copy_file(p, q, fs::copy_options::overwrite_existing);
      try {
        const loom::Image img = loom::read_atlas_image(q);
        EXPECT_EQ(img.data.size(), size_t(img.width) * img.height * img.channels);
      } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(q.string()), std::string::npos) << e.what();
      }
    }
    if (name.find(".cut") != std::string::npos && name.find("exr") != std::string::npos) {
      EXPECT_THROW(loom::read_atlas_image(p), std::runtime_error) << "a truncated map reads";
    }
  }
  EXPECT_EQ(whole, 4);
}
