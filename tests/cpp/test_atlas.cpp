// Atlas contract: bake, validate, reject broken atlases, reuse, CLI behaviour, evaluators.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <sstream>

#include "loom/atlas.h"
#include "loom/bake.h"
#include "test_util.h"
#include "loom/evaluator.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using loom::test::run;
using loom::test::scratch;

loom::FabricSpec draft(const std::string& preset) {
  auto r = loom::parse_spec(loom::preset(preset), "draft");
  EXPECT_TRUE(r.ok());
  return r.spec;
}

/// The draft plain atlas the tests of this file read or copy: the one the test processes share
/// (draft_atlas), baked once per run.
const fs::path& plain_atlas() { return loom::test::draft_atlas("plain", "surface"); }


fs::path copy_atlas(const std::string& name) {
  fs::path d = scratch(name);
  fs::copy(plain_atlas(), d);
  return d;
}

void edit_manifest(const fs::path& d, const std::function<void(json&)>& f) {
  json m = json::parse(std::ifstream(d / "manifest.json"));
  f(m);
  std::ofstream(d / "manifest.json") << m.dump();
}

}  // namespace

TEST(Atlas, BakeProducesAValidAtlas) {
  const fs::path d = scratch("plain.atlas");  // its own: the shared ones' folder has others' bakes
  loom::bake_atlas(draft("plain"), d, {});
  json m;
  auto errors = loom::validate_atlas(d, &m);
  EXPECT_TRUE(errors.empty()) << ::testing::PrintToString(errors);
  EXPECT_EQ(m["schema"], loom::kAtlasSchema);
  EXPECT_EQ(m["spec_sha256"].get<std::string>().size(), 64u);
  EXPECT_EQ(m["colour"]["from"], "sRGB");
  for (const char* name : {"ply_frame", "ply_normal", "yarn_info", "albedo_reflect",
                           "albedo_transmit", "spec_params", "horizon_0", "horizon_1",
                           "closure_lut"}) {
    ASSERT_TRUE(m["textures"].contains(name)) << name;
    EXPECT_TRUE(fs::exists(d / m["textures"][name]["file"].get<std::string>()));
  }
  // No temporary directory is left beside it.
  for (auto& e : fs::directory_iterator(d.parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

TEST(Atlas, ColourGoesThroughOCIO) {
  // sRGB 0.5 -> linear 0.214041 (IEC 61966-2-1), as recorded in the yarn colours.
  auto s = draft("plain");
  s.warp.color_input = s.weft.color_input = {0.5, 0.5, 0.5};
  auto d = scratch("grey.atlas");
  loom::bake_atlas(s, d, {});
  json m = json::parse(std::ifstream(d / "manifest.json"));
  EXPECT_NEAR(m["yarn_colours_linear"]["warp"][0].get<double>(), 0.2140411, 2e-4);
}

TEST(Atlas, ReusesAValidAtlasOfTheSameSpec) {
  auto d = copy_atlas("reuse.atlas");
  auto r = loom::bake_atlas(draft("plain"), d, {});
  EXPECT_TRUE(r.reused);
  auto s = draft("plain");
  s.warp.roughness = 0.5;
  auto r2 = loom::bake_atlas(s, d, {});  // different spec: replaced atomically
  EXPECT_FALSE(r2.reused);
  json m = json::parse(std::ifstream(d / "manifest.json"));
  EXPECT_EQ(m["spec"]["warp"]["roughness"], 0.5);
  EXPECT_TRUE(loom::validate_atlas(d).empty());
}

TEST(Atlas, AnAtlasWhoseBakeKeyIsNotAStringIsReplaced) {
  // Found by fuzz_manifest (stop 19): an atlas already at the target whose bake_key was not a
  // string made the bake itself throw nlohmann's type_error, where it must be taken for another
  // spec's atlas and replaced. Both places read it: the check for reuse before the bake and
  // the one at publishing, when the rename meets the existing directory. (A number and null:
  // every other non-string type takes the same path; each key costs a draft bake.)
  for (const json& key : {json(12345), json(nullptr)}) {
    auto d = copy_atlas("bake_key.atlas");
    json m = json::parse(std::ifstream(d / "manifest.json"));
    m["bake_key"] = key;
    std::ofstream(d / "manifest.json") << m.dump(2);
    loom::BakeResult r;
    ASSERT_NO_THROW(r = loom::bake_atlas(draft("plain"), d, {})) << key.dump();
    EXPECT_FALSE(r.reused) << key.dump();
    json after = json::parse(std::ifstream(d / "manifest.json"));
    EXPECT_TRUE(after["bake_key"].is_string()) << key.dump();
    EXPECT_TRUE(loom::validate_atlas(d).empty()) << key.dump();
  }
}

TEST(Atlas, RejectsCorruptedTruncatedAndForeignAtlases) {
  auto d = copy_atlas("corrupt.atlas");
  { std::ofstream(d / "ply_frame.tx", std::ios::binary | std::ios::trunc) << "x"; }
  auto e = loom::validate_atlas(d);
  ASSERT_FALSE(e.empty());
  EXPECT_NE(e[0].find("sha256"), std::string::npos);

  d = copy_atlas("schema.atlas");
  edit_manifest(d, [](json& m) { m["schema"] = "loom.atlas/0"; });
  e = loom::validate_atlas(d);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NE(e[0].find("not supported"), std::string::npos);

  d = copy_atlas("escape.atlas");
  edit_manifest(d, [](json& m) { m["textures"]["ply_frame"]["file"] = "../../etc/passwd"; });
  e = loom::validate_atlas(d);
  ASSERT_FALSE(e.empty());
  EXPECT_NE(e[0].find("plain file name"), std::string::npos);

  d = copy_atlas("nomanifest.atlas");
  fs::remove(d / "manifest.json");
  EXPECT_FALSE(loom::validate_atlas(d).empty());
  EXPECT_THROW(loom::load_atlas(d), std::runtime_error);
}

TEST(Atlas, RefusesToReplaceANonAtlasDirectory) {
  auto d = scratch("user_stuff");
  fs::create_directories(d);
  std::ofstream(d / "precious.txt") << "keep me";
  EXPECT_THROW(loom::bake_atlas(draft("plain"), d, {}), std::runtime_error);
  loom::BakeOptions force;
  force.force = true;  // --force re-bakes an atlas; it never deletes a user's folder
  EXPECT_THROW(loom::bake_atlas(draft("plain"), d, force), std::runtime_error);
  std::ofstream(d / "manifest.json") << R"({"name": "some web extension"})";
  EXPECT_THROW(loom::bake_atlas(draft("plain"), d, force), std::runtime_error);
  EXPECT_TRUE(fs::exists(d / "precious.txt"));
  // An atlas of another schema version is Loom's own: replaced.
  auto old = copy_atlas("old_schema.atlas");
  edit_manifest(old, [](json& m) { m["schema"] = "loom.atlas/0"; });
  EXPECT_NO_THROW(loom::bake_atlas(draft("plain"), old, {}));
  EXPECT_TRUE(loom::validate_atlas(old).empty());
}

TEST(Atlas, SweepsTemporariesOfDeadBakes) {
  auto d = scratch("swept.atlas");
  // A temporary left by a bake killed with SIGKILL: its PID does not exist any more.
  fs::path stale = d.parent_path() / ".swept.atlas.tmp-999999999-deadbeef";
  fs::create_directories(stale);
  std::ofstream(stale / "ply_frame.exr") << "half written";
  loom::bake_atlas(draft("plain"), d, {});
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(loom::validate_atlas(d).empty());
}

TEST(AtlasCli, InvalidSpecWritesNothingAndExitsNonZero) {
  auto spec = scratch("bad.json");
  std::ofstream(spec) << R"({"warp": {"ior": 7}, "weave": {"pattern": "tartan"}})";
  auto out = scratch("bad.atlas");
  std::string text;
  int code = run(loom::test::bake_exe() + " bake " + spec.string() + " -o " + out.string() +
                     " 2>&1",
                 &text);
  EXPECT_EQ(code, 2);
  EXPECT_NE(text.find("$.warp.ior"), std::string::npos) << text;
  EXPECT_NE(text.find("$.weave.pattern"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(out));
  for (auto& e : fs::directory_iterator(out.parent_path()))
    EXPECT_EQ(e.path().filename().string().find("bad.atlas"), std::string::npos);
}

TEST(AtlasCli, InspectAndEval) {
  std::string text;
  EXPECT_EQ(run(loom::test::bake_exe() + " inspect " + plain_atlas().string(), &text), 0);
  EXPECT_NE(text.find("valid"), std::string::npos);
  EXPECT_EQ(run(loom::test::bake_exe() + " eval bsdf --atlas " + plain_atlas().string() +
                    " --uv 0.25,0.25 --wi 0,0.5,0.866 --wo 0.2,0,1 --evaluator closures",
                &text),
            0);
  auto j = json::parse(text);
  ASSERT_EQ(j["f"].size(), 3u);
  EXPECT_GT(j["f"][0].get<double>(), 0.0);
  // Several (wi, wo) pairs in one call: one line per pair, each what a call of its own prints;
  // unequal counts of --wi and --wo are bad input.
  const std::string eval = loom::test::bake_exe() + " eval bsdf --average --atlas " +
                           plain_atlas().string() + " --evaluator closures";
  std::string one, two, both;
  ASSERT_EQ(run(eval + " --wi 0,0.5,0.866 --wo 0.2,0,1", &one), 0);
  ASSERT_EQ(run(eval + " --wi -0.3,0.1,-0.9 --wo 0,0,1", &two), 0);
  ASSERT_EQ(run(eval + " --wi 0,0.5,0.866 --wo 0.2,0,1 --wi -0.3,0.1,-0.9 --wo 0,0,1", &both), 0);
  EXPECT_EQ(both, one + two);
  EXPECT_NE(one, two);
  EXPECT_EQ(run(eval + " --wi 0,0,1 --wi 0,0,1 --wo 0,0,1 2>&1", &text), 2);
  EXPECT_NE(text.find("--wi and --wo"), std::string::npos) << text;
  auto bad = copy_atlas("inspect_bad.atlas");
  fs::remove(bad / "horizon_0.exr");
  EXPECT_EQ(run(loom::test::bake_exe() + " inspect " + bad.string() + " 2>&1", &text), 3);
  EXPECT_NE(text.find("horizon_0.exr is missing"), std::string::npos) << text;
  // Summary fields that validation does not require (the evaluators do not read them) may be
  // missing or of another type: inspect still summarises, naming what is absent (it threw a
  // JSON type_error, exit 1, before).
  auto bare = copy_atlas("inspect_bare.atlas");
  edit_manifest(bare, [](json& m) {
    m["spec"].erase("name");
    m["quality"] = 3;
    m.erase("repeat");
  });
  ASSERT_TRUE(loom::validate_atlas(bare).empty());
  EXPECT_EQ(run(loom::test::bake_exe() + " inspect " + bare.string() + " 2>&1", &text), 0);
  EXPECT_NE(text.find("(no spec.name)"), std::string::npos) << text;
  EXPECT_NE(text.find("(no repeat.warp_yarns)"), std::string::npos) << text;
  EXPECT_EQ(run(loom::test::bake_exe() + " inspect --json " + bare.string(), &text), 0);
  const json bare_summary = json::parse(text);
  EXPECT_TRUE(bare_summary["name"].is_null());
  EXPECT_TRUE(bare_summary["repeat"].is_null());
  EXPECT_EQ(bare_summary["quality"], 3);
}

TEST(Evaluators, SampleAtTexelCentreIsTheTexel) {
  auto a = loom::load_atlas(plain_atlas());
  const auto& img = a.map("ply_frame");
  for (int k = 0; k < 20; ++k) {
    int ix = (k * 7) % img.width, iy = (k * 13) % img.height;
    auto p = loom::sample_surface(a, (ix + 0.5f) / img.width, (iy + 0.5f) / img.height);
    auto q = loom::texel_surface(a, ix, iy);
    EXPECT_NEAR(p.height, q.height, 1e-3);
    EXPECT_NEAR(p.gap, q.gap, 1e-6);
  }
}

TEST(Evaluators, ClosureMixtureConservesEnergyAndTracksTheModel) {
  auto a = loom::load_atlas(plain_atlas());
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> U(0, 1);
  using loom::shading::vec3;
  for (int k = 0; k < 6; ++k) {
    auto p = loom::sample_surface(a, U(rng), U(rng));
    vec3 V = loom::shading::normalize(vec3(U(rng) - 0.5f, U(rng) - 0.5f, 0.2f + U(rng)));
    double e_model = 0, e_clos = 0;
    int n = 200;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < 2 * n; ++j) {
        double z = -1 + (i + 0.5) * 2.0 / n, r = std::sqrt(1 - z * z), ph = (j + 0.5) * M_PI / n;
        vec3 L{float(r * std::cos(ph)), float(r * std::sin(ph)), float(z)};
        double dw = (2.0 / n) * (M_PI / n) * std::fabs(z);
        e_model += loom::eval_bsdf(a, p, L, V, loom::Evaluator::Model)[1] * dw;
        e_clos += loom::eval_bsdf(a, p, L, V, loom::Evaluator::Closures)[1] * dw;
      }
    EXPECT_LE(e_clos, 1.0 + 1e-3);
    EXPECT_LE(e_model, 1.0 + 1e-3);
    // Same energy up to what the closures cannot carry (light-side visibility): within 25%.
    EXPECT_NEAR(e_clos, e_model, 0.25 * e_model + 1e-3) << k;
  }
}

TEST(AtlasCli, ProgressJsonLinesEndWithTheResult) {
  auto d = scratch("progress.atlas");
  std::string text;
  ASSERT_EQ(run(loom::test::bake_exe() + " bake plain --quality draft --progress=json -o " +
                    d.string(),
                &text),
            0);
  std::istringstream in(text);
  std::string line, last;
  int stages = 0;
  while (std::getline(in, line)) {
    auto j = json::parse(line);
    if (j.contains("stage")) {
      double f = j["fraction"].get<double>();
      EXPECT_GE(f, 0.0);
      EXPECT_LE(f, 1.0);
      ++stages;
    }
    last = line;
  }
  EXPECT_GE(stages, 4);
  auto r = json::parse(last);
  EXPECT_EQ(r["atlas"], fs::absolute(d).string());
  EXPECT_EQ(r["reused"], false);
}

TEST(AtlasCli, ConcurrentBakesOfOneSpecLeaveOneValidAtlas) {
  auto d = scratch("concurrent.atlas");
  std::string cmd = loom::test::bake_exe() + " bake twill --quality draft --progress=none -o " +
                    d.string() + " >/dev/null";
  auto codes = scratch("codes.txt");
  std::string one = "(" + cmd + "; echo $? >> " + codes.string() + ")";
  ASSERT_EQ(run("(" + one + " & " + one + " & " + one + " & wait) 2>&1"), 0);
  std::ifstream in(codes);
  int code, n = 0;
  while (in >> code) {
    EXPECT_EQ(code, 0);
    ++n;
  }
  EXPECT_EQ(n, 3);
  EXPECT_TRUE(loom::validate_atlas(d).empty());
  int leftovers = 0;
  for (auto& e : fs::directory_iterator(d.parent_path()))
    leftovers += e.path().filename().string().find("concurrent.atlas.tmp") != std::string::npos;
  EXPECT_EQ(leftovers, 0);
}

TEST(AtlasCli, KilledBakesLeaveACompleteAtlasOrNone) {
  // SIGKILL (no clean-up possible) right after each progress line a bake prints: after every
  // stage and every texture written, wherever this machine's speed puts them. First into an
  // empty place, then re-baking over an existing atlas. The place holds either a complete, valid
  // atlas (the old or the new one) or nothing, never a half one; the next bake sweeps the dead
  // bakes' temporaries.
  const auto d = scratch("killed.atlas");
  const std::string prefix = ".killed.atlas.tmp-";
  auto temporaries = [&] {
    int n = 0;
    for (auto& e : fs::directory_iterator(d.parent_path()))
      n += e.path().filename().string().rfind(prefix, 0) == 0;
    return n;
  };
  // Bakes `quality` into d and kills it after its `lines`-th progress line (0: lets it finish).
  // Returns 1 if it was killed, 0 if it ended first (exit status in *exit_code).
  auto bake = [&](const std::string& quality, int lines, int* exit_code = nullptr,
                  std::vector<std::string>* printed = nullptr) {
    const std::string exe = loom::test::bake_exe();
    int fds[2];
    if (pipe(fds) != 0) return -1;
    const pid_t pid = fork();
    if (pid == 0) {
      close(fds[0]);
      dup2(fds[1], 1);
      const int null = open("/dev/null", O_WRONLY);
      dup2(null, 2);
      execl(exe.c_str(), exe.c_str(), "bake", "plain", "--quality", quality.c_str(),
            "--force", "--progress=json", "-o", d.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    close(fds[1]);
    int seen = 0;
    bool killed = false;
    char c;
    std::string line;
    while (read(fds[0], &c, 1) == 1) {
      if (c != '\n') {
        line += c;
        continue;
      }
      if (printed) printed->push_back(line);
      line.clear();
      if (++seen == lines) {
        kill(pid, SIGKILL);
        killed = true;
        break;
      }
    }
    close(fds[0]);
    int st = 0;
    waitpid(pid, &st, 0);
    if (exit_code) *exit_code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return killed && WIFSIGNALED(st) && WTERMSIG(st) == SIGKILL ? 1 : 0;
  };
  // Into an empty place, killed once a texture is in its temporary.
  ASSERT_EQ(bake("draft", 9), 1) << "the first bake ended before it could be killed";
  EXPECT_FALSE(fs::exists(d)) << "a killed first bake published an atlas";
  EXPECT_EQ(temporaries(), 1) << "the killed bake's temporary";
  int code = -1;
  std::vector<std::string> printed;
  ASSERT_EQ(bake("draft", 0, &code, &printed), 0);
  ASSERT_EQ(code, 0);
  EXPECT_TRUE(loom::validate_atlas(d).empty());
  EXPECT_EQ(temporaries(), 0) << "the dead bake's temporary was not swept";
  // Over the draft atlas: another draft bake (--force: baked afresh, not reused) killed after
  // the first line of each stage (at the closure LUT's: no texture in the temporary yet), the
  // first, middle and last line of the writing (one, some and all of the maps written; the LUT
  // follows them), and the last progress line before the result:
  // each a different state of the temporary (a kill after the n-th line re-runs the bake up to
  // it, so every line would cost O(lines^2) bakes; 6 min under the sanitizers).
  std::set<int> kill_at;
  std::vector<int> writes;
  std::string stage_before;
  for (size_t n = 0; n + 1 < printed.size(); ++n) {  // the last line is the result
    const json j = json::parse(printed[n]);
    const std::string stage = j.value("stage", "");
    if (stage != stage_before || n + 2 == printed.size()) kill_at.insert(int(n) + 1);
    if (stage == "write") writes.push_back(int(n) + 1);
    stage_before = stage;
  }
  ASSERT_GE(writes.size(), 3u) << "a draft bake writes fewer textures than expected";
  kill_at.insert({writes[writes.size() / 2], writes.back()});
  EXPECT_GE(kill_at.size(), 7u) << "a draft bake prints fewer stages than expected";
  int killed = 0;
  for (int n : kill_at) {
    const int k = bake("draft", n);
    ASSERT_GE(k, 0);
    json m;
    const auto errors = loom::validate_atlas(d, &m);
    ASSERT_TRUE(errors.empty()) << "after a kill at progress line " << n << ": "
                                << ::testing::PrintToString(errors);
    killed += k;
  }
  // (after the last progress line the bake may publish and end before the kill arrives)
  EXPECT_GE(killed, int(kill_at.size()) - 1) << "bakes ended before their kill";
  ASSERT_EQ(bake("draft", 0, &code), 0);
  ASSERT_EQ(code, 0);
  EXPECT_TRUE(loom::validate_atlas(d).empty());
  EXPECT_EQ(temporaries(), 0);
}

TEST(Evaluators, RandomSweepNeverNaNNorInf) {
  // A million (wi, wo) pairs per evaluator (200,000 in the test command, a million with
  // scripts/test.sh --full) over random texels: uniform directions, plus grazing (|cos| down to
  // 1e-6 and exactly 0), mirrored, opposite and non-finite ones.
  auto a = loom::load_atlas(plain_atlas());
  using loom::shading::vec3;
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> U(-1, 1);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<loom::SurfacePoint> pts;
  for (int k = 0; k < 256; ++k) pts.push_back(loom::sample_surface(a, U(rng), U(rng)));
  auto dir = [&](int kind) {
    vec3 d = loom::shading::normalize(vec3(U(rng), U(rng), U(rng)));
    switch (kind) {
      case 0: return d;
      case 1: return loom::shading::normalize(vec3(d.x, d.y, 1e-6f * (d.z < 0 ? -1.0f : 1.0f)));
      case 2: return loom::shading::normalize(vec3(d.x, d.y, 0.0f));
      case 3: return vec3(0, 0, 1);
      case 4: return vec3(nan, d.y, d.z);
      default: return vec3(d.x, inf, d.z);
    }
  };
  // The model, and the closures as node mode and as the OSL shader build them.
  const std::pair<loom::Evaluator, loom::Backend> evaluators[] = {
      {loom::Evaluator::Model, loom::Backend::Nodes},
      {loom::Evaluator::Closures, loom::Backend::Nodes},
      {loom::Evaluator::Closures, loom::Backend::Osl}};
  for (auto [e, b] : evaluators) {
    int bad = 0;
    for (int n = 0; n < loom::test::sweep(200000, 1000000); ++n) {
      int ki = (n % 97 == 0) ? 4 + (n / 97) % 2 : (n % 7 == 0 ? 1 + (n / 7) % 3 : 0);
      vec3 wi = dir(ki), wo = n % 11 == 0 ? -wi : dir(n % 13 == 0 ? 1 + n % 3 : 0);
      auto f = loom::eval_bsdf(a, pts[n & 255], wi, wo, e, b);
      for (float c : f) bad += !(std::isfinite(c) && c >= 0.0f);
    }
    EXPECT_EQ(bad, 0) << int(e) << " " << int(b);
  }
}
