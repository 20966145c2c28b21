// Specs from files: a JSON spec (a draft it names read relative to its folder), a WIF weaving
// draft baked as it is, or a built-in preset (spec.h: load_spec, spec_with_draft).
#include <cstdint>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <sstream>

#include "loom/spec.h"
#include "loom/wif.h"

namespace loom {

using nlohmann::json;

namespace {

/// Specs and drafts are text of at most this many bytes (a draft of 16,384 threads per system
/// is about 1 MB).
constexpr std::uintmax_t kMaxSpecBytes = 64u << 20;

/// The text of a regular file of at most kMaxSpecBytes, or the reason it cannot be read.
bool read_text(const std::filesystem::path& p, std::string& text, std::string& why) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(p, ec)) {
    why = "cannot read this file";
    return false;
  }
  if (std::filesystem::file_size(p, ec) > kMaxSpecBytes || ec) {
    why = fmt::format("larger than {} MB, not a spec or a draft", kMaxSpecBytes >> 20);
    return false;
  }
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  text = ss.str();
  if (!in && !in.eof()) {
    why = "cannot read this file";
    return false;
  }
  return true;
}

}  // namespace

SpecResult load_spec(const std::string& file_or_preset, const std::string& quality_override) {
  std::string name = file_or_preset;
  if (name.rfind("preset:", 0) == 0) name = name.substr(7);
  for (auto& p : preset_names())
    if (p == name) return parse_spec(preset(name), quality_override);
  std::string text, why;
  if (!read_text(file_or_preset, text, why)) {
    SpecResult r;
    std::string list;
    for (auto& p : preset_names()) list += (list.empty() ? "" : ", ") + p;
    r.errors.push_back(fmt::format("{}: {}, and it is not a preset name ({})", file_or_preset,
                                   why, list));
    return r;
  }
  const std::filesystem::path path(file_or_preset);
  std::string ext = path.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".wif" || looks_like_wif(text))
    return spec_with_draft(json::object(), text, file_or_preset, quality_override);
  json doc;
  try {
    doc = json::parse(text, nullptr, true, /*ignore_comments=*/false);
  } catch (const json::exception& e) {
    return parse_spec_text(text, quality_override);  // (its syntax error)
  }
  // A spec naming a draft: the path relative to the spec's folder.
  if (doc.is_object() && doc.contains("weave") && doc["weave"].is_object() &&
      doc["weave"].contains("wif")) {
    const json& w = doc["weave"]["wif"];
    SpecResult r;
    if (!w.is_string() || w.get<std::string>().empty()) {
      r.errors.push_back(fmt::format("$.weave.wif: expected the path of a WIF draft (relative to "
                                     "the spec's folder), not {}",
                                     w.dump()));
      return r;
    }
    std::filesystem::path draft(w.get<std::string>());
    if (draft.is_relative()) draft = path.parent_path() / draft;
    std::string draft_text;
    if (!read_text(draft, draft_text, why)) {
      r.errors.push_back(fmt::format("$.weave.wif: {}: {}", draft.string(), why));
      return r;
    }
    return spec_with_draft(doc, draft_text, draft.string(), quality_override);
  }
  return parse_spec(doc, quality_override);
}

SpecResult spec_with_draft(const json& user, const std::string& wif_text,
                           const std::string& draft_name, const std::string& quality_override) {
  SpecResult res;
  WifResult w = parse_wif(wif_text, draft_name);
  if (!w.ok()) {
    res.errors = std::move(w.errors);
    return res;
  }
  std::string stem = std::filesystem::path(draft_name).stem().string();
  if (stem.empty() || stem.size() > 128) stem = "draft";
  const WifSpec ws = wif_spec(w.draft, stem, res.errors);
  for (auto& e : res.errors)  // name the file, not the stem
    if (e.rfind(stem + " ", 0) == 0) e = draft_name + e.substr(stem.size());
  if (!res.errors.empty()) return res;
  const YarnSpec defaults;
  const json doc = merge_draft_spec(user, ws, defaults.ply_diameter_um / defaults.yarn_diameter_um,
                                    res.errors);
  if (!res.errors.empty()) return res;
  res = parse_spec(doc, quality_override);
  // Values the draft gave (not the spec laid over it), named where they came from.
  const WifDraft& d = w.draft;
  auto set_by_user = [&](const std::string& field) {  // "$.warp.yarn_diameter_um"
    const std::string rest = field.substr(2);
    const std::string top = rest.substr(0, rest.find('.')), key = rest.substr(rest.find('.') + 1);
    auto has = [&](const char* o, const std::string& k) {
      return user.is_object() && user.contains(o) && user[o].is_object() && user[o].contains(k);
    };
    return has(top.c_str(), key) || (top != "density" && has("yarn", key));
  };
  const std::tuple<std::string, std::string, int> origin[] = {
      {"$.warp.yarn_diameter_um", "[WARP] Thickness", d.warp_thickness_line},
      {"$.warp.ply_diameter_um", "[WARP] Thickness", d.warp_thickness_line},
      {"$.weft.yarn_diameter_um", "[WEFT] Thickness", d.weft_thickness_line},
      {"$.weft.ply_diameter_um", "[WEFT] Thickness", d.weft_thickness_line},
      {"$.density.warp_per_cm", "[WARP] Spacing", d.warp_spacing_line},
      {"$.density.weft_per_cm", "[WEFT] Spacing", d.weft_spacing_line}};
  for (auto& e : res.errors) {
    bool named = false;
    for (const auto& [field, key, line] : origin)
      if (line > 0 && e.rfind(field, 0) == 0 && !set_by_user(field)) {
        e += fmt::format(" (from {} line {}: {})", draft_name, line, key);
        named = true;
        break;
      }
    // The repeat the draft makes (its interlacing and colour sequences) and what it costs.
    for (const char* field : {"$.weave.matrix", "$.warp.sequence", "$.weft.sequence",
                              "$.model.quality"})
      if (!named && e.rfind(field, 0) == 0 && !(std::string(field) != "$.model.quality" &&
                                                set_by_user(field))) {
        e += fmt::format(" (the repeat of draft {})", draft_name);
        break;
      }
  }
  return res;
}

}  // namespace loom
