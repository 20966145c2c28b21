// loom-bake's command-line conventions (issue 34): --version with the commit, --threads before
// or after the subcommand (results independent of it), the exit codes in --help, a destination
// that is not an atlas refused as bad input with nothing written, a bake's errors as JSON with
// --progress=json, -q and -v, batch bakes.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <nlohmann/json.hpp>
#include <algorithm>
#include <cctype>
#include <string>
#include <vector>

#include "loom/atlas.h"
#include "loom/spec.h"
#include "test_util.h"

namespace {

TEST(CliConventions, VersionNamesTheCommit) {
  std::string out;
  ASSERT_EQ(loom::test::run(loom::test::bake_exe() + " --version", &out), 0) << out;
  // "loom-bake X.Y.Z (commit C)", C hexadecimal (7 to 40 digits, "-dirty" after it for a
  // changed tree) or "unknown" outside a git checkout.
  const std::string head = "loom-bake ", mid = " (commit ";
  ASSERT_EQ(out.rfind(head, 0), 0u) << out;
  const size_t m = out.find(mid), end = out.find(')');
  ASSERT_TRUE(m != std::string::npos && end != std::string::npos && end > m) << out;
  const std::string version = out.substr(head.size(), m - head.size());
  EXPECT_EQ(std::count(version.begin(), version.end(), '.'), 2) << version;
  for (char c : version) EXPECT_TRUE(std::isdigit(static_cast<unsigned char>(c)) || c == '.') << version;
  std::string commit = out.substr(m + mid.size(), end - m - mid.size());
  if (commit.size() > 6 && commit.substr(commit.size() - 6) == "-dirty") commit.resize(commit.size() - 6);
  if (commit != "unknown") {
    EXPECT_GE(commit.size(), 7u) << commit;
    EXPECT_LE(commit.size(), 40u) << commit;
    for (char c : commit) EXPECT_TRUE(std::isxdigit(static_cast<unsigned char>(c))) << commit;
  }
}

TEST(CliConventions, HelpListsTheExitCodes) {
  std::string out;
  ASSERT_EQ(loom::test::run(loom::test::bake_exe() + " --help", &out), 0);
  for (const char* s : {"Exit codes", "0 done", "1 failed", "2 bad input", "3 not a valid atlas",
                        "--threads", "--version"})
    EXPECT_NE(out.find(s), std::string::npos) << s;
}

TEST(CliConventions, SpecHelpNamesEveryPreset) {
  // Every subcommand that takes a spec lists every built-in preset in its help.
  const std::string exe = loom::test::bake_exe();
  for (const char* sub : {"bake", "check", "fibers", "eval truth", "eval swatch", "eval fibers",
                          "eval plysim"}) {
    std::string out;
    ASSERT_EQ(loom::test::run(exe + " " + sub + " --help", &out), 0) << sub;
    for (const std::string& name : loom::preset_names())
      EXPECT_NE(out.find(name), std::string::npos) << sub << ": " << name;
  }
}

TEST(CliConventions, TheSameFlagForTheSameThingEverywhere) {
  // -o for every output; a spec positional or as --spec, an atlas positional or as --atlas.
  const std::string exe = loom::test::bake_exe();
  for (const char* sub : {"bake", "fibers", "eval truth"}) {
    std::string out;
    ASSERT_EQ(loom::test::run(exe + " " + sub + " --help", &out), 0) << sub;
    EXPECT_NE(out.find("-o,--"), std::string::npos) << sub << " has no -o:\n" << out;
  }
  for (const char* sub : {"bake", "check", "fibers"}) {
    std::string out;
    ASSERT_EQ(loom::test::run(exe + " " + sub + " --help", &out), 0) << sub;
    EXPECT_NE(out.find("  spec TEXT"), std::string::npos) << sub << ":\n" << out;
    EXPECT_NE(out.find("  --spec TEXT"), std::string::npos) << sub << ":\n" << out;
  }
  std::string positional, named;
  ASSERT_EQ(loom::test::run(exe + " check plain", &positional), 0);
  ASSERT_EQ(loom::test::run(exe + " check --spec plain", &named), 0);
  EXPECT_EQ(positional, named);
  const auto atlas = loom::test::draft_atlas("plain", "surface");
  ASSERT_EQ(loom::test::run(exe + " inspect --json " + atlas.string(), &positional), 0);
  ASSERT_EQ(loom::test::run(exe + " inspect --json --atlas " + atlas.string(), &named), 0);
  EXPECT_EQ(positional, named);
  const auto dir = loom::test::scratch("same_flags") / "fibers";
  std::filesystem::remove_all(dir);
  ASSERT_EQ(loom::test::run(exe + " fibers plain --region 0,0,300,300 -o " + dir.string() +
                                " 2>&1",
                            &named),
            0)
      << named;
  EXPECT_TRUE(std::filesystem::exists(dir / "manifest.json")) << named;
}

TEST(CliConventions, ThreadsChangeNothingButTheSpeed) {
  const std::string exe = loom::test::bake_exe();
  const std::string cmd = " eval truth --spec plain --wi 0.3,0.1,0.9 --rays 3000 --min-yarns 2";
  std::string all, one, before;
  ASSERT_EQ(loom::test::run(exe + cmd, &all), 0) << all;
  ASSERT_EQ(loom::test::run(exe + cmd + " --threads 1", &one), 0) << one;
  ASSERT_EQ(loom::test::run(exe + " --threads 2" + cmd, &before), 0) << before;
  for (const std::string* o : {&one, &before})
    for (const char* k : {"reflect", "transmit", "absorbed"})
      EXPECT_EQ(nlohmann::json::parse(*o).at(k), nlohmann::json::parse(all).at(k)) << k;
  std::string bad;
  EXPECT_EQ(loom::test::run(exe + " --threads 0 presets 2>&1", &bad), 2);
  EXPECT_NE(bad.find("--threads"), std::string::npos) << bad;
}

TEST(CliConventions, BakingOverAFolderThatIsNotAnAtlasIsBadInput) {
  namespace fs = std::filesystem;
  const fs::path dir = loom::test::scratch("not-an-atlas");
  fs::create_directories(dir);
  std::ofstream(dir / "notes.txt") << "a user's file\n";
  std::string out;
  EXPECT_EQ(loom::test::run(loom::test::bake_exe() + " bake plain --progress none -o " +
                                dir.string() + " 2>&1",
                            &out),
            2)
      << out;
  EXPECT_NE(out.find("-o"), std::string::npos) << out;
  EXPECT_NE(out.find("not a Loom atlas"), std::string::npos) << out;
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.exists();
  EXPECT_EQ(n, 1u);  // the user's file alone, untouched
}

// With --progress=json (what the add-on reads), a bake's failure is also a JSON line on stdout
// naming the problem, with the exit code; without it stdout stays empty on failure.
TEST(CliConventions, BakeErrorsAreJsonOnStdoutWithProgressJson) {
  namespace fs = std::filesystem;
  const std::string exe = loom::test::bake_exe();
  const fs::path spec = loom::test::scratch("bad-spec") / "bad.json";
  fs::create_directories(spec.parent_path());
  std::ofstream(spec) << R"({"schema": "loom.fabric/1", "weave": {"pattern": "plain"},
    "density": {"warp_per_cm": -3}})";
  const fs::path not_atlas = loom::test::scratch("json-not-an-atlas");
  fs::create_directories(not_atlas);
  std::ofstream(not_atlas / "notes.txt") << "a user's file\n";
  const fs::path fresh = loom::test::scratch("json-fresh") / "out.atlas";
  struct Case {
    std::string args, names;
  };
  for (const Case& k : {Case{spec.string() + " -o " + fresh.string(), "warp_per_cm"},
                        Case{"plain -o " + not_atlas.string(), "-o"}}) {
    std::string out;
    EXPECT_EQ(loom::test::run(exe + " bake " + k.args + " --progress=json 2>/dev/null", &out), 2)
        << out;
    nlohmann::json last;
    for (size_t p = 0, e; p < out.size(); p = e + 1) {
      e = out.find('\n', p);
      if (e == std::string::npos) e = out.size();
      if (e > p) last = nlohmann::json::parse(out.substr(p, e - p));
    }
    ASSERT_TRUE(last.is_object() && last.contains("error")) << out;
    EXPECT_EQ(last.at("exit"), 2) << out;
    EXPECT_NE(last.at("error").get<std::string>().find(k.names), std::string::npos) << out;
    EXPECT_FALSE(last.at("errors").empty()) << out;
    std::string quiet;
    EXPECT_EQ(loom::test::run(exe + " bake " + k.args + " --progress=none 2>/dev/null", &quiet), 2);
    EXPECT_TRUE(quiet.empty()) << quiet;
  }
  EXPECT_FALSE(fs::exists(fresh));
}

