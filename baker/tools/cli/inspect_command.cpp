// loom-bake inspect: validate an atlas and print a summary of its manifest.
#include <fmt/format.h>

#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/atlas.h"

using nlohmann::json;
namespace fs = std::filesystem;

namespace loom::cli {

namespace {

int inspect(const std::string& dir, bool as_json) {
  json m;
  auto errors = loom::validate_atlas(dir, &m);
  if (!errors.empty()) {
    for (auto& e : errors) std::cerr << "error: " << e << "\n";
    std::cerr << fmt::format("loom-bake: {} is not a valid atlas ({} problem{})\n", dir,
                             errors.size(), errors.size() == 1 ? "" : "s");
    return 3;
  }
  // The summary's fields are for people, not for the evaluators, so validate_atlas does not
  // require them: one that is missing or of another type shows as null (JSON) or as
  // "(no <field>)", never as an exception.
  auto at = [&m](const char* ptr) {
    const json::json_pointer p(ptr);
    return m.contains(p) ? m.at(p) : json();
  };
  auto text = [&at](const char* ptr, const char* field) {
    const json v = at(ptr);
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number_integer()) return std::to_string(v.get<long long>());
    return fmt::format("(no {})", field);
  };
  json summary = {{"atlas", fs::absolute(dir).string()},
                  {"valid", true},
                  {"schema", at("/schema")},
                  {"baker_version", at("/baker_version")},
                  {"spec_sha256", at("/spec_sha256")},
                  {"name", at("/spec/name")},
                  {"tier", at("/tier")},
                  {"quality", at("/quality")},
                  {"repeat", at("/repeat")},
                  {"colour", at("/colour")}};
  json tex = json::object();
  for (auto& [name, t] : m["textures"].items()) tex[name] = t["size"];
  summary["textures"] = tex;
  if (as_json) {
    std::cout << summary.dump(2) << std::endl;
    return 0;
  }
  std::cout << fmt::format("{}: valid {} atlas \"{}\" ({}, {}), {} x {} yarn repeat\n",
                           summary["atlas"].get<std::string>(), text("/schema", "schema"),
                           text("/spec/name", "spec.name"), text("/tier", "tier"),
                           text("/quality", "quality"),
                           text("/repeat/warp_yarns", "repeat.warp_yarns"),
                           text("/repeat/weft_yarns", "repeat.weft_yarns"));
  for (auto& [name, t] : m["textures"].items())
    std::cout << fmt::format("  {:<16} {:>5} x {:<5} {}\n", name, t["size"][0].get<int>(),
                             t["size"][1].get<int>(), t["channels"].dump());
  return 0;
}

}  // namespace

void add_inspect(CLI::App& app, Commands& out) {
  struct Args {
    std::string dir;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("inspect", "validate an atlas and print a summary");
  c->add_option("atlas,--atlas", a->dir, "atlas directory")->required();
  c->add_flag("--json", a->json, "print the manifest summary as JSON");
  out.push_back({c, [a] { return inspect(a->dir, a->json); }});
}

}  // namespace loom::cli
