#include "loom/wif.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <cmath>
#include <map>
#include <optional>

namespace loom {

using nlohmann::json;

namespace {

std::string trim(const std::string& s) {
  size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}

std::string upper(std::string s) {
  for (char& c : s) c = char(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

/// "RISING SHED" -> "Rising Shed" (a key as the WIF specification writes it).
std::string title(const std::string& key) {
  std::string t = key;
  for (size_t i = 0; i < t.size(); ++i)
    t[i] = char(i == 0 || t[i - 1] == ' ' ? std::toupper(static_cast<unsigned char>(t[i]))
                                          : std::tolower(static_cast<unsigned char>(t[i])));
  return t;
}

/// One key=value line of a section.
struct Entry {
  std::string value;
  int line = 0;
  std::string key;  ///< as written
};

/// A section: its entries by upper-cased key, and where it starts.
struct Section {
  std::map<std::string, Entry> entries;
  int line = 0;
};

/// The file split into sections (upper-cased names), comments and blank lines dropped.
class Reader {
 public:
  Reader(const std::string& text, const std::string& name, std::vector<std::string>& errors)
      : name_(name), errors_(errors) {
    std::string cur;
    int n = 0;
    size_t pos = 0;
    while (pos <= text.size()) {
      size_t end = text.find('\n', pos);
      if (end == std::string::npos) end = text.size();
      std::string line = text.substr(pos, end - pos);
      pos = end + 1;
      ++n;
      if (const size_t c = line.find(';'); c != std::string::npos) line.resize(c);
      line = trim(line);
      if (line.empty()) continue;
      if (line.front() == '[' && line.back() == ']') {
        cur = upper(trim(line.substr(1, line.size() - 2)));
        if (sections_.count(cur) && known(cur))
          error(n, cur, fmt::format("the section appears twice (first at line {})",
                                    sections_[cur].line));
        else if (!sections_.count(cur))
          sections_[cur].line = n;
        continue;
      }
      const size_t eq = line.find('=');
      if (cur.empty()) {
        error(n, "", line.front() == '['
                         ? fmt::format("\"{}\" is not a section header ([NAME])", line)
                         : std::string("a line before the first section"));
        continue;
      }
      if (!known(cur)) continue;  // [TEXT], [NOTES], private sections: anything goes
      if (eq == std::string::npos) {
        error(n, cur, fmt::format("\"{}\" is not a KEY=VALUE line", line));
        continue;
      }
      const std::string key = upper(trim(line.substr(0, eq)));
      Section& s = sections_[cur];
      if (s.entries.count(key))
        error(n, cur, fmt::format("{} given twice (first at line {})", key, s.entries[key].line));
      s.entries[key] = {trim(line.substr(eq + 1)), n, trim(line.substr(0, eq))};
    }
  }

  const Section* section(const std::string& s) const {
    auto it = sections_.find(s);
    return it == sections_.end() ? nullptr : &it->second;
  }

  void error(int line, const std::string& section, const std::string& what) {
    errors_.push_back(section.empty() ? fmt::format("{} line {}: {}", name_, line, what)
                                      : fmt::format("{} line {} [{}]: {}", name_, line, section,
                                                    what));
  }
  void missing(const std::string& section, const std::string& what) {
    errors_.push_back(fmt::format("{} [{}]: {}", name_, section, what));
  }

  /// An integer in [lo, hi] from `key` of `section`; nullopt (and an error when required) if
  /// absent or bad.
  std::optional<int> integer(const std::string& section, const std::string& key, int lo, int hi,
                             bool required) {
    const Section* s = this->section(section);
    auto it = s ? s->entries.find(key) : decltype(s->entries.end()){};
    if (!s || it == s->entries.end()) {
      if (required)
        missing(section, fmt::format("{}= is missing (an integer in [{}, {}])", title(key), lo, hi));
      return std::nullopt;
    }
    int v = 0;
    const std::string& t = it->second.value;
    auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || p != t.data() + t.size() || v < lo || v > hi) {
      error(it->second.line, section,
            fmt::format("{}={} is not an integer in [{}, {}]", it->second.key, t, lo, hi));
      return std::nullopt;
    }
    return v;
  }

  static bool known(const std::string& s) {
    static const char* names[] = {"WIF", "CONTENTS", "WEAVING", "WARP", "WEFT", "THREADING",
                                  "TIEUP", "TREADLING", "LIFTPLAN", "COLOR PALETTE",
                                  "COLOR TABLE", "WARP COLORS", "WEFT COLORS"};
    return std::find(std::begin(names), std::end(names), s) != std::end(names);
  }

 private:
  std::string name_;
  std::vector<std::string>& errors_;
  std::map<std::string, Section> sections_;
};

/// "3,4" -> {3, 4}; "" -> {}; 0 entries dropped. False on anything else, outside [0, hi], or
/// longer than kWifMaxShafts numbers (no thread has more shafts or treadles, nor more colours).
bool int_list(const std::string& v, int hi, std::vector<int>& out) {
  out.clear();
  if (v.empty()) return true;
  size_t pos = 0, count = 0;
  while (pos <= v.size()) {
    if (++count > size_t(kWifMaxShafts)) return false;
    size_t end = v.find(',', pos);
    if (end == std::string::npos) end = v.size();
    const std::string t = trim(v.substr(pos, end - pos));
    int x = 0;
    auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), x);
    if (t.empty() || ec != std::errc() || p != t.data() + t.size() || x < 0 || x > hi)
      return false;
    if (x > 0 && std::find(out.begin(), out.end(), x) == out.end()) out.push_back(x);
    pos = end + 1;
  }
  return true;
}

/// A per-thread section (thread number = list of values in [0, hi]) into `out` (count threads).
void per_thread(Reader& r, const std::string& section, int count, const std::string& count_what,
                int hi, const std::string& hi_what, std::vector<std::vector<int>>& out) {
  out.assign(size_t(std::max(count, 0)), {});
  const Section* s = r.section(section);
  if (!s) return;
  for (const auto& [key, e] : s->entries) {
    int t = 0;
    auto [p, ec] = std::from_chars(key.data(), key.data() + key.size(), t);
    if (ec != std::errc() || p != key.data() + key.size() || t < 1) {
      r.error(e.line, section, fmt::format("\"{}\" is not a thread number (1, 2, ...)", key));
      continue;
    }
    if (t > count) {
      r.error(e.line, section, fmt::format("{} {} is beyond {}{}",
                                        section == "TIEUP" ? "treadle" : "thread", t, count_what,
                                        count));
      continue;
    }
    if (!int_list(e.value, hi, out[size_t(t - 1)]))
      r.error(e.line, section,
              fmt::format("{}={}: expected numbers in [1, {}] ({}; 0 or nothing: none) "
                          "separated by commas",
                          e.key, e.value, hi, hi_what));
  }
}

double unit_cm(Reader& r, const std::string& system) {
  const Section* s = r.section(system);
  auto it = s ? s->entries.find("UNITS") : decltype(s->entries.end()){};
  if (!s || it == s->entries.end()) return 1.0;
  const std::string u = upper(it->second.value);
  if (u == "CENTIMETERS" || u == "CENTIMETRES") return 1.0;
  if (u == "INCHES") return 2.54;
  if (u == "DECIPOINTS") return 2.54 / 720.0;
  r.error(it->second.line, system,
          fmt::format("Units={}: expected centimeters, inches or decipoints", it->second.value));
  return 1.0;
}

/// A positive length (Spacing, Thickness) of a system in cm, 0 when absent.
double length_cm(Reader& r, const std::string& system, const std::string& key, double unit,
                 int& line) {
  const Section* s = r.section(system);
  auto it = s ? s->entries.find(key) : decltype(s->entries.end()){};
  if (!s || it == s->entries.end()) return 0;
  line = it->second.line;
  double v = 0;
  const std::string& t = it->second.value;
  auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || p != t.data() + t.size() || !(v > 0) || v * unit > 10.0) {
    r.error(line, system, fmt::format("{}={}: expected a length in (0, 10] cm in its Units",
                                      it->second.key, t));
    return 0;
  }
  return v * unit;
}

}  // namespace

