// Spec validation: every rejected case names its JSON path and the allowed range.
#include <gtest/gtest.h>

#include "loom/spec.h"

using loom::parse_spec;
using loom::parse_spec_text;
using nlohmann::json;

namespace {

json base() { return loom::preset("plain"); }

/// Exactly one error, mentioning every given fragment.
void expect_one_error(const json& doc, std::initializer_list<const char*> fragments) {
  auto r = parse_spec(doc);
  ASSERT_EQ(r.errors.size(), 1u) << doc.dump() << "\n" << ::testing::PrintToString(r.errors);
  for (const char* f : fragments) EXPECT_NE(r.errors[0].find(f), std::string::npos) << r.errors[0];
}

}  // namespace

TEST(Spec, PresetsAreValid) {
  for (auto& name : loom::preset_names()) {
    auto r = parse_spec(loom::preset(name));
    EXPECT_TRUE(r.ok()) << name << ": " << ::testing::PrintToString(r.errors);
  }
  EXPECT_THROW(loom::preset("tartan"), std::out_of_range);
}

TEST(Spec, EmptyObjectTakesDefaults) {
  auto r = parse_spec(json::object());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.spec.weave.pattern, "plain");
  EXPECT_EQ(r.spec.quality, loom::Quality::Preview);
}

TEST(Spec, ColourReadingSwatchOnBothAtlasTiers) {
  json d = base();
  d["model"]["tier"] = "raywave";
  auto r = parse_spec(d);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.spec.colour_reading, loom::ColourReading::PlyAlbedo);  // the default, for now
  EXPECT_EQ(loom::canonical_spec(r.spec)["model"]["colour_reading"], "ply_albedo");
  d["model"]["colour_reading"] = "swatch";
  r = parse_spec(d);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.spec.colour_reading, loom::ColourReading::Swatch);
  EXPECT_EQ(loom::canonical_spec(r.spec)["model"]["colour_reading"], "swatch");
  d["model"]["tier"] = "surface";  // solved on the surface tier too (surface_swatch.h)
  r = parse_spec(d);
  ASSERT_TRUE(r.ok()) << r.errors.at(0);
  EXPECT_EQ(r.spec.colour_reading, loom::ColourReading::Swatch);

  d["model"]["colour_reading"] = "paint";
  expect_one_error(d, {"$.model.colour_reading", "\"swatch\"", "\"ply_albedo\""});
}

TEST(Spec, WrongType) {
  json d = base();
  d["warp"] = {{"ior", "glass"}};
  expect_one_error(d, {"$.warp.ior", "[1, 3]", "string"});
}

TEST(Spec, OutOfRange) {
  json d = base();
  d["density"]["warp_per_cm"] = 0.5;
  expect_one_error(d, {"$.density.warp_per_cm", "[1, 400]", "yarns/cm"});
  d = base();
  d["yarn"]["plies"] = 9;  // "yarn" feeds warp and weft: reported once, where it was written
  expect_one_error(d, {"$.yarn.plies", "[1, 8]"});
  d["weft"] = {{"plies", 12}};  // the weft overrides it: its own message
  auto r = parse_spec(d);
  ASSERT_EQ(r.errors.size(), 2u) << ::testing::PrintToString(r.errors);
  EXPECT_NE(r.errors[0].find("$.yarn.plies"), std::string::npos);
  EXPECT_NE(r.errors[1].find("$.weft.plies"), std::string::npos);
}

TEST(Spec, NonFiniteNumbers) {
  // JSON has no NaN literal; overflowing numbers become +-inf or a syntax error, both rejected.
  auto r = parse_spec_text(R"({"warp": {"roughness": 1e999}})");
  ASSERT_FALSE(r.ok());
  auto r2 = parse_spec_text(R"({"warp": {"roughness": NaN}})");
  ASSERT_EQ(r2.errors.size(), 1u);
  EXPECT_NE(r2.errors[0].find("not valid JSON"), std::string::npos);
  json d = base();
  d["model"] = {{"optical_thickness", std::numeric_limits<double>::quiet_NaN()}};
  expect_one_error(d, {"$.model.optical_thickness"});
}

