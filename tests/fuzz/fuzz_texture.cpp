// libFuzzer target: an atlas's texture files read through OpenImageIO (baker/src/atlas.cpp:
// read_atlas_image, which load_atlas reads every node_file with, and atlas_image_header, which
// validate_atlas reads both files' headers with) on arbitrary bytes.
//
// Each input is written as a scratch "t.exr" and "t.tx". Properties beyond "no crash, no
// sanitizer report": read_atlas_image either returns an image of the sizes the baker writes (1 to
// 4 channels, at most kMaxMapSide x 2 kMaxMapSide, as many floats as texels times channels) or
// throws std::runtime_error whose message names the file; the header reads agree with the image
// for the .exr and obey the same limits for the .tx. Any other exception escapes and is reported
// as a crash.
//
// LOOM_FUZZ_SEED_DIR (scripts/fuzz.sh sets it): the initializer writes seeds there, a tiny map
// and LUT written by the baker's own writer (write_atlas_map: half and float OpenEXR, tiled
// mip-mapped TIFF) and truncated copies of each (tests/fuzz/corpus/texture holds the same).
//
//   build-fuzz/fuzz_texture CORPUS -max_total_time=60   (scripts/fuzz.sh)
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include "loom/atlas.h"

namespace fs = std::filesystem;

namespace {

fs::path dir;

void check(bool ok) {
  if (!ok) std::abort();
}

void write_file(const fs::path& p, const char* data, size_t size) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(data, std::streamsize(size));
  check(bool(f));
}

bool sane(int w, int h, int c) {
  return w >= 1 && h >= 1 && c >= 1 && c <= 4 && w <= loom::kMaxMapSide &&
         h <= 2 * loom::kMaxMapSide;
}

void seeds(const fs::path& out) {
  fs::create_directories(out);
  const fs::path scratch = dir / "seeds";
  fs::create_directories(scratch);
  loom::Image map(4, 2, 4), lut(3, 2, 4);
  for (size_t k = 0; k < map.data.size(); ++k) map.data[k] = float(k) * 0.25f - 1.0f;
  for (size_t k = 0; k < lut.data.size(); ++k) lut.data[k] = float(k) / float(lut.data.size());
  loom::write_atlas_map(map, scratch, "map", true, "periodic");
  loom::write_atlas_map(lut, scratch, "lut", false, "clamp");
  for (const char* name : {"map.exr", "map.tx", "lut.exr", "lut.tx"}) {
    const fs::path src = scratch / name;
    fs::copy_file(src, out / name, fs::copy_options::overwrite_existing);
    std::ifstream in(src, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (size_t cut : {size_t(8), size_t(40), bytes.size() / 2, bytes.size() - 1}) {
      const fs::path t = out / (std::string(name) + ".cut" + std::to_string(cut));
      write_file(t, bytes.data(), std::min(cut, bytes.size()));
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  dir = fs::temp_directory_path() / ("loom_fuzz_texture_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  if (const char* out = std::getenv("LOOM_FUZZ_SEED_DIR")) seeds(out);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const fs::path exr = dir / "t.exr", tx = dir / "t.tx";
  write_file(exr, reinterpret_cast<const char*>(data), size);
  write_file(tx, reinterpret_cast<const char*>(data), size);
  const auto named = [](const std::runtime_error& e, const fs::path& p) {
    check(std::string(e.what()).find(p.string()) != std::string::npos);
  };
  try {
    const loom::Image img = loom::read_atlas_image(exr);
    check(sane(img.width, img.height, img.channels));
    check(img.data.size() == size_t(img.width) * size_t(img.height) * size_t(img.channels));
    const auto h = loom::atlas_image_header(exr);
    check(h[0] == img.width && h[1] == img.height && h[2] == img.channels);
  } catch (const std::runtime_error& e) {
    named(e, exr);
  }
  try {
    const auto h = loom::atlas_image_header(tx);
    check(sane(h[0], h[1], h[2]));
  } catch (const std::runtime_error& e) {
    named(e, tx);
  }
  return 0;
}