bool looks_like_wif(const std::string& text) {
  size_t pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    if (line.rfind("\xEF\xBB\xBF", 0) == 0) line = line.substr(3);  // a UTF-8 byte-order mark
    if (const size_t c = line.find(';'); c != std::string::npos) line.resize(c);
    line = trim(line);
    if (!line.empty()) return upper(line) == "[WIF]";
  }
  return false;
}

WifResult parse_wif(const std::string& text_in, const std::string& name) {
  WifResult res;
  std::string text = text_in;
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) text = text.substr(3);
  Reader r(text, name, res.errors);
  WifDraft& d = res.draft;
  if (!r.section("WIF")) r.missing("WIF", "the section is missing (not a WIF file?)");
  const bool lift = r.section("LIFTPLAN") != nullptr;
  d.has_liftplan = lift;
  for (const char* s : {"WEAVING", "WARP", "WEFT", "THREADING"})
    if (!r.section(s)) r.missing(s, "the section is missing");
  if (!lift)
    for (const char* s : {"TIEUP", "TREADLING"})
      if (!r.section(s))
        r.missing(s, "the section is missing (a draft needs [TIEUP] and [TREADLING], or "
                     "[LIFTPLAN])");
  d.shafts = r.integer("WEAVING", "SHAFTS", 1, kWifMaxShafts, true).value_or(0);
  d.treadles = r.integer("WEAVING", "TREADLES", lift ? 0 : 1, kWifMaxShafts, !lift).value_or(0);
  if (const Section* w = r.section("WEAVING")) {
    if (auto it = w->entries.find("RISING SHED"); it != w->entries.end()) {
      const std::string v = upper(it->second.value);
      if (v == "YES" || v == "TRUE" || v == "ON" || v == "1")
        d.rising_shed = true;
      else if (v == "NO" || v == "FALSE" || v == "OFF" || v == "0")
        d.rising_shed = false;
      else
        r.error(it->second.line, "WEAVING",
                fmt::format("Rising Shed={}: expected yes or no", it->second.value));
    }
  }
  d.warp_threads = r.integer("WARP", "THREADS", 1, kWifMaxThreads, true).value_or(0);
  d.weft_threads = r.integer("WEFT", "THREADS", 1, kWifMaxThreads, true).value_or(0);
  if (res.errors.empty() && int64_t(d.warp_threads) * d.weft_threads > kWifMaxCells)
    r.missing("WEFT", fmt::format("{} warp threads x {} picks is more than {} crossings",
                                  d.warp_threads, d.weft_threads, kWifMaxCells));
  if (!res.errors.empty()) return res;  // the counts the tables are checked against

  per_thread(r, "THREADING", d.warp_threads, "[WARP] Threads=", d.shafts, "shafts", d.threading);
  if (lift) {
    per_thread(r, "LIFTPLAN", d.weft_threads, "[WEFT] Threads=", d.shafts, "shafts", d.liftplan);
  } else {
    per_thread(r, "TIEUP", d.treadles, "[WEAVING] Treadles=", d.shafts, "shafts", d.tieup);
    per_thread(r, "TREADLING", d.weft_threads, "[WEFT] Threads=", d.treadles, "treadles",
               d.treadling);
  }

  // Colours: the palette's range, the table, each system's default and per-thread indices.
  double lo = 0, hi = 255;
  if (const Section* p = r.section("COLOR PALETTE")) {
    if (auto it = p->entries.find("RANGE"); it != p->entries.end()) {
      const std::string& t = it->second.value;
      const size_t c = t.find(',');
      double a = 0, b = 0;
      bool good = c != std::string::npos;
      if (good) {
        const std::string sa = trim(t.substr(0, c)), sb = trim(t.substr(c + 1));
        auto ra = std::from_chars(sa.data(), sa.data() + sa.size(), a);
        auto rb = std::from_chars(sb.data(), sb.data() + sb.size(), b);
        good = ra.ec == std::errc() && rb.ec == std::errc() && ra.ptr == sa.data() + sa.size() &&
               rb.ptr == sb.data() + sb.size() && b > a && std::isfinite(a) && std::isfinite(b);
      }
      if (good)
        lo = a, hi = b;
      else
        r.error(it->second.line, "COLOR PALETTE",
                fmt::format("Range={}: expected two numbers lo,hi with lo < hi", t));
    }
  }
  std::map<int, std::vector<double>> table;
  if (const Section* t = r.section("COLOR TABLE")) {
    for (const auto& [key, e] : t->entries) {
      int idx = 0;
      auto [p, ec] = std::from_chars(key.data(), key.data() + key.size(), idx);
      std::vector<double> rgb;
      size_t pos = 0;
      bool good = ec == std::errc() && p == key.data() + key.size() && idx >= 1;
      while (good && pos <= e.value.size() && rgb.size() < 4) {
        size_t end = e.value.find(',', pos);
        if (end == std::string::npos) end = e.value.size();
        const std::string s = trim(e.value.substr(pos, end - pos));
        double x = 0;
        auto [q, ec2] = std::from_chars(s.data(), s.data() + s.size(), x);
        good = ec2 == std::errc() && q == s.data() + s.size() && x >= lo && x <= hi;
        rgb.push_back((x - lo) / (hi - lo));
        pos = end + 1;
      }
      if (!good || rgb.size() != 3) {
        r.error(e.line, "COLOR TABLE",
                fmt::format("{}={}: expected index=r,g,b with each in the palette's range "
                            "[{}, {}]",
                            key, e.value, lo, hi));
        continue;
      }
      table[idx] = rgb;
    }
  }
  for (const auto& [system, count, out] :
       {std::tuple{std::string("WARP"), d.warp_threads, &d.warp_colour},
        std::tuple{std::string("WEFT"), d.weft_threads, &d.weft_colour}}) {
    std::vector<double> def;
    if (const Section* s = r.section(system))
      if (auto it = s->entries.find("COLOR"); it != s->entries.end()) {
        std::vector<int> v;
        if (!int_list(it->second.value, 1 << 20, v) || v.size() != 1 || !table.count(v[0]))
          r.error(it->second.line, system,
                  fmt::format("Color={}: not an index of [COLOR TABLE]", it->second.value));
        else
          def = table[v[0]];
      }
    out->assign(size_t(count), def);
    std::vector<std::vector<int>> idx;
    per_thread(r, system + " COLORS", count, "[" + system + "] Threads=", 1 << 20, "indices", idx);
    const Section* s = r.section(system + " COLORS");
    for (int t = 0; t < count && s; ++t) {
      if (idx[size_t(t)].empty()) continue;
      const int k = idx[size_t(t)][0];
      if (idx[size_t(t)].size() != 1 || !table.count(k)) {
        const auto it = s->entries.find(std::to_string(t + 1));
        r.error(it == s->entries.end() ? s->line : it->second.line, system + " COLORS",
                idx[size_t(t)].size() != 1
                    ? fmt::format("thread {}: one colour index per thread", t + 1)
                    : fmt::format("thread {}: colour {} is not an index of [COLOR TABLE]", t + 1,
                                  k));
        continue;
      }
      (*out)[size_t(t)] = table[k];
    }
  }
  for (const auto& [system, spacing, thickness, sl, tl] :
       {std::tuple{"WARP", &d.warp_spacing_cm, &d.warp_thickness_cm, &d.warp_spacing_line,
                   &d.warp_thickness_line},
        std::tuple{"WEFT", &d.weft_spacing_cm, &d.weft_thickness_cm, &d.weft_spacing_line,
                   &d.weft_thickness_line}}) {
    const double u = unit_cm(r, system);
    *spacing = length_cm(r, system, "SPACING", u, *sl);
    *thickness = length_cm(r, system, "THICKNESS", u, *tl);
  }
  return res;
}

std::vector<std::vector<int>> wif_interlacing(const WifDraft& d) {
  std::vector<std::vector<int>> m(size_t(d.warp_threads), std::vector<int>(size_t(d.weft_threads), 0));
  for (int j = 0; j < d.weft_threads; ++j) {
    std::vector<bool> moves(size_t(d.shafts) + 1, false);
    if (d.has_liftplan) {
      for (int s : d.liftplan[size_t(j)]) moves[size_t(s)] = true;
    } else {
      for (int t : d.treadling[size_t(j)])
        for (int s : d.tieup[size_t(t - 1)]) moves[size_t(s)] = true;
    }
    for (int i = 0; i < d.warp_threads; ++i) {
      bool any = false;
      for (int s : d.threading[size_t(i)]) any = any || moves[size_t(s)];
      m[size_t(i)][size_t(j)] = d.rising_shed ? any : !any;
    }
  }
  return m;
}

}  // namespace loom
