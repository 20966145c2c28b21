// WIF drafts (wif.h): the reader against drafts written from published structures, the
// interlacing against an independent drawdown, the smallest repeat, the spec a draft makes, and
// the refusals of bad drafts (section and line named, exit 2, nothing written).
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "loom/spec.h"
#include "loom/weave.h"
#include "loom/wif.h"
#include "test_util.h"

namespace {

using Matrix = std::vector<std::vector<int>>;
using loom::test::run;
using loom::test::scratch;

std::string read(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::filesystem::path draft(const std::string& name) {
  return loom::test::source_dir() / "presets" / "drafts" / name;
}

/// The drawdown by its definition, from the draft's lists as the test writes them (rising shed:
/// warp thread i is up at pick j when its shaft is in the tie-up of pick j's treadle).
Matrix drawdown(const std::vector<int>& threading, const std::vector<std::vector<int>>& tieup,
                const std::vector<int>& treadling) {
  Matrix m(threading.size(), std::vector<int>(treadling.size(), 0));
  for (size_t i = 0; i < threading.size(); ++i)
    for (size_t j = 0; j < treadling.size(); ++j)
      for (int s : tieup[size_t(treadling[j] - 1)]) m[i][j] |= s == threading[i];
  return m;
}

/// A WIF text of a single-shaft-per-thread draft, with a lift plan instead of tie-up and
/// treadling when `liftplan`, and the tie-up inverted for a sinking shed when `sinking`.
std::string wif_text(const std::vector<int>& threading, const std::vector<std::vector<int>>& tieup,
                     const std::vector<int>& treadling, int shafts, bool liftplan, bool sinking) {
  std::ostringstream o;
  o << "[WIF]\nVersion=1.1\n[WEAVING]\nShafts=" << shafts << "\nTreadles=" << tieup.size()
    << "\nRising Shed=" << (sinking ? "no" : "yes") << "\n[WARP]\nThreads=" << threading.size()
    << "\n[WEFT]\nThreads=" << treadling.size() << "\n[THREADING]\n";
  for (size_t i = 0; i < threading.size(); ++i) o << i + 1 << "=" << threading[i] << "\n";
  auto shafts_of = [&](const std::vector<int>& up) {
    std::string s;
    for (int k = 1; k <= shafts; ++k) {
      const bool in = std::find(up.begin(), up.end(), k) != up.end();
      if (in != sinking) s += (s.empty() ? "" : ",") + std::to_string(k);
    }
    return s;
  };
  if (liftplan) {
    o << "[LIFTPLAN]\n";
    for (size_t j = 0; j < treadling.size(); ++j)
      o << j + 1 << "=" << shafts_of(tieup[size_t(treadling[j] - 1)]) << "\n";
  } else {
    o << "[TIEUP]\n";
    for (size_t t = 0; t < tieup.size(); ++t) o << t + 1 << "=" << shafts_of(tieup[t]) << "\n";
    o << "[TREADLING]\n";
    for (size_t j = 0; j < treadling.size(); ++j) o << j + 1 << "=" << treadling[j] << "\n";
  }
  return o.str();
}

bool equal_up_to_shift(const Matrix& a, const Matrix& b) {
  if (a.size() != b.size() || a[0].size() != b[0].size()) return false;
  const size_t R = a.size(), C = a[0].size();
  for (size_t dr = 0; dr < R; ++dr)
    for (size_t dc = 0; dc < C; ++dc) {
      bool same = true;
      for (size_t i = 0; i < R && same; ++i)
        for (size_t j = 0; j < C && same; ++j) same = a[i][j] == b[(i + dr) % R][(j + dc) % C];
      if (same) return true;
    }
  return false;
}

}  // namespace

TEST(Wif, PointTwillIsItsDrawdownInEveryNotation) {
  // The point twill of presets/drafts (CRLF, comments, keys in any case, sections in any order)
  // against the drawdown of its published lists, and the same draft as a lift plan and with a
  // sinking shed (the tie-up inverted): one interlacing.
  const std::vector<int> threading = {1, 2, 3, 4, 3, 2}, treadling = {1, 2, 3, 4, 3, 2};
  const std::vector<std::vector<int>> tieup = {{1, 2}, {2, 3}, {3, 4}, {4, 1}};
  const Matrix want = drawdown(threading, tieup, treadling);
  const loom::WifResult r = loom::parse_wif(read(draft("point_twill.wif")), "point_twill.wif");
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  EXPECT_EQ(loom::wif_interlacing(r.draft), want);
  for (auto [lift, sinking] : {std::pair{true, false}, std::pair{false, true},
                               std::pair{true, true}}) {
    const loom::WifResult v =
        loom::parse_wif(wif_text(threading, tieup, treadling, 4, lift, sinking), "variant");
    ASSERT_TRUE(v.ok()) << ::testing::PrintToString(v.errors);
    EXPECT_EQ(loom::wif_interlacing(v.draft), want) << "liftplan " << lift << " sinking " << sinking;
  }
  // The spec: the interlacing (already its smallest repeat), 0.04 cm spacing, 0.03 cm thick.
  std::vector<std::string> errors;
  const loom::WifSpec s = loom::wif_spec(r.draft, "point_twill", errors);
  EXPECT_TRUE(errors.empty());
  EXPECT_EQ(s.doc["weave"]["matrix"].get<Matrix>(), want);
  EXPECT_NEAR(s.doc["density"]["warp_per_cm"].get<double>(), 25.0, 1e-9);
  EXPECT_NEAR(s.doc["warp"]["yarn_diameter_um"].get<double>(), 300.0, 1e-9);
  EXPECT_NEAR(s.doc["warp"]["color"]["srgb"][0].get<double>(), 31.0 / 255.0, 1e-12);
}

TEST(Wif, StraightDrawTwillsAreLoomsTwills) {
  // A straight draw of n shafts with a twill tie-up (up shafts rising, then down sinking, moved
  // by one per treadle), woven over 3 repeats: its smallest repeat is Loom's up/down twill.
  for (auto [up, down] : {std::pair{2, 2}, std::pair{2, 1}, std::pair{3, 1}, std::pair{1, 3}}) {
    const int n = up + down;
    std::vector<int> threading, treadling;
    for (int i = 0; i < 3 * n; ++i) threading.push_back(i % n + 1), treadling.push_back(i % n + 1);
    std::vector<std::vector<int>> tieup(static_cast<size_t>(n));
    for (int t = 0; t < n; ++t)
      for (int k = 0; k < up; ++k) tieup[size_t(t)].push_back((t + k) % n + 1);
    const loom::WifResult r = loom::parse_wif(wif_text(threading, tieup, treadling, n, false, false), "twill");
    ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
    const Matrix rep = loom::smallest_repeat(loom::wif_interlacing(r.draft));
    loom::WeaveSpec w;
    w.pattern = "twill", w.up = up, w.down = down;
    bool any = false;
    for (const char* dir : {"S", "Z"}) {
      w.direction = dir;
      any = any || equal_up_to_shift(rep, loom::make_weave(w).m);
    }
    EXPECT_TRUE(any) << up << "/" << down << ": " << ::testing::PrintToString(rep);
    // Loom's convention (warp thread i is row i, pick j column j): a straight draw with the
    // tie-up moving up one shaft per treadle rises to the right, a Z twill; a reversed
    // treadling is the S twill.
    w.direction = "Z";
    EXPECT_TRUE(equal_up_to_shift(rep, loom::make_weave(w).m)) << up << "/" << down;
    std::vector<int> reversed;
    for (int i = 0; i < 3 * n; ++i) reversed.push_back(n - i % n);
    const loom::WifResult rr =
        loom::parse_wif(wif_text(threading, tieup, reversed, n, false, false), "twill");
    ASSERT_TRUE(rr.ok());
    w.direction = "S";
    EXPECT_TRUE(equal_up_to_shift(loom::smallest_repeat(loom::wif_interlacing(rr.draft)),
                                  loom::make_weave(w).m))
        << up << "/" << down;
  }
}

TEST(Wif, SmallestRepeatDividesTheDraft) {
  const Matrix tile = {{1, 0, 0}, {0, 1, 1}};
  Matrix tiled;
  for (int a = 0; a < 3; ++a)
    for (const auto& row : tile) {
      std::vector<int> r;
      for (int b = 0; b < 4; ++b) r.insert(r.end(), row.begin(), row.end());
      tiled.push_back(r);
    }
  EXPECT_EQ(loom::smallest_repeat(tiled), tile);
  // A period that does not divide the draft is not a repeat of it: the draft stays whole.
  const Matrix odd = {{1, 0, 1, 0, 1}, {0, 1, 0, 1, 0}};
  EXPECT_EQ(loom::smallest_repeat(odd), odd);
}

TEST(Wif, ReadsWhatDraftsWrite) {
  // Several shafts on a thread, several treadles on a pick, a thread on no shaft (0), 0-255
  // default range, [WARP] Color as the default, per-thread colours over it, inches.
  const std::string text =
      "; comment first\r\n[wif]\r\nversion=1.1\r\n[Weaving]\r\nSHAFTS=3\r\ntreadles=2\r\n"
      "[warp]\r\nthreads=3\r\ncolor=1\r\nunits=INCHES\r\nspacing=0.05 ; 20 epi\r\n"
      "[weft]\r\nthreads=2\r\n[THREADING]\r\n1=1,3\r\n2=2\r\n3=0\r\n[tieup]\r\n1=1\r\n2=2\r\n"
      "[treadling]\r\n1=1,2\r\n2=2\r\n[COLOR TABLE]\r\n1=255,0,0\r\n2=0,0,255\r\n"
      "[WARP COLORS]\r\n2=2\r\n[TEXT]\r\nTitle=anything; here\r\n";
  const loom::WifResult r = loom::parse_wif(text, "t");
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  EXPECT_EQ(r.draft.threading, (Matrix{{1, 3}, {2}, {}}));
  EXPECT_EQ(r.draft.treadling, (Matrix{{1, 2}, {2}}));
  // pick 1 lifts shafts 1 and 2 (threads 1, 2 up), pick 2 shaft 2 (thread 2 up).
  EXPECT_EQ(loom::wif_interlacing(r.draft), (Matrix{{1, 0}, {1, 1}, {0, 0}}));
  EXPECT_NEAR(r.draft.warp_spacing_cm, 0.127, 1e-12);
  EXPECT_EQ(r.draft.warp_colour[0], (std::vector<double>{1, 0, 0}));
  EXPECT_EQ(r.draft.warp_colour[1], (std::vector<double>{0, 0, 1}));
  EXPECT_TRUE(r.draft.weft_colour[0].empty());
  // Threads 2 and 3 never interlace (every pick interlaces): refused, naming the thread and
  // the section.
  std::vector<std::string> errors;
  loom::wif_spec(r.draft, "t", errors);
  ASSERT_EQ(errors.size(), 2u) << ::testing::PrintToString(errors);
  EXPECT_NE(errors[0].find("[THREADING]: warp thread 2 lies over every pick"), std::string::npos);
  EXPECT_NE(errors[1].find("warp thread 3 lies under every pick (shafts: none)"), std::string::npos);
}

TEST(Wif, LiftPlansNeedNoTreadlesAndNotesMayHoldAnything) {
  // A lift plan without treadles (absent or 0), a sinking shed, a [NOTES] section holding what
  // no known section may, a UTF-8 byte-order mark and a Thickness in centimetres.
  for (const char* treadles : {"", "Treadles=0\n"}) {
    const std::string text = std::string("\xEF\xBB\xBF[WIF]\n[WEAVING]\nShafts=2\n") + treadles +
                             "Rising Shed=no\n[WARP]\nThreads=2\nThickness=0.02\n[WEFT]\n"
                             "Threads=2\n[THREADING]\n1=1\n2=2\n[LIFTPLAN]\n1=1\n2=2\n[NOTES]\n"
                             "[unclosed\nno key here\n[NOTES]\n";
    ASSERT_TRUE(loom::looks_like_wif(text));
    const loom::WifResult r = loom::parse_wif(text, "l.wif");
    ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
    // sinking: shaft 1 sinks at pick 1, so thread 1 is under it and thread 2 over
    EXPECT_EQ(loom::wif_interlacing(r.draft), (Matrix{{0, 1}, {1, 0}}));
    EXPECT_NEAR(r.draft.warp_thickness_cm, 0.02, 1e-12);
  }
}

TEST(Wif, BadDraftsNameTheSectionAndLine) {
  const std::string head = "[WIF]\n[WEAVING]\nShafts=2\nTreadles=2\n[WARP]\nThreads=2\n[WEFT]\n"
                           "Threads=2\n";  // lines 1-8
  const std::string body = "[THREADING]\n1=1\n2=2\n[TIEUP]\n1=1\n2=2\n[TREADLING]\n1=1\n2=2\n";
  struct Case {
    std::string text, want;
  };
  const Case cases[] = {
      {"[WEAVING]\nShafts=2\n", "[WIF]: the section is missing"},
      {head + "[THREADING]\n1=1\n2=2\n", "[TIEUP]: the section is missing"},
      {head + "[THREADING]\n1=1\n2=3\n[TIEUP]\n1=1\n2=2\n[TREADLING]\n1=1\n2=2\n",
       "line 11 [THREADING]: 2=3: expected numbers in [1, 2] (shafts;"},
      {head + body + "[THREADING]\n", "line 18 [THREADING]: the section appears twice"},
      {head + "[THREADING]\n1=1\n3=2\n" + body.substr(body.find("[TIEUP]")),
       "line 11 [THREADING]: thread 3 is beyond [WARP] Threads=2"},
      {"[WIF]\n[WEAVING]\nShafts=2\nTreadles=2\n[WARP]\nThreads=0\n", "line 6 [WARP]: Threads=0"},
      {"[WIF]\n[WEAVING]\nShafts=2\nTreadles=2\n[WARP]\nThreads=100000\n",
       "Threads=100000 is not an integer in [1, 16384]"},
      {"[WIF]\n[WEAVING]\nShafts=300\n", "Shafts=300 is not an integer in [1, 256]"},
      {"[WIF]\n[WEAVING]\nShafts=2\nTreadles=2\n[WARP]\nThreads=16384\n[WEFT]\n"
       "Threads=16384\n" + body,
       "[WEFT]: 16384 warp threads x 16384 picks is more than 16777216 crossings"},
      {head + body + "[COLOR TABLE]\n1=0,0,300\n", "line 19 [COLOR TABLE]: 1=0,0,300"},
      {head + body + "[COLOR TABLE]\n1=0,0,0\n[WARP COLORS]\n1=7\n",
       "line 21 [WARP COLORS]: thread 1: colour 7 is not an index of [COLOR TABLE]"},
      {head + body + "[WARP]\n", "[WARP]: the section appears twice"},
      {"[WIF]\n[WEAVING]\nShafts=2\nTreadles=2\n[WARP]\nThreads=2\nUnits=furlongs\n[WEFT]\n"
       "Threads=2\n" + body,
       "line 7 [WARP]: Units=furlongs: expected centimeters, inches or decipoints"},
      {head + "garbage\n" + body, "line 9 [WEFT]: \"garbage\" is not a KEY=VALUE line"},
  };
  for (const Case& c : cases) {
    const loom::WifResult r = loom::parse_wif(c.text, "d.wif");
    ASSERT_FALSE(r.ok()) << c.want;
    bool found = false;
    for (const auto& e : r.errors) found = found || e.find(c.want) != std::string::npos;
    EXPECT_TRUE(found) << "want \"" << c.want << "\" in " << ::testing::PrintToString(r.errors);
    for (const auto& e : r.errors) EXPECT_EQ(e.rfind("d.wif", 0), 0u) << e;
  }
}

TEST(WifCli, DraftsBakeDirectlyOrFromASpecAndBadOnesWriteNothing) {
  const std::string exe = loom::test::bake_exe();
  std::string out;
  // check DRAFT.wif prints the canonical spec: the custom interlacing of the draft.
  ASSERT_EQ(run(exe + " check " + draft("point_twill.wif").string() + " 2>&1", &out), 0) << out;
  const auto spec = nlohmann::json::parse(out);
  EXPECT_EQ(spec["weave"]["pattern"], "custom");
  EXPECT_EQ(spec["weave"]["matrix"].size(), 6u);
  EXPECT_EQ(spec["name"], "point_twill");
  // A draft of several colours per system: yarn types and their sequences (the repeat reduced:
  // 4 white and 4 red threads), on the surface tier; the ray-wave tier says "not yet".
  ASSERT_EQ(run(exe + " check " + draft("gingham.wif").string() + " 2>&1", &out), 0) << out;
  const auto gs = nlohmann::json::parse(out);
  EXPECT_EQ(gs["warp"]["sequence"], nlohmann::json::parse(R"([["color_1", 4], ["color_2", 4]])"));
  EXPECT_EQ(gs["weft"]["sequence"], gs["warp"]["sequence"]);
  EXPECT_NEAR(gs["yarn_types"]["color_2"]["color"]["srgb"][0].get<double>(), 200.0 / 255.0, 1e-12);
  const auto dir = scratch("wif_spec");
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(draft("gingham.wif"), dir / "gingham.wif");
  {
    std::ofstream(dir / "g.json") << R"({"weave": {"wif": "gingham.wif"},
                                         "yarn": {"color": {"srgb": [0.8, 0.1, 0.1]}}})";
  }
  ASSERT_EQ(run(exe + " check " + (dir / "g.json").string() + " 2>&1", &out), 0) << out;
  const auto g = nlohmann::json::parse(out);
  EXPECT_EQ(g["weave"]["matrix"], (nlohmann::json{{1, 0}, {0, 1}}));  // plain, reduced
  EXPECT_NEAR(g["density"]["warp_per_cm"].get<double>(), 1.0 / 0.0635, 1e-9);  // 40 epi
  EXPECT_NEAR(g["warp"]["yarn_diameter_um"].get<double>(), 254.0, 1e-9);
  // Only the warp's colour given: the warp's sequence goes, the weft keeps its own and the
  // types it uses.
  {
    std::ofstream(dir / "warp.json") << R"({"weave": {"wif": "gingham.wif"},
                                            "warp": {"color": {"srgb": [0.1, 0.1, 0.8]}}})";
  }
  ASSERT_EQ(run(exe + " check " + (dir / "warp.json").string() + " 2>&1", &out), 0) << out;
  const auto wj = nlohmann::json::parse(out);
  EXPECT_FALSE(wj["warp"].contains("sequence"));
  EXPECT_EQ(wj["weft"]["sequence"], gs["weft"]["sequence"]);
  EXPECT_EQ(wj["yarn_types"].size(), 2u);
  // The spec's colour replaced the draft's sequences, and their yarn types went with them.
  EXPECT_FALSE(g.contains("yarn_types"));
  EXPECT_FALSE(g["warp"].contains("sequence"));
  EXPECT_NEAR(g["weft"]["color"]["srgb"][0].get<double>(), 0.8, 1e-12);
  // Bad: a missing draft, a field next to "wif", a draft with a shaft out of range.
  {
    std::ofstream(dir / "missing.json") << R"({"weave": {"wif": "nowhere.wif"}})";
    std::ofstream(dir / "extra.json") << R"({"weave": {"wif": "gingham.wif", "pattern": "plain"},
                                             "yarn": {"color": {"srgb": [1, 1, 1]}}})";
    std::ofstream(dir / "bad.wif") << "[WIF]\n[WEAVING]\nShafts=2\nTreadles=1\n[WARP]\n"
                                      "Threads=2\n[WEFT]\nThreads=2\n[THREADING]\n1=1\n2=5\n"
                                      "[TIEUP]\n1=1\n[TREADLING]\n1=1\n2=1\n";
  }
  {
    std::ofstream(dir / "raywave.json") << R"({"weave": {"wif": "gingham.wif"},
                                               "model": {"tier": "raywave"}})";
  }
  const std::pair<std::string, std::string> bad[] = {
      {"raywave.json", "$.model.tier: \"raywave\" does not yet take per-thread yarn sequences"},
      {"missing.json", "nowhere.wif: cannot read this file"},
      {"extra.json", "$.weave.pattern: not allowed next to \"wif\""},
      {"bad.wif", "bad.wif line 11 [THREADING]: 2=5"}};
  for (const auto& [file, want] : bad) {
    const auto atlas = dir / (file + ".atlas");
    EXPECT_EQ(run(exe + " bake " + (dir / file).string() + " --quality draft -o " +
                      atlas.string() + " 2>&1",
                  &out),
              2)
        << out;
    EXPECT_NE(out.find(want), std::string::npos) << out;
    EXPECT_FALSE(std::filesystem::exists(atlas)) << file;
  }
}
