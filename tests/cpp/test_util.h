// Helpers shared by the C++ tests that bake atlases and run loom-bake.
#pragma once
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "loom/atlas.h"

namespace loom::test {

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

/// A draft atlas of a built-in preset at a tier ("surface" or "raywave"), baked once per process
/// into scratch("<preset>-<tier>.draft"); read it, do not change it (copy_atlas_dir for that).
inline const std::filesystem::path& draft_atlas(const std::string& preset, const std::string& tier) {
  static std::map<std::string, std::filesystem::path> baked;
  const std::string key = preset + "-" + tier;
  auto it = baked.find(key);
  if (it != baked.end()) return it->second;
  nlohmann::json d = loom::preset(preset);
  d["model"]["tier"] = tier;
  const loom::SpecResult r = loom::parse_spec(d, "draft");
  if (!r.ok()) throw std::runtime_error("draft_atlas: " + r.errors.at(0));
  const std::filesystem::path dir = scratch(key + ".draft");
  loom::bake_atlas(r.spec, dir, {});
  return baked.emplace(key, dir).first->second;
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
