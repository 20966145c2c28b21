// Helpers shared by the C++ tests that bake atlases and run loom-bake.
#pragma once
#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "loom/atlas.h"
#include "loom/bake.h"

namespace loom::test {

/// The build directory this test binary belongs to (the binary is tests/loom_tests in it). The
/// paths below are found at run time rather than compiled in, so that no object depends on
/// where the clone is and ccache reuses them from one clone to the next (scripts/build.sh).
inline std::filesystem::path build_dir() {
  return std::filesystem::canonical("/proc/self/exe").parent_path().parent_path();
}

/// The loom-bake of this build: $LOOM_BAKE_EXE, else build_dir()/loom-bake.
inline std::string bake_exe() {
  if (const char* e = std::getenv("LOOM_BAKE_EXE"); e && *e) return e;
  return (build_dir() / "loom-bake").string();
}

/// The source tree: $LOOM_SOURCE_DIR, else the one this build was configured from
/// (CMAKE_HOME_DIRECTORY in build_dir()/CMakeCache.txt).
inline std::filesystem::path source_dir() {
  if (const char* e = std::getenv("LOOM_SOURCE_DIR"); e && *e) return e;
  std::ifstream cache(build_dir() / "CMakeCache.txt");
  const std::string key = "CMAKE_HOME_DIRECTORY:INTERNAL=";
  for (std::string line; std::getline(cache, line);)
    if (line.rfind(key, 0) == 0) return line.substr(key.size());
  throw std::runtime_error("no CMAKE_HOME_DIRECTORY in " + (build_dir() / "CMakeCache.txt").string() +
                           "; set LOOM_SOURCE_DIR");
}

/// A fresh (removed) path under this process's scratch directory.
inline std::filesystem::path scratch(const std::string& name) {
  namespace fs = std::filesystem;
  fs::path p = fs::temp_directory_path() / ("loom_test_" + std::to_string(getpid())) / name;
  fs::remove_all(p);
  fs::create_directories(p.parent_path());
  return p;
}

/// Runs a shell command; returns its exit status and (if `out`) its standard output.
inline int run(const std::string& cmd, std::string* out = nullptr) {
  FILE* p = popen(cmd.c_str(), "r");
  std::string s;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) s.append(buf, n);
  int st = pclose(p);
  if (out) *out = s;
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/// Who bakes a shared atlas: this test binary, in process (under the sanitizers in
/// scripts/test.sh), or the loom-bake that $LOOM_TEST_FIXTURE_BAKE names (scripts/test.sh: the
/// release build's, of the same sources), where one is named. Tests that only read an atlas need
/// not pay for its bake under the sanitizers (a ray-wave draft bake there takes about a minute, a
/// fifth of that in release): the bake's own code runs under them in the tests that bake, ray-wave
/// ones included (PlyTables, RaywaveShading, AtlasCli, Atlas), and each stage that
/// only fixtures run has one fixture baked in process (the plain preset's surface draft, the
/// plain red surface swatch, the plain ray-wave swatch). An atlas of the fixture baker is not
/// this binary's to reuse (bake keys hold the baker's hash): tests of reuse bake their own.
enum class Baker { ThisBinary, Fixture };

/// The atlas of `spec` (a spec document, parsed at `quality`), baked once for all the test
/// processes of a run: into $LOOM_TEST_ATLAS_CACHE/<name> (CTest sets it to the build's
/// test-atlases/; every C++ test is a process of its own), else into scratch(<name>), by `who`
/// (Baker). bake_atlas reuses a valid atlas there only if the same spec was baked by the same
/// baker binary (its bake key holds the binary's hash), so a rebuilt binary bakes afresh;
/// concurrent bakes of one spec leave one valid atlas
/// (AtlasCli.ConcurrentBakesOfOneSpecLeaveOneValidAtlas). Read it, do not change it
/// (copy_atlas_dir for that). `name` must differ for different specs.
inline const std::filesystem::path& shared_atlas(const std::string& name,
                                                 const nlohmann::json& spec,
                                                 const std::string& quality = "draft",
                                                 Baker who = Baker::ThisBinary) {
  static std::map<std::string, std::filesystem::path> baked;
  auto it = baked.find(name);
  if (it != baked.end()) return it->second;
  const loom::SpecResult r = loom::parse_spec(spec, quality);
  if (!r.ok()) throw std::runtime_error("shared_atlas " + name + ": " + r.errors.at(0));
  std::filesystem::path dir;
  // Test processes running at once that share an atlas of the cache bake it once: the others
  // wait on its lock file and then find it baked (bake_atlas reuses a valid atlas of its key).
  struct Lock {
    int fd = -1;
    ~Lock() {
      if (fd >= 0) ::close(fd);  // (closing releases the flock)
    }
  } lock;
  const char* fixture = std::getenv("LOOM_TEST_FIXTURE_BAKE");
  const bool by_fixture = who == Baker::Fixture && fixture && *fixture;
  if (const char* cache = std::getenv("LOOM_TEST_ATLAS_CACHE"); cache && *cache) {
    std::filesystem::create_directories(cache);
    // (one folder per baker: each would replace the other's atlas, of another bake key)
    dir = std::filesystem::path(cache) / (by_fixture ? name + ".fixture" : name);
    lock.fd = ::open((dir.string() + ".lock").c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
    if (lock.fd >= 0) ::flock(lock.fd, LOCK_EX);
  } else {
    dir = scratch(name);
  }
  if (by_fixture) {
    const std::string spec_file = dir.string() + ".spec.json";
    std::ofstream(spec_file) << spec.dump();
    std::string out;
    if (run(std::string(fixture) + " bake " + spec_file + " --quality " + quality +
                " --progress=none -o " + dir.string() + " 2>&1",
            &out) != 0)
      throw std::runtime_error("shared_atlas " + name + ": " + fixture + " failed: " + out);
  } else {
    loom::bake_atlas(r.spec, dir, {});
  }
  return baked.emplace(name, dir).first->second;
}

/// A draft atlas of a built-in preset at a tier ("surface" or "raywave"): shared_atlas.
/// By the fixture baker (Baker), but for the plain preset's surface tier, the one the tests of
/// bake reuse and of the default bake's stages read as this binary bakes it.
inline const std::filesystem::path& draft_atlas(const std::string& preset, const std::string& tier) {
  nlohmann::json d = loom::preset(preset);
  d["model"]["tier"] = tier;
  return shared_atlas(preset + "-" + tier + ".draft", d, "draft",
                      preset == "plain" && tier == "surface" ? Baker::ThisBinary : Baker::Fixture);
}

/// The size of a randomised sweep: `fast` in the test command, `full` with LOOM_FULL=1
/// (scripts/test.sh --full).
inline long sweep(long fast, long full) {
  const char* f = std::getenv("LOOM_FULL");
  return f && std::string(f) == "1" ? full : fast;
}

/// A copy of the atlas directory `src` at scratch(name).
inline std::filesystem::path copy_atlas_dir(const std::filesystem::path& src,
                                            const std::string& name) {
  const std::filesystem::path d = scratch(name);
  std::filesystem::copy(src, d);
  return d;
}

/// Rewrites an atlas's manifest.json through `edit`.
inline void edit_atlas_manifest(const std::filesystem::path& dir,
                                const std::function<void(nlohmann::json&)>& edit) {
  nlohmann::json m = nlohmann::json::parse(std::ifstream(dir / "manifest.json"));
  edit(m);
  std::ofstream(dir / "manifest.json", std::ios::trunc) << m.dump();
}

}  // namespace loom::test