// -v: a bake says each stage once, on a line of its own with its time; by default (no terminal)
// and with -q (also with --progress=text) it says nothing on stderr; -q and -v together are a
// bad command line.
TEST(CliConventions, QuietAndVerbose) {
  const std::string exe = loom::test::bake_exe();
  const std::string atlas = (loom::test::scratch("quiet-verbose") / "a.atlas").string();
  // (-q with --progress=text: quiet wins; -q alone is the same with less asked of it.)
  for (const char* flags : {"-q", "", "-v"}) {
    const std::string progress = std::string(flags) == "-q" ? " --progress=text" : "";
    std::string err;  // stderr alone: stdout to /dev/null
    ASSERT_EQ(loom::test::run(exe + " " + flags + " bake plain --quality draft --force" +
                                  progress + " -o " + atlas + " 2>&1 1>/dev/null",
                              &err),
              0)
        << flags << progress << ": " << err;
    if (std::string(flags) != "-v") {
      EXPECT_TRUE(err.empty()) << flags << ": " << err;
      continue;
    }
    std::vector<std::string> stages;  // "loom-bake: <stage> done (<t> s)", a line each
    for (size_t p = err.find("loom-bake: "); p != std::string::npos;
         p = err.find("loom-bake: ", p + 1)) {
      const size_t d = err.find(" done (", p), e = err.find('\n', p);
      ASSERT_TRUE(d != std::string::npos && d < e) << err;
      stages.push_back(err.substr(p + 11, d - p - 11));
    }
    EXPECT_GE(stages.size(), 5u) << err;  // the surface bake's stages, each once: the maps'
    std::vector<std::string> sorted = stages;  // writing, then the fits: per texel, averaged
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(std::unique(sorted.begin(), sorted.end()), sorted.end()) << err;
    ASSERT_GE(stages.size(), 3u) << err;
    EXPECT_EQ(stages[stages.size() - 3], "write") << err;
    EXPECT_EQ(stages[stages.size() - 2], "fitted closures") << err;
    EXPECT_EQ(stages.back(), "average") << err;
  }
  std::string both;
  EXPECT_EQ(loom::test::run(exe + " -q -v presets 2>&1", &both), 2) << both;
}

