// load_atlas: an atlas that validates, decoded into memory for the C++ evaluators.
#include <fmt/format.h>

#include "loom/atlas.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace loom {

const Image& Atlas::map(const std::string& name) const {
  for (size_t k = 0; k < names.size(); ++k)
    if (names[k] == name) return images[k];
  throw std::runtime_error("atlas has no map " + name);
}

Atlas load_atlas(const fs::path& dir) {
  // The node files' bytes validation hashed are the ones decoded: no second read.
  json manifest;
  std::map<std::string, AtlasFile> node_files;
  auto errors = validate_atlas(dir, &manifest, &node_files);
  if (!errors.empty()) {
    std::string msg = fmt::format("{} is not a valid atlas:", dir.string());
    for (auto& e : errors) msg += "\n  " + e;
    throw std::runtime_error(msg);
  }
  return atlas_from_files(dir, std::move(manifest), std::move(node_files));
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
    if (name == "closure_lut") {
      a.closure_lut = std::move(img);
    } else {
      a.names.push_back(name);
      a.images.push_back(std::move(img));
    }
  }
  return a;
}

}  // namespace loom