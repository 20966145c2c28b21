// Fabric spec parsing and validation. See spec.h.
#include "loom/spec.h"

#include <cmath>
#include <fmt/format.h>
#include <algorithm>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>
#include <stdexcept>

namespace loom {

using nlohmann::json;

const char* to_string(ColourReading r) {
  return r == ColourReading::Swatch ? "swatch" : "ply_albedo";
}

const char* to_string(Quality q) {
  switch (q) {
    case Quality::Draft: return "draft";
    case Quality::Preview: return "preview";
    case Quality::Final: return "final";
    case Quality::Reference: return "reference";
  }
  return "?";
}

const char* to_string(Tier t) {
  switch (t) {
    case Tier::Surface: return "surface";
    case Tier::Raywave: return "raywave";
    case Tier::Fiber: return "fiber";
  }
  return "?";
}

int texels_per_cell(Quality q) {
  switch (q) {
    case Quality::Draft: return 16;
    case Quality::Preview: return 32;
    case Quality::Final: return 64;
    case Quality::Reference: return 128;
  }
  return 32;
}

namespace {

std::string type_name(const json& j) {
  if (j.is_number_integer() || j.is_number_unsigned()) return "integer";
  if (j.is_number_float()) return "number";
  return j.type_name();
}

/// Reads one object level, collecting errors with JSON paths ("$.warp.ior").
class Reader {
 public:
  Reader(const json& obj, std::string path, std::vector<std::string>& errors)
      : obj_(obj), path_(std::move(path)), errors_(errors) {}

  bool valid_object() const { return obj_.is_object(); }
  std::string at(const std::string& key) const { return path_ + "." + key; }

  void error(const std::string& key, const std::string& msg) {
    errors_.push_back(fmt::format("{}: {}", at(key), msg));
  }

  const json* get(const std::string& key) {
    seen_.insert(key);
    if (!obj_.is_object()) return nullptr;
    auto it = obj_.find(key);
    return it == obj_.end() ? nullptr : &*it;
  }

  double number(const std::string& key, double def, double lo, double hi, const char* unit) {
    const json* j = get(key);
    if (!j) return def;
    if (!j->is_number()) {
      error(key, fmt::format("expected a number in [{}, {}] {}, got {}", lo, hi, unit,
                             type_name(*j)));
      return def;
    }
    double v = j->get<double>();
    if (!std::isfinite(v) || v < lo || v > hi) {
      error(key, fmt::format("{} is out of range [{}, {}] {}", j->dump(), lo, hi, unit));
      return def;
    }
    return v;
  }

  int integer(const std::string& key, int def, int lo, int hi, const char* unit = "") {
    const json* j = get(key);
    if (!j) return def;
    if (!(j->is_number_integer() || j->is_number_unsigned()) &&
        !(j->is_number_float() && std::floor(j->get<double>()) == j->get<double>())) {
      error(key, fmt::format("expected an integer in [{}, {}]{}{}, got {}", lo, hi,
                             *unit ? " " : "", unit, type_name(*j)));
      return def;
    }
    double v = j->get<double>();
    if (v < lo || v > hi) {
      error(key, fmt::format("{} is out of range [{}, {}]{}{}", j->dump(), lo, hi,
                             *unit ? " " : "", unit));
      return def;
    }
    return static_cast<int>(v);
  }

  bool boolean(const std::string& key, bool def) {
    const json* j = get(key);
    if (!j) return def;
    if (!j->is_boolean()) {
      error(key, fmt::format("expected true or false, got {}", type_name(*j)));
      return def;
    }
    return j->get<bool>();
  }

  std::string choice(const std::string& key, const std::string& def,
                     const std::vector<std::string>& allowed) {
    const json* j = get(key);
    if (!j) return def;
    std::string list;
    for (auto& a : allowed) list += (list.empty() ? "" : ", ") + ("\"" + a + "\"");
    if (!j->is_string()) {
      error(key, fmt::format("expected one of {}, got {}", list, type_name(*j)));
      return def;
    }
    auto v = j->get<std::string>();
    for (auto& a : allowed)
      if (a == v) return v;
    error(key, fmt::format("\"{}\" is not one of {}", v, list));
    return def;
  }