TEST(Spec, UnknownWeaveAndField) {
  json d = base();
  d["weave"] = {{"pattern", "tartan"}};
  expect_one_error(d, {"$.weave.pattern", "\"tartan\"", "\"plain\"", "\"custom\""});
  d = base();
  d["warp"] = {{"iorr", 1.5}};
  expect_one_error(d, {"$.warp.iorr", "unknown field"});
}

TEST(Spec, Contradictions) {
  json d = base();
  d["warp"] = {{"ply_diameter_um", 400}, {"yarn_diameter_um", 300}};
  expect_one_error(d, {"$.warp.ply_diameter_um", "larger than yarn_diameter_um", "[5, 300]"});
  d = base();
  d["weave"] = {{"pattern", "satin"}, {"harness", 6}, {"shift", 2}};
  expect_one_error(d, {"$.weave.shift", "coprime"});
  d = base();
  d["weave"] = {{"pattern", "custom"}, {"matrix", {{1, 1}, {0, 1}}}};
  auto r = parse_spec(d);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.errors[0].find("never interlaces"), std::string::npos);
  d = base();
  d["weave"] = {{"pattern", "custom"}, {"matrix", {{1, 0, 2}}}};
  expect_one_error(d, {"$.weave.matrix", "0 (weft on top) or 1"});
  auto big = parse_spec_text(R"({"weave": {"pattern": "custom", "matrix": [[4294967297, 0], [0, 1]]}})");
  ASSERT_EQ(big.errors.size(), 1u);  // 2^32 + 1 must not wrap to 1
  EXPECT_NE(big.errors[0].find("$.weave.matrix"), std::string::npos);
  // Yarns wider than three spacings at their own density (warp: warp_per_cm).
  d = base();
  d["density"] = {{"warp_per_cm", 150}, {"weft_per_cm", 10}};  // warp spacing 66.7 um
  expect_one_error(d, {"$.warp.yarn_diameter_um", "at 150 yarns/cm", "[10, 200.0]"});
}

TEST(Spec, ResolutionThatDoesNotFit) {
  json d = base();
  json m = json::array();
  for (int r = 0; r < 40; ++r) {
    json row = json::array();
    for (int c = 0; c < 40; ++c) row.push_back((r + c) % 2);
    m.push_back(row);
  }
  d["weave"] = {{"pattern", "custom"}, {"matrix", m}};
  d["model"] = {{"quality", "reference"}};
  expect_one_error(d, {"$.model.quality", "5120 x 5120", "4096"});
  EXPECT_TRUE(parse_spec(d, "preview").ok());
}

TEST(Spec, QualityOverrideAndUnavailableTier) {
  EXPECT_EQ(parse_spec(base(), "final").spec.quality, loom::Quality::Final);
  EXPECT_FALSE(parse_spec(base(), "ultra").ok());
  json d = base();
  d["model"]["tier"] = "fiber";
  expect_one_error(d, {"$.model.tier", "not available yet"});
  d["model"]["tier"] = "raywave";
  EXPECT_TRUE(parse_spec(d).ok());
}

TEST(Spec, ColourForms) {
  json d = base();
  d["warp"] = {{"color", {{"linear", {0.1, 0.2, 0.3}}}}};
  auto r = parse_spec(d);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.spec.warp.color_space, "linear");
  d["warp"] = {{"color", {{"srgb", {0.1, 0.2}}}}};
  expect_one_error(d, {"$.warp.color.srgb", "3 numbers in [0, 1]"});
  d["warp"] = {{"color", {{"srgb", {0.1, 0.2, 0.3}}, {"linear", {0.1, 0.2, 0.3}}}}};
  expect_one_error(d, {"$.warp.color", "exactly one"});
}

