// Weaving drafts as Loom specs (wif.h): the interlacing's smallest repeat, the spec document a
// draft makes (yarn types for systems of several colours), and a spec laid over it.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "loom/wif.h"

namespace loom {

using nlohmann::json;

namespace {

/// The smallest p dividing n with same(k, k mod p) for every k (n when none smaller does).
template <class Same>
size_t smallest_period(size_t n, Same same) {
  for (size_t p = 1; p < n; ++p) {
    if (n % p) continue;
    bool ok = true;
    for (size_t k = p; k < n && ok; ++k) ok = same(k, k % p);
    if (ok) return p;
  }
  return n;
}

}  // namespace

std::vector<std::vector<int>> smallest_repeat(const std::vector<std::vector<int>>& m) {
  if (m.empty() || m[0].empty()) return m;
  const size_t R = m.size(), C = m[0].size();
  const size_t pr = smallest_period(R, [&](size_t a, size_t b) { return m[a] == m[b]; });
  const size_t pc = smallest_period(C, [&](size_t a, size_t b) {
    for (const auto& row : m)
      if (row[a] != row[b]) return false;
    return true;
  });
  std::vector<std::vector<int>> out(pr);
  for (size_t i = 0; i < pr; ++i) out[i].assign(m[i].begin(), m[i].begin() + long(pc));
  return out;
}

WifSpec wif_spec(const WifDraft& d, const std::string& name, std::vector<std::string>& errors) {
  WifSpec out;
  const auto m = wif_interlacing(d);
  const char* pick_section = d.has_liftplan ? "[LIFTPLAN]" : "[TREADLING]";
  // Threads that never interlace, the first few of each system named.
  constexpr int kNamed = 8;
  const size_t before = errors.size();
  int unwoven = 0;
  for (int i = 0; i < d.warp_threads; ++i) {
    int s = 0;
    for (int v : m[size_t(i)]) s += v;
    if ((s == 0 || s == d.weft_threads) && ++unwoven <= kNamed)
      errors.push_back(fmt::format("{} [THREADING]: warp thread {} lies {} every pick (shafts: "
                                   "{}); every thread must go over and under",
                                   name, i + 1, s ? "over" : "under",
                                   d.threading[size_t(i)].empty()
                                       ? std::string("none")
                                       : fmt::format("{}", fmt::join(d.threading[size_t(i)], ","))));
  }
  if (unwoven > kNamed)
    errors.push_back(fmt::format("{} [THREADING]: ... and {} more warp threads that never "
                                 "interlace", name, unwoven - kNamed));
  int unpicked = 0;
  for (int j = 0; j < d.weft_threads; ++j) {
    int s = 0;
    for (int i = 0; i < d.warp_threads; ++i) s += m[size_t(i)][size_t(j)];
    if ((s == 0 || s == d.warp_threads) && ++unpicked <= kNamed)
      errors.push_back(fmt::format("{} {}: pick {} lies {} every warp thread; every pick must go "
                                   "over and under",
                                   name, pick_section, j + 1, s ? "under" : "over"));
  }
  if (unpicked > kNamed)
    errors.push_back(fmt::format("{} {}: ... and {} more picks that never interlace", name,
                                 pick_section, unpicked - kNamed));
  if (errors.size() > before) return out;  // (no document of a draft that cannot be woven)
  json doc = {{"schema", "loom.fabric/1"},
              {"name", name},
              {"weave", {{"pattern", "custom"}, {"matrix", smallest_repeat(m)}}}};
  // A system of one colour gets it; one of several a sequence of yarn types, one per distinct
  // colour of the draft ("color_1", ... in order of appearance, warp first).
  std::vector<std::vector<double>> palette;
  auto type_of = [&](const std::vector<double>& c) {
    auto it = std::find(palette.begin(), palette.end(), c);
    if (it == palette.end()) it = palette.insert(palette.end(), c);
    return "color_" + std::to_string(it - palette.begin() + 1);
  };
  json types = json::object();
  for (const auto& [system, colours, spacing, thickness] :
       {std::tuple{"warp", &d.warp_colour, d.warp_spacing_cm, d.warp_thickness_cm},
        std::tuple{"weft", &d.weft_colour, d.weft_spacing_cm, d.weft_thickness_cm}}) {
    std::vector<std::vector<double>> distinct;
    for (const auto& c : *colours)
      if (!c.empty() && std::find(distinct.begin(), distinct.end(), c) == distinct.end())
        distinct.push_back(c);
    json y = json::object();
    if (distinct.size() == 1) y["color"] = {{"srgb", distinct[0]}};
    if (distinct.size() > 1) {
      std::vector<std::string> ts;  // each thread's type
      std::vector<double> use = distinct[0];
      for (const auto& c : *colours) {
        // A thread the draft leaves without a colour takes the one before it (the first: the
        // first coloured one).
        if (!c.empty()) use = c;
        ts.push_back(type_of(use));
        types[ts.back()] = {{"color", {{"srgb", use}}}};
      }
      // The sequence's smallest period that divides the draft (as the interlacing's).
      const size_t period =
          smallest_period(ts.size(), [&](size_t a, size_t b) { return ts[a] == ts[b]; });
      json runs = json::array();
      for (size_t k = 0; k < period; ++k)
        if (!runs.empty() && runs.back()[0] == ts[k])
          runs.back()[1] = runs.back()[1].get<int>() + 1;
        else
          runs.push_back({ts[k], 1});
      y["sequence"] = runs;
    }
    if (thickness > 0) y["yarn_diameter_um"] = thickness * 1e4;
    if (spacing > 0) doc["density"][std::string(system) + "_per_cm"] = 1.0 / spacing;
    if (!y.empty()) doc[system] = y;
  }
  if (!types.empty()) doc["yarn_types"] = types;
  out.doc = std::move(doc);
  return out;
}

json merge_draft_spec(const json& user, const WifSpec& draft, double ply_per_yarn,
                      std::vector<std::string>& errors) {
  json doc = draft.doc;
  const json none = json::object();
  auto obj = [&](const json& j, const char* k) -> const json& {
    return j.is_object() && j.contains(k) && j[k].is_object() ? j[k] : none;
  };
  const json& yarn = obj(user, "yarn");
  for (const char* system : {"warp", "weft"}) {
    const json& mine = obj(user, system);
    json& theirs = doc[system];
    if (theirs.is_null()) theirs = json::object();
    for (auto& [k, v] : yarn.items()) theirs.erase(k);  // "yarn" sets both systems
    if (mine.contains("color") || yarn.contains("color")) theirs.erase("sequence");
    if (theirs.contains("yarn_diameter_um") && !mine.contains("ply_diameter_um") &&
        !yarn.contains("ply_diameter_um") && !mine.contains("yarn_diameter_um") &&
        !yarn.contains("yarn_diameter_um"))
      theirs["ply_diameter_um"] = theirs["yarn_diameter_um"].get<double>() * ply_per_yarn;
    for (auto& [k, v] : mine.items()) theirs[k] = v;
    if (theirs.empty()) doc.erase(system);
  }
  if (user.is_object())
    for (auto& [k, v] : user.items()) {
      if (k == "warp" || k == "weft") continue;
      if (k == "weave") {
        for (auto& [wk, wv] : v.items())
          if (wk != "wif")
            errors.push_back(fmt::format("$.weave.{}: not allowed next to \"wif\" (the draft "
                                         "gives the interlacing)",
                                         wk));
        continue;
      }
      if ((k == "density" || k == "yarn_types") && v.is_object() && doc.contains(k)) {
        for (auto& [dk, dv] : v.items()) doc[k][dk] = dv;
        continue;
      }
      doc[k] = v;
    }
  // The draft's yarn types no sequence uses any more (a colour the spec gave instead).
  if (doc.contains("yarn_types") && doc["yarn_types"].is_object()) {
    std::vector<std::string> unused;
    for (auto& [name, t] : doc["yarn_types"].items()) {
      bool used = obj(user, "yarn_types").contains(name);
      for (const char* system : {"warp", "weft", "yarn"})
        if (doc.contains(system) && doc[system].is_object() && doc[system].contains("sequence") &&
            doc[system]["sequence"].is_array())
          for (const auto& run : doc[system]["sequence"])
            used = used || (run.is_array() && !run.empty() && run[0] == name);
      if (!used) unused.push_back(name);
    }
    for (const auto& n : unused) doc["yarn_types"].erase(n);
    if (doc["yarn_types"].empty()) doc.erase("yarn_types");
  }
  return doc;
}

}  // namespace loom
