// Per-thread yarn types (spec.h: "yarn_types", "sequence"): the repeat tiled to hold whole
// sequences, the canonical form, each texel of the surface maps coloured by its own thread (the
// sequence expanded here by hand), and the refusals.
#include <gtest/gtest.h>

#include "loom/colour.h"
#include "loom/ply_maps.h"
#include "loom/spec.h"
#include "loom/weave.h"

namespace {

using nlohmann::json;

/// (Sequences as JSON text: an initializer list of [name, count] pairs would make an object.)
json striped(const std::string& warp_seq, const std::string& weft_seq,
             const std::string& pattern = "plain") {
  return {{"weave", {{"pattern", pattern}}},
          {"yarn_types",
           {{"white", {{"color", {{"linear", {0.9, 0.9, 0.9}}}}}},
            {"red", {{"color", {{"linear", {0.8, 0.05, 0.1}}}}}}}},
          {"warp", {{"sequence", json::parse(warp_seq)}}},
          {"weft", {{"sequence", json::parse(weft_seq)}}},
          {"model", {{"quality", "draft"}}}};
}

bool has_error(const loom::SpecResult& r, const std::string& want) {
  for (const auto& e : r.errors)
    if (e.find(want) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST(YarnSequences, TileTheRepeatAndRoundTrip) {
  const auto r = loom::parse_spec(striped(R"([["white", 3], ["red", 2]])", R"([["red", 1], ["white", 1]])"));
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  const loom::Weave w = loom::make_weave(r.spec.weave);
  ASSERT_EQ(w.rows(), 10);  // lcm(2, 5)
  ASSERT_EQ(w.cols(), 2);   // lcm(2, 2)
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 2; ++j) EXPECT_EQ(w.m[size_t(i)][size_t(j)], (i + j + 1) % 2);
  const json c = loom::canonical_spec(r.spec);
  EXPECT_EQ(c["warp"]["sequence"], json::parse(R"([["white", 3], ["red", 2]])"));
  EXPECT_EQ(c["weave"]["pattern"], "plain");  // the tiling is derived, not stored
  const auto again = loom::parse_spec(c);
  ASSERT_TRUE(again.ok()) << ::testing::PrintToString(again.errors);
  EXPECT_EQ(loom::canonical_spec(again.spec), c);
  // Adjacent runs of one type are one run; "yarn" gives both systems the sequence.
  json one = striped(R"([["red", 1], ["red", 2], ["white", 1]])", R"([["white", 1]])");
  one["yarn"] = {{"sequence", json::parse(R"([["white", 2]])")}};
  one["weft"].erase("sequence");
  one["weave"] = {{"pattern", "twill"}, {"up", 2}, {"down", 1}};
  const auto y = loom::parse_spec(one);
  ASSERT_TRUE(y.ok()) << ::testing::PrintToString(y.errors);
  EXPECT_EQ(loom::canonical_spec(y.spec)["warp"]["sequence"],
            json::parse(R"([["red", 3], ["white", 1]])"));
  EXPECT_EQ(loom::canonical_spec(y.spec)["weft"]["sequence"], json::parse(R"([["white", 2]])"));
  EXPECT_EQ(loom::make_weave(y.spec.weave).rows(), 12);  // lcm(3, 4)
  EXPECT_EQ(loom::make_weave(y.spec.weave).cols(), 6);   // lcm(3, 2)
}

TEST(YarnSequences, EachTexelHasItsThreadsColour) {
  // Warp: 2 white, 1 red; weft: 1 red, 3 white (a plain weave: a 6 x 4 repeat). A texel's
  // thread is the row (warp) or column (weft) of weave cells it lies in; its albedo is the
  // yarn's (1 - specular)(1 - transmission) times its type's colour.
  auto r = loom::parse_spec(striped(R"([["white", 2], ["red", 1]])", R"([["red", 1], ["white", 3]])"));
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  loom::resolve_yarn_colours(r.spec, loom::ColourConverter(""));
  const auto maps = loom::bake_surface_maps(r.spec, {}, false);
  const int tpc = loom::texels_per_cell(r.spec.quality);
  ASSERT_EQ(maps.warp_yarns, 6);
  ASSERT_EQ(maps.weft_yarns, 4);
  const std::array<double, 3> white{0.9, 0.9, 0.9}, red{0.8, 0.05, 0.1};
  auto warp_colour = [&](int i) { return i % 3 < 2 ? white : red; };
  auto weft_colour = [&](int j) { return j % 4 == 0 ? red : white; };
  const loom::Image& info = maps.images[2];
  const loom::Image& alb = maps.images[3];
  int seen[2][2] = {{0, 0}, {0, 0}};  // [warp/weft][white/red]
  for (int iy = 0; iy < info.height; ++iy)
    for (int ix = 0; ix < info.width; ++ix) {
      const int kind = int(std::lround(info.px(ix, iy)[0]));
      if (kind == 0) continue;
      const loom::YarnSpec& y = kind == 2 ? r.spec.weft : r.spec.warp;
      const double k = (1 - y.specular) * (1 - y.transmission);
      const auto want = kind == 1 ? warp_colour(iy / tpc) : weft_colour(ix / tpc);
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(alb.px(ix, iy)[c], k * want[size_t(c)], 1e-5)
            << "texel " << ix << ", " << iy << " kind " << kind;
      ++seen[kind - 1][want == red ? 1 : 0];
    }
  for (auto& s : seen)
    for (int n : s) EXPECT_GT(n, 0);
}

TEST(YarnSequences, BadSequencesNameTheField) {
  struct Case {
    json spec;
    std::string want;
  };
  json unknown = striped(R"([["blue", 2]])", R"([["red", 1]])");
  json zero = striped(R"([["red", 0]])", R"([["red", 1]])");
  json shape = striped(R"([["red", "2"]])", R"([["red", 1]])");
  json many = striped(R"([["red", 600], ["white", 600]])", R"([["red", 1]])");
  json lcm = striped(R"([["red", 1024]])", R"([["red", 1]])", "twill");
  json more = striped(R"([["red", 1]])", R"([["red", 1]])");
  more["yarn_types"]["red"]["roughness"] = 0.5;
  json raywave = striped(R"([["red", 1], ["white", 1]])", R"([["red", 1]])");
  raywave["model"]["tier"] = "raywave";
  const Case cases[] = {
      {unknown, "$.warp.sequence[0]: \"blue\" is not a yarn type ($.yarn_types: red, white)"},
      {zero, "$.warp.sequence[0]: expected runs [[type, count], ...]"},
      {shape, "$.warp.sequence[0]: expected runs"},
      {many, "$.warp.sequence: more than 1024 threads"},
      {lcm, "$.warp.sequence: the repeat grows to 3072 warp yarns"},
      {more, "$.yarn_types.red.roughness: yarn types that differ in more than colour are not "
             "yet supported"},
      {raywave, "$.model.tier: \"raywave\" does not yet take per-thread yarn sequences"},
  };
  for (const Case& c : cases) {
    const auto r = loom::parse_spec(c.spec);
    EXPECT_TRUE(has_error(r, c.want)) << c.want << " in " << ::testing::PrintToString(r.errors);
  }
}
