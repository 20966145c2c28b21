// libFuzzer target: an atlas's manifest (baker/src/atlas.cpp: validate_atlas, load_atlas) and
// everything the evaluators read from it (ply tables, absorption curves, double-layer grids,
// diffraction and noise tables: baker/src/ply_tables.cpp, raywave_bsdf.cpp) on arbitrary bytes.
//
// A real ray-wave atlas (the plain preset, draft) is baked once into a scratch directory; each
// input replaces its manifest.json, so that mutations of a valid manifest keep its textures and
// their hashes and reach the deep readers. Properties: no crash and no sanitizer report;
// validate_atlas either accepts or names a problem (no empty message) and throws nothing; a
// manifest it accepts loads, and the ray-wave readers either load it or throw
// std::runtime_error (a clear message naming the field), never anything else.
//
// The contract, decided: validate_atlas checks the type of every manifest field the deep readers
// read (and the ranges of the integers they compute with), so that the readers never meet a wrong
// type; an nlohmann::json exception (type_error, out_of_range, ...) or any exception other than
// std::runtime_error escaping validate_atlas, load_atlas or load_raywave is a bug of that check,
// and is not caught here: it reaches libFuzzer as a crash. (The readers are not wrapped in a
// catch that would turn such exceptions into runtime_error: a message from inside nlohmann names
// no field, and a missing key read through a const json is undefined behaviour, not an
// exception, which only the validation can prevent; the fuzz build keeps assertions on, so that
// nlohmann's JSON_ASSERT catches such reads.)
//
//   build-fuzz/fuzz_manifest CORPUS -max_total_time=60   (scripts/fuzz.sh seeds CORPUS with a
//   freshly baked manifest)
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "loom/atlas.h"
#include "loom/bake.h"
#include "loom/raywave_bsdf.h"
#include "loom/spec.h"

namespace fs = std::filesystem;

namespace {
fs::path atlas_dir;
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  atlas_dir = fs::temp_directory_path() / ("loom_fuzz_manifest_" + std::to_string(getpid()));
  fs::remove_all(atlas_dir);
  auto d = loom::preset("plain");
  d["model"]["tier"] = "raywave";
  const loom::SpecResult r = loom::parse_spec(d, "draft");
  if (!r.ok()) std::abort();
  loom::bake_atlas(r.spec, atlas_dir, {});
  // The seed a fuzzing run starts from: LOOM_FUZZ_SEED_OUT names where to copy it.
  if (const char* out = std::getenv("LOOM_FUZZ_SEED_OUT"))
    fs::copy_file(atlas_dir / "manifest.json", out, fs::copy_options::overwrite_existing);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  {
    std::ofstream f(atlas_dir / "manifest.json", std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  nlohmann::json m;
  const std::vector<std::string> errors = loom::validate_atlas(atlas_dir, &m);
  for (const std::string& e : errors)
    if (e.empty()) std::abort();
  if (!errors.empty()) return 0;
  try {
    const loom::Atlas a = loom::load_atlas(atlas_dir);
    if (a.manifest.value("tier", "") == "raywave") (void)loom::load_raywave(a);
  } catch (const std::runtime_error&) {
    // A clear refusal: fine.
  }
  return 0;
}