TEST(CliConventions, BakesSeveralSpecsOrAFolderEachIntoItsOwnAtlas) {
  // Several specs (a preset and a draft) into -o/<name>; a folder of specs (its *.json and
  // *.wif) likewise; one bad spec among them: exit 2, every problem named, nothing written.
  namespace fs = std::filesystem;
  const std::string exe = loom::test::bake_exe();
  const fs::path src = loom::test::source_dir(), dir = loom::test::scratch("batch");
  const fs::path specs = dir / "specs", out = dir / "out";
  fs::create_directories(specs);
  fs::copy_file(src / "presets" / "drafts" / "point_twill.wif", specs / "point_twill.wif");
  std::ofstream(specs / "red.json") << R"({"yarn": {"color": {"srgb": [0.8, 0.1, 0.1]}}})";
  std::ofstream(specs / "notes.txt") << "not a spec";
  std::string res;
  ASSERT_EQ(loom::test::run(exe + " bake " + specs.string() + " plain --quality draft "
                                "--progress=json -o " + out.string() + " 2>&1",
                            &res),
            0)
      << res;
  std::vector<std::string> done;
  std::istringstream lines(res);
  for (std::string line; std::getline(lines, line);) {
    const auto j = nlohmann::json::parse(line);
    ASSERT_TRUE(j.contains("spec")) << line;  // every line says whose it is
    if (j.contains("atlas"))
      done.push_back(fs::path(j["atlas"].get<std::string>()).filename().string());
  }
  std::sort(done.begin(), done.end());  // (baked up to --threads at once: in any order)
  EXPECT_EQ(done, (std::vector<std::string>{"plain", "point_twill", "red"})) << res;
  for (const auto& name : {"point_twill", "red", "plain"})
    EXPECT_TRUE(loom::validate_atlas(out / name).empty()) << name;
  EXPECT_FALSE(fs::exists(out / "notes")) << "a file that is not a spec was baked";
  // Two of one name, and a bad spec: refused before any work.
  const fs::path out2 = dir / "out2";
  std::ofstream(dir / "bad.json") << R"({"density": {"warp_per_cm": 0}})";
  EXPECT_EQ(loom::test::run(exe + " bake " + (dir / "bad.json").string() + " " +
                                (specs / "red.json").string() + " " + specs.string() +
                                " --quality draft -o " + out2.string() + " 2>&1",
                            &res),
            2)
      << res;
  EXPECT_NE(res.find("bad.json: $.density.warp_per_cm"), std::string::npos) << res;
  EXPECT_NE(res.find("both would bake into"), std::string::npos) << res;
  EXPECT_FALSE(fs::exists(out2)) << "a refused batch wrote something";
}

}  // namespace