TEST(Spec, CanonicalFormIsOrderIndependentAndComplete) {
  auto a = parse_spec_text(R"({"name":"x","density":{"weft_per_cm":30,"warp_per_cm":20}})");
  auto b = parse_spec_text(R"({"density":{"warp_per_cm":20,"weft_per_cm":30},"name":"x"})");
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(loom::canonical_spec(a.spec).dump(), loom::canonical_spec(b.spec).dump());
  auto c = loom::canonical_spec(a.spec);
  EXPECT_TRUE(c["warp"].contains("ior"));
  // The canonical form parses back to itself.
  auto back = parse_spec(c);
  ASSERT_TRUE(back.ok()) << ::testing::PrintToString(back.errors);
  EXPECT_EQ(loom::canonical_spec(back.spec), c);
}

TEST(Spec, ProceduralFiberFields) {
  json d = base();
  d["warp"] = {{"migration_min", 0.8}, {"migration_max", 0.5}};
  expect_one_error(d, {"$.warp.migration_min", "larger than migration_max", "[0, 0.5]"});
  d["warp"] = {{"density_beta", 0.0}};
  expect_one_error(d, {"$.warp.density_beta", "[0.01, 10]"});
  d["warp"] = {{"hair_flyaways_per_mm", 2.5}, {"migration_period", 1.5}};
  auto r = parse_spec(d);
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  EXPECT_EQ(r.spec.warp.hair_flyaways_per_mm, 2.5);
  EXPECT_EQ(loom::canonical_spec(r.spec)["warp"]["migration_period"], 1.5);
}

TEST(Spec, WaveFields) {
  json d = base();
  d["wave"] = {{"beam_waist_um", 0.5}};
  expect_one_error(d, {"$.wave.beam_waist_um", "[1, 1000]", "um"});
  d["wave"] = {{"diffraction", "yes"}};
  expect_one_error(d, {"$.wave.diffraction"});
  d["wave"] = {{"diffracton", false}};
  expect_one_error(d, {"$.wave.diffracton"});
  d["wave"] = {{"noise", 1}};
  expect_one_error(d, {"$.wave.noise"});
  d["wave"] = {{"speckle_width_um", 5000}};
  expect_one_error(d, {"$.wave.speckle_width_um", "[1, 1000]"});
  d["wave"] = {{"diffraction", false}, {"beam_waist_um", 25}, {"noise", false}};
  auto r = parse_spec(d);
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  EXPECT_FALSE(r.spec.wave.diffraction);
  EXPECT_FALSE(r.spec.wave.noise);
  EXPECT_EQ(loom::canonical_spec(r.spec)["wave"]["beam_waist_um"], 25.0);
  // Defaults: diffraction on, the supplement's 10 um waist (Eq. S.36).
  auto def = parse_spec(base());
  EXPECT_TRUE(def.spec.wave.diffraction);
  EXPECT_TRUE(def.spec.wave.noise);
  EXPECT_EQ(def.spec.wave.beam_waist_um, 10.0);
}

TEST(Spec, RaywaveComponentSwitches) {
  json d = base();
  d["components"] = {{"multi_ply", "no"}};
  expect_one_error(d, {"$.components.multi_ply"});
  d["components"] = {{"double_layer", 0}};
  expect_one_error(d, {"$.components.double_layer"});
  d["components"] = {{"multi_ply", false}, {"double_layer", false}};
  auto r = parse_spec(d);
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  EXPECT_FALSE(r.spec.components.multi_ply);
  EXPECT_FALSE(r.spec.components.double_layer);
  const json c = loom::canonical_spec(r.spec);
  EXPECT_EQ(c["components"]["multi_ply"], false);
  EXPECT_EQ(c["components"]["double_layer"], false);
  // Defaults: both on; they are part of the canonical spec (and so of the bake's identity).
  auto def = parse_spec(base());
  EXPECT_TRUE(def.spec.components.multi_ply);
  EXPECT_TRUE(def.spec.components.double_layer);
  EXPECT_NE(loom::canonical_spec(def.spec).dump(), c.dump());
}
