// AtlasWriter: the one place an atlas's files are written and published (atlas_writer.h).
#include "loom/atlas_writer.h"
#include "loom/publish_dir.h"

#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fmt/format.h>
#include <fstream>
#include <random>
#include <stdexcept>

namespace fs = std::filesystem;
using nlohmann::json;

namespace loom {

namespace {

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

}  // namespace

uint64_t atlas_dir_bytes(const fs::path& d) {
  uint64_t n = 0;
  for (auto& e : fs::directory_iterator(d))
    if (e.is_regular_file()) n += e.file_size();
  return n;
}

void check_bake_destination(const fs::path& dir) {
  if (!fs::exists(fs::symlink_status(dir))) return;
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

AtlasWriter::AtlasWriter(const fs::path& dir) : dir_(dir) {
  fs::create_directories(dir.parent_path());
  sweep_stale_temporaries(dir);
  std::random_device rd;
  tmp_ = dir.parent_path() / fmt::format(".{}.tmp-{}-{:08x}", dir.filename().string(), getpid(), rd());
  fs::create_directory(tmp_);
}

AtlasWriter::~AtlasWriter() {
  if (published_) return;
  std::error_code ec;
  fs::remove_all(tmp_, ec);
}

void AtlasWriter::write(const Image& img, const std::string& name, bool half, const char* wrap,
                        json entry) {
  write_atlas_map(img, tmp_, name, half, wrap);
  entry["file"] = name + ".tx";
  entry["node_file"] = name + ".exr";
  entry["format"] = half ? "half" : "float";
  entry["size"] = {img.width, img.height};
  textures_[name] = std::move(entry);
}

void AtlasWriter::write_table(const Image& img, const std::string& name,
                              const std::vector<std::string>& channels,
                              const std::string& description, bool half, const char* tiling) {
  json range = json::array();
  for (int c = 0; c < img.channels; ++c) {
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = size_t(c); i < img.data.size(); i += size_t(img.channels))
      lo = std::min(lo, img.data[i]), hi = std::max(hi, img.data[i]);
    range.push_back({lo, hi});
  }
  write(img, name, half, tiling,
        {{"channels", channels},
         {"range", range},
         {"units", std::vector<std::string>(channels.size(), "")},
         {"tiling", tiling},
         {"description", description}});
}

void AtlasWriter::copy(const fs::path& atlas, const json& manifest, const std::string& name) {
  const json& t = manifest.at("textures").at(name);
  for (const char* key : {"file", "node_file"})
    fs::copy_file(atlas / t[key].get<std::string>(), tmp_ / t[key].get<std::string>());
  textures_[name] = t;
}

json AtlasWriter::hashed_textures() const {
  json out = textures_;
  for (auto& [name, t] : out.items()) {
    t["sha256"] = sha256_file(tmp_ / t["file"].get<std::string>());
    t["node_sha256"] = sha256_file(tmp_ / t["node_file"].get<std::string>());
  }
  return out;
}

Atlas AtlasWriter::load_written(const json& manifest) const {
  {
    std::ofstream out(tmp_ / "manifest.json");
    out << manifest.dump(2) << "\n";
    if (!out) throw std::runtime_error("writing manifest.json failed");
  }
  return load_atlas(tmp_);
}

bool AtlasWriter::publish(const json& manifest, const std::string& bake_key, bool force) {
  {
    std::ofstream out(tmp_ / "manifest.json");
    out << manifest.dump(2) << "\n";
    if (!out) throw std::runtime_error("writing manifest.json failed");
  }
  // Rename into place, or atomically exchange with an older atlas and remove it.
  if (publish_directory(tmp_, dir_)) {
    published_ = true;
    return false;
  }
  json other;
  if (!force && validate_atlas(dir_, &other).empty() &&
      string_field(other, "bake_key") == bake_key)
    return true;  // a concurrent bake of the same spec won the race; ~AtlasWriter removes ours
  exchange_directories(tmp_, dir_);
  // The temporary's name now holds the old atlas, which the destructor removes.
  return false;
}

}  // namespace loom