  std::string string(const std::string& key, const std::string& def, size_t max_len) {
    const json* j = get(key);
    if (!j) return def;
    if (!j->is_string() || j->get<std::string>().size() > max_len) {
      error(key, fmt::format("expected a string of at most {} characters", max_len));
      return def;
    }
    return j->get<std::string>();
  }

  /// Unknown keys are errors: a misspelt field must not silently fall back to its default.
  void reject_unknown() {
    if (!obj_.is_object()) return;
    for (auto& [k, v] : obj_.items())
      if (!seen_.count(k)) errors_.push_back(fmt::format("{}: unknown field", at(k)));
  }

 private:
  const json& obj_;
  std::string path_;
  std::vector<std::string>& errors_;
  std::set<std::string> seen_;
};

const json kEmpty = json::object();

const json& sub(Reader& r, const std::string& key, std::vector<std::string>& errors) {
  const json* j = r.get(key);
  if (!j) return kEmpty;
  if (!j->is_object()) {
    errors.push_back(fmt::format("{}: expected an object, got {}", r.at(key), type_name(*j)));
    return kEmpty;
  }
  return *j;
}

void read_yarn(const json& j, const std::string& path, YarnSpec& y,
               std::vector<std::string>& errors) {
  Reader r(j, path, errors);
  y.plies = r.integer("plies", y.plies, 1, 8);
  y.fibers_per_ply = r.integer("fibers_per_ply", y.fibers_per_ply, 1, 1000);
  y.yarn_diameter_um = r.number("yarn_diameter_um", y.yarn_diameter_um, 10, 5000, "um");
  y.ply_diameter_um = r.number("ply_diameter_um", y.ply_diameter_um, 5, 5000, "um");
  y.fiber_diameter_um = r.number("fiber_diameter_um", y.fiber_diameter_um, 1, 200, "um");
  y.fiber_twist_pitch_um =
      r.number("fiber_twist_pitch_um", y.fiber_twist_pitch_um, 50, 100000, "um");
  y.ply_twist_deg = r.number("ply_twist_deg", y.ply_twist_deg, 0, 60, "degrees");
  y.twist = r.choice("twist", y.twist, {"S", "Z"});
  y.ior = r.number("ior", y.ior, 1.0, 3.0, "");
  y.roughness = r.number("roughness", y.roughness, 0.001, 1.0, "");
  y.specular = r.number("specular", y.specular, 0.0, 1.0, "");
  y.transmission = r.number("transmission", y.transmission, 0.0, 1.0, "");
  y.migration_min = r.number("migration_min", y.migration_min, 0.0, 1.0, "");
  y.migration_max = r.number("migration_max", y.migration_max, 0.0, 1.0, "");
  y.migration_period = r.number("migration_period", y.migration_period, 0.1, 10.0, "");
  y.density_epsilon = r.number("density_epsilon", y.density_epsilon, 0.0, 0.5, "");
  y.density_beta = r.number("density_beta", y.density_beta, 0.01, 10.0, "");
  y.loop_flyaways_per_mm = r.number("loop_flyaways_per_mm", y.loop_flyaways_per_mm, 0, 100, "/mm");
  y.hair_flyaways_per_mm = r.number("hair_flyaways_per_mm", y.hair_flyaways_per_mm, 0, 100, "/mm");
  if (const json* c = r.get("color")) {
    Reader cr(*c, r.at("color"), errors);
    if (!c->is_object()) {
      errors.push_back(fmt::format(
          "{}: expected an object {{\"srgb\": [r, g, b]}} or {{\"linear\": [r, g, b]}} with "
          "components in [0, 1]",
          r.at("color")));
    } else {
      const json* s = cr.get("srgb");
      const json* l = cr.get("linear");
      cr.reject_unknown();
      if ((s != nullptr) == (l != nullptr)) {
        errors.push_back(fmt::format("{}: give exactly one of \"srgb\" or \"linear\"",
                                     r.at("color")));
      } else {
        const json& a = s ? *s : *l;
        std::string cp = r.at("color") + (s ? ".srgb" : ".linear");
        bool good = a.is_array() && a.size() == 3;
        for (size_t k = 0; good && k < 3; ++k) {
          good = a[k].is_number() && std::isfinite(a[k].get<double>()) &&
                 a[k].get<double>() >= 0.0 && a[k].get<double>() <= 1.0;
        }
        if (!good) {
          errors.push_back(fmt::format("{}: expected 3 numbers in [0, 1], got {}", cp, a.dump()));
        } else {
          for (size_t k = 0; k < 3; ++k) y.color_input[k] = a[k].get<double>();
          y.color_space = s ? "srgb" : "linear";
        }
      }
    }
  }
  r.reject_unknown();
  if (y.ply_diameter_um > y.yarn_diameter_um)
    errors.push_back(fmt::format(
        "{}.ply_diameter_um: {} um is larger than yarn_diameter_um {} um; allowed range [5, {}] um",
        path, y.ply_diameter_um, y.yarn_diameter_um, y.yarn_diameter_um));
  if (y.migration_min > y.migration_max)
    errors.push_back(fmt::format("{}.migration_min: {} is larger than migration_max {}; allowed "
                                 "range [0, {}]",
                                 path, y.migration_min, y.migration_max, y.migration_max));
  if (y.fiber_diameter_um > y.ply_diameter_um)
    errors.push_back(fmt::format(
        "{}.fiber_diameter_um: {} um is larger than ply_diameter_um {} um; allowed range [1, {}] "
        "um",
        path, y.fiber_diameter_um, y.ply_diameter_um, y.ply_diameter_um));
}

void read_weave(const json& j, const std::string& path, WeaveSpec& w,
                std::vector<std::string>& errors) {
  if (j.is_object() && j.contains("wif")) {  // load_spec reads it; a spec given as text cannot
    errors.push_back(fmt::format("{}.wif: a draft is read from a spec file (loom-bake check or "
                                 "bake SPEC.json, the path relative to its folder)",
                                 path));
    return;
  }
  Reader r(j, path, errors);
  w.pattern = r.choice("pattern", w.pattern, {"plain", "twill", "satin", "basket", "custom"});
  if (w.pattern == "twill") {
    w.up = r.integer("up", w.up, 1, 8);
    w.down = r.integer("down", w.down, 1, 8);
    w.direction = r.choice("direction", w.direction, {"S", "Z"});
    if (w.up + w.down < 3)
      errors.push_back(fmt::format("{}: up + down = {} makes a plain weave; a twill needs "
                                   "up + down in [3, 16]",
                                   path, w.up + w.down));
  } else if (w.pattern == "satin") {
    w.harness = r.integer("harness", w.harness, 5, 16);
    w.shift = r.integer("shift", w.shift, 2, 14);
    if (w.shift > w.harness - 2 || std::gcd(w.shift, w.harness) != 1)
      errors.push_back(fmt::format("{}.shift: {} is not allowed with harness {}: the shift must "
                                   "be in [2, {}] and coprime with the harness",
                                   path, w.shift, w.harness, w.harness - 2));
  } else if (w.pattern == "basket") {
    w.group = r.integer("group", w.group, 2, 4);
  } else if (w.pattern == "custom") {
    const json* m = r.get("matrix");
    bool good = m && m->is_array() && !m->empty() && m->size() <= kMaxRepeatYarns;
    size_t cols = good ? ((*m)[0].is_array() ? (*m)[0].size() : 0) : 0;
    good = good && cols >= 1 && cols <= kMaxRepeatYarns;
    if (good) {
      w.matrix.clear();
      for (auto& row : *m) {
        if (!row.is_array() || row.size() != cols) { good = false; break; }
        std::vector<int> rr;
        for (auto& v : row) {
          if (!v.is_number_integer() || (v.get<int64_t>() != 0 && v.get<int64_t>() != 1)) {
            good = false;
            break;
          }
          rr.push_back(v.get<int>());
        }
        w.matrix.push_back(rr);
      }
    }
    if (!good) {
      errors.push_back(fmt::format("{}.matrix: expected a rectangular array of 1 to {} rows of 1 "
                                   "to {} entries, each 0 (weft on top) or 1 (warp on top)",
                                   path, kMaxRepeatYarns, kMaxRepeatYarns));
      w.matrix = {{1, 0}, {0, 1}};
    } else {
      // Each warp yarn must go under at least once and over at least once, or it is not woven.
      for (size_t i = 0; i < w.matrix.size(); ++i) {
        int s = std::accumulate(w.matrix[i].begin(), w.matrix[i].end(), 0);
        if (s == 0 || s == static_cast<int>(cols))
          errors.push_back(fmt::format("{}.matrix[{}]: warp yarn {} never interlaces (all {}); "
                                       "every row needs both 0 and 1",
                                       path, i, i, s ? 1 : 0));
      }
      for (size_t c = 0; c < cols; ++c) {
        int s = 0;
        for (auto& row : w.matrix) s += row[c];
        if (s == 0 || s == static_cast<int>(w.matrix.size()))
          errors.push_back(fmt::format("{}.matrix: weft yarn (column) {} never interlaces; "
                                       "every column needs both 0 and 1",
                                       path, c));
      }
    }
  }
  r.reject_unknown();
}

/// "yarn_types": {name: {"color": ...}} (sorted by name).
void read_yarn_types(const json& j, std::vector<YarnType>& types,
                     std::vector<std::string>& errors) {
  if (j.is_null()) return;
  if (!j.is_object()) {
    errors.push_back(fmt::format("$.yarn_types: expected an object of yarn types by name, e.g. "
                                 "{{\"red\": {{\"color\": {{\"srgb\": [0.8, 0.1, 0.1]}}}}}}"));
    return;
  }
  for (auto& [name, t] : j.items()) {
    const std::string path = "$.yarn_types." + name;
    if (name.empty() || name.size() > 64) {
      errors.push_back(fmt::format("{}: a yarn type's name has 1 to 64 characters", path));
      continue;
    }
    if (!t.is_object() || !t.contains("color")) {
      errors.push_back(fmt::format("{}: expected {{\"color\": {{\"srgb\": [r, g, b]}}}}", path));
      continue;
    }
    for (auto& [k, v] : t.items())
      if (k != "color")
        errors.push_back(fmt::format("{}.{}: yarn types that differ in more than colour are not "
                                     "yet supported (issue 33); allowed: \"color\"",
                                     path, k));
    YarnSpec y;
    read_yarn(json{{"color", t["color"]}}, path, y, errors);
    types.push_back({name, y.color_linear, y.color_input, y.color_space});
  }
  std::sort(types.begin(), types.end(),
            [](const YarnType& a, const YarnType& b) { return a.name < b.name; });
}

/// A system's "sequence": [[type, count], ...], runs of known types.
void read_sequence(const json& j, const std::string& path, const std::vector<YarnType>& types,
                   std::vector<ThreadRun>& runs, std::vector<std::string>& errors) {
  const std::string want = fmt::format(
      "expected runs [[type, count], ...] of the yarn_types' names, each count in [1, {0}], "
      "{0} threads in all at most",
      kMaxRepeatYarns);
  if (!j.is_array() || j.empty()) {
    errors.push_back(fmt::format("{}: {}", path, want));
    return;
  }
  long long total = 0;
  for (size_t k = 0; k < j.size(); ++k) {
    const json& e = j[k];
    if (!e.is_array() || e.size() != 2 || !e[0].is_string() || !e[1].is_number_integer() ||
        e[1].get<int64_t>() < 1 || e[1].get<int64_t>() > kMaxRepeatYarns) {
      errors.push_back(fmt::format("{}[{}]: {}", path, k, want));
      continue;
    }
    const std::string type = e[0].get<std::string>();
    if (std::none_of(types.begin(), types.end(), [&](const YarnType& t) { return t.name == type; })) {
      std::string names;
      for (const auto& t : types) names += (names.empty() ? "" : ", ") + t.name;
      errors.push_back(fmt::format("{}[{}]: \"{}\" is not a yarn type ($.yarn_types: {})", path,
                                   k, type, names.empty() ? "none" : names));
      continue;
    }
    total += e[1].get<int64_t>();
    if (total > kMaxRepeatYarns) break;  // (reported below; the runs need not be kept)
    if (!runs.empty() && runs.back().type == type)
      runs.back().count += e[1].get<int>();  // adjacent runs of one type are one run
    else
      runs.push_back({type, e[1].get<int>()});
  }
  if (total > kMaxRepeatYarns)
    errors.push_back(fmt::format("{}: more than {} threads; {}", path, kMaxRepeatYarns, want));
}

/// The checks that read several fields: the tier against the sequences, the repeat and the
/// map size it needs, each yarn's diameter against its spacing. Sets the weave's tiling.
void check_across_fields(FabricSpec& s, std::vector<std::string>& errors) {
  if (s.tier == Tier::Fiber)
    errors.push_back(fmt::format(
        "$.model.tier: \"{}\" is not available yet as an atlas tier; allowed: \"surface\", "
        "\"raywave\". Fibers go over either where the camera resolves them: the Blender "
        "add-on's Fibers from Camera, or loom-bake fibers --region",
        to_string(s.tier)));
  // The repeat holds whole yarn sequences: the weave's repeat tiled to their lengths.
  s.weave.tile_rows = std::max(sequence_length(s.warp_sequence), 1);
  s.weave.tile_cols = std::max(sequence_length(s.weft_sequence), 1);
  if (has_thread_sequences(s) && s.tier == Tier::Raywave)
    errors.push_back("$.model.tier: \"raywave\" does not yet take per-thread yarn sequences "
                     "(issue 33: its tables are per system); allowed with a sequence: "
                     "\"surface\"");
  // Resolution: rows = warp yarns in the repeat, cols = weft yarns.
  int rows = 2, cols = 2;
  const auto& w = s.weave;
  if (w.pattern == "twill") rows = cols = w.up + w.down;
  if (w.pattern == "satin") rows = cols = w.harness;
  if (w.pattern == "basket") rows = cols = 2 * w.group;
  if (w.pattern == "custom" && !w.matrix.empty()) {
    rows = static_cast<int>(w.matrix.size());
    cols = static_cast<int>(w.matrix[0].size());
  }
  for (auto [n, tile, what] : {std::tuple{&rows, w.tile_rows, "warp"},
                               std::tuple{&cols, w.tile_cols, "weft"}}) {
    const long long l = std::lcm(static_cast<long long>(*n), static_cast<long long>(tile));
    if (l > kMaxRepeatYarns)
      errors.push_back(fmt::format("$.{}.sequence: the repeat grows to {} {} yarns (the least "
                                   "common multiple of the weave's {} and the sequence's {}), "
                                   "more than {}",
                                   what, l, what, *n, tile, kMaxRepeatYarns));
    *n = int(std::min<long long>(l, kMaxRepeatYarns));
  }
  long long side = static_cast<long long>(std::max(rows, cols)) * texels_per_cell(s.quality);
  if (side > kMaxMapSide)
    errors.push_back(fmt::format(
        "$.model.quality: \"{}\" needs {} x {} texels for a {} x {} weave repeat, more than the "
        "{} per side that fit in memory; choose a lower quality or a smaller repeat",
        to_string(s.quality), cols * texels_per_cell(s.quality), rows * texels_per_cell(s.quality),
        rows, cols, kMaxMapSide));
  // Warp yarns lie side by side at the warp density (1e4 / warp_per_cm um apart), weft yarns at
  // the weft density.
  for (auto [name, y, per_cm] : {std::tuple{"warp", &s.warp, s.warp_per_cm},
                                 std::tuple{"weft", &s.weft, s.weft_per_cm}}) {
    // A yarn wider than 3x its spacing cannot lie flat next to its neighbours.
    double spacing = 1e4 / per_cm;
    if (y->yarn_diameter_um > 3.0 * spacing)
      errors.push_back(fmt::format(
          "$.{}.yarn_diameter_um: {} um does not fit at {} yarns/cm (spacing {:.1f} um); allowed "
          "range [10, {:.1f}] um at this density",
          name, y->yarn_diameter_um, per_cm, spacing, 3.0 * spacing));
  }
}

}  // namespace

SpecResult parse_spec(const json& doc, const std::string& quality_override) {
  SpecResult res;
  auto& errors = res.errors;
  FabricSpec& s = res.spec;
  if (!doc.is_object()) {
    errors.push_back(fmt::format("$: expected a JSON object, got {}", type_name(doc)));
    return res;
  }
  Reader r(doc, "$", errors);
  if (const json* sc = r.get("schema")) {
    if (!sc->is_string() || sc->get<std::string>() != kSpecSchema)
      errors.push_back(fmt::format("$.schema: {} is not supported; this baker reads \"{}\"",
                                   sc->dump(), kSpecSchema));
  }
  s.name = r.string("name", s.name, 128);
  read_weave(sub(r, "weave", errors), "$.weave", s.weave, errors);
  // "yarn" sets both systems; "warp"/"weft" override it field by field.
  json yarn = sub(r, "yarn", errors);
  json warp = yarn, weft = yarn;
  for (auto [key, target] : {std::pair{"warp", &warp}, std::pair{"weft", &weft}}) {
    const json& o = sub(r, key, errors);
    for (auto& [k, v] : o.items()) (*target)[k] = v;
  }
  read_yarn_types(r.get("yarn_types") ? *r.get("yarn_types") : json(), s.yarn_types, errors);
  // Report a field that came from "yarn" (and was not overridden) once, under $.yarn.
  for (auto [key, target, y] : {std::tuple{"warp", &warp, &s.warp},
                                std::tuple{"weft", &weft, &s.weft}}) {
    std::vector<std::string> yerr;
    const std::string path = std::string("$.") + key;
    if (target->is_object() && target->contains("sequence")) {
      const json* own = r.get(key);
      const bool mine = own && own->is_object() && own->contains("sequence");
      read_sequence((*target)["sequence"], (mine ? path : std::string("$.yarn")) + ".sequence",
                    s.yarn_types, std::string(key) == "warp" ? s.warp_sequence : s.weft_sequence,
                    yerr);
      target->erase("sequence");
    }
    read_yarn(*target, path, *y, yerr);
    const json* own = r.get(key);
    for (auto& e : yerr) {
      for (auto& [field, v] : yarn.items()) {
        const std::string from = path + "." + field;
        bool overridden = own && own->is_object() && own->contains(field);
        if (!overridden && e.rfind(from, 0) == 0 &&
            (e.size() == from.size() || e[from.size()] == ':' || e[from.size()] == '.'))
          e = "$.yarn." + e.substr(path.size() + 1);
      }
      if (std::find(errors.begin(), errors.end(), e) == errors.end()) errors.push_back(e);
    }
  }
  {
    Reader d(sub(r, "density", errors), "$.density", errors);
    s.warp_per_cm = d.number("warp_per_cm", s.warp_per_cm, 1, 400, "yarns/cm");
    s.weft_per_cm = d.number("weft_per_cm", s.weft_per_cm, 1, 400, "yarns/cm");
    d.reject_unknown();
  }
  {
    Reader m(sub(r, "model", errors), "$.model", errors);
    auto tier = m.choice("tier", "surface", {"surface", "raywave", "fiber"});
    s.tier = tier == "raywave" ? Tier::Raywave : tier == "fiber" ? Tier::Fiber : Tier::Surface;
    auto q = m.choice("quality", "preview", {"draft", "preview", "final", "reference"});
    if (!quality_override.empty()) {
      if (quality_override == "draft" || quality_override == "preview" ||
          quality_override == "final" || quality_override == "reference")
        q = quality_override;
      else
        errors.push_back(fmt::format("--quality: \"{}\" is not one of \"draft\", \"preview\", "
                                     "\"final\", \"reference\"",
                                     quality_override));
    }
    s.quality = q == "draft"   ? Quality::Draft
                : q == "final" ? Quality::Final
                : q == "reference" ? Quality::Reference
                                   : Quality::Preview;
    const auto reading = m.choice("colour_reading", "ply_albedo", {"swatch", "ply_albedo"});
    s.colour_reading = reading == "swatch" ? ColourReading::Swatch : ColourReading::PlyAlbedo;
    // Fitted where the tier has them (surface): closer to the model and cheaper to render.
    const auto closures = m.choice("closures", s.tier == Tier::Surface ? "fitted" : "mapped",
                                   {"mapped", "fitted"});
    s.closures = closures == "fitted" ? ClosureSource::Fitted : ClosureSource::Mapped;
    if (s.closures == ClosureSource::Fitted && s.tier != Tier::Surface)
      errors.push_back(fmt::format("$.model.closures: \"fitted\" is the surface tier's only (not "
                                   "yet on the {} tier); use \"mapped\" or \"tier\": \"surface\"",
                                   to_string(s.tier)));
    s.optical_thickness = m.number("optical_thickness", s.optical_thickness, 0.01, 100, "");
    s.diffuse_blend = m.number("diffuse_blend", s.diffuse_blend, 0, 1, "");
    s.double_layer_blend = m.number("double_layer_blend", s.double_layer_blend, 0, 1, "");
    m.reject_unknown();
  }
  {
    Reader c(sub(r, "components", errors), "$.components", errors);
    s.components.transmission = c.boolean("transmission", s.components.transmission);
    s.components.gaps = c.boolean("gaps", s.components.gaps);
    s.components.shadowing = c.boolean("shadowing", s.components.shadowing);
    s.components.multi_ply = c.boolean("multi_ply", s.components.multi_ply);
    s.components.double_layer = c.boolean("double_layer", s.components.double_layer);
    s.perlin.enabled = c.boolean("perlin", s.perlin.enabled);
    c.reject_unknown();
  }
  {
    Reader p(sub(r, "perlin", errors), "$.perlin", errors);
    s.perlin.seed = static_cast<unsigned>(p.integer("seed", 1, 0, 2147483647));
    s.perlin.amplitude = p.number("amplitude", s.perlin.amplitude, 0, 1, "radians");
    s.perlin.cells_per_repeat = p.integer("cells_per_repeat", s.perlin.cells_per_repeat, 1, 64);
    p.reject_unknown();
  }
  {
    Reader w(sub(r, "wave", errors), "$.wave", errors);
    s.wave.diffraction = w.boolean("diffraction", s.wave.diffraction);
    s.wave.beam_waist_um = w.number("beam_waist_um", s.wave.beam_waist_um, 1, 1000, "um");
    s.wave.noise = w.boolean("noise", s.wave.noise);
    s.wave.speckle_width_um =
        w.number("speckle_width_um", s.wave.speckle_width_um, 1, 1000, "um");
    w.reject_unknown();
  }
  r.reject_unknown();

  check_across_fields(s, errors);
  return res;
}

SpecResult parse_spec_text(const std::string& text, const std::string& quality_override) {
  json doc;
  try {
    doc = json::parse(text, nullptr, true, /*ignore_comments=*/false);
  } catch (const json::exception& e) {  // syntax errors, and numbers that overflow a double
    SpecResult r;
    r.errors.push_back(fmt::format("$: not valid JSON: {}", e.what()));
    return r;
  }
  return parse_spec(doc, quality_override);
}

}  // namespace loom
