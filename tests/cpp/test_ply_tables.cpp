// Ray-wave atlases: the ply tables round-trip through the atlas exactly as fitted, the raywave
// probe answers with the table's value and the bake's own simulation (--raw), and validation
// rejects a ray-wave manifest without its tables; the diffraction tables are stored as computed.
#include <gtest/gtest.h>

#include <fstream>

#include "loom/closure_lut.h"
#include "loom/diffraction_tables.h"
#include "loom/ply_tables.h"
#include "loom/speckle_noise.h"
#include "loom/spectrum.h"
#include "lobe_paths.h"
#include "raywave_checks.h"
#include "test_util.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using loom::test::run;
using loom::test::scratch;

loom::FabricSpec raywave_draft() {
  auto d = loom::preset("plain");
  d["model"]["tier"] = "raywave";
  d["weft"]["ior"] = 1.46;  // weft differs from warp: two sets of tables
  auto r = loom::parse_spec(d, "draft");
  EXPECT_TRUE(r.ok());
  return r.spec;
}

const fs::path& raywave_atlas() {
  static fs::path dir = [] {
    fs::path d = scratch("raywave.atlas");
    loom::bake_atlas(raywave_draft(), d, {});
    return d;
  }();
  return dir;
}


}  // namespace

void atlas_holds_the_fitted_tables_exactly() {
  const auto& dir = raywave_atlas();
  json m;
  auto errors = loom::validate_atlas(dir, &m);
  ASSERT_TRUE(errors.empty()) << errors[0];
  EXPECT_EQ(m["tier"], "raywave");
  auto atlas = loom::load_atlas(dir);
  auto spec = raywave_draft();
  for (const char* yarn : {"warp"}) {  // (the weft's tables come from the same code)
    auto t = loom::load_ply_tables(atlas, yarn);
    // The bake is deterministic: re-simulating and re-fitting gives the same tables, and the
    // atlas stores them (as float32) without loss beyond float rounding.
    auto ref = loom::bake_ply_tables(std::string(yarn) == "warp" ? spec.warp : spec.weft,
                                     loom::Quality::Draft);
    ASSERT_EQ(t.high.nodes.size(), ref.high.nodes.size());
    for (size_t i = 0; i < t.high.nodes.size(); ++i) {
      EXPECT_FLOAT_EQ(float(t.high.nodes[i].mu1), float(ref.high.nodes[i].mu1));
      EXPECT_FLOAT_EQ(float(t.high.nodes[i].phi_z), float(ref.high.nodes[i].phi_z));
      EXPECT_FLOAT_EQ(float(t.high.nodes[i].c), float(ref.high.nodes[i].c));
    }
    ASSERT_EQ(t.high.scale.size(), ref.high.scale.size());
    for (size_t i = 0; i < t.high.scale.size(); ++i)
      EXPECT_FLOAT_EQ(float(t.high.scale[i]), float(ref.high.scale[i]));
    EXPECT_EQ(t.refl.lobes, ref.refl.lobes);
    loom::test::expect_no_sweeping_lobes(t.high);
    loom::test::expect_no_sweeping_lobes(t.refl);
    EXPECT_EQ(t.high.sigmas, ref.high.sigmas);
  }
  // Double-layer factors, front and back: energies in [0, 1], the orderings of Eq. S.20, and
  // (level 0, no absorption) almost all light accounted for.
  ASSERT_TRUE(m["raywave"].contains("double_layer"));
  const int T = m["raywave"]["double_layer"]["theta_count"];
  for (const char* side : {"double_layer_front", "double_layer_back"}) {
    const auto& img = atlas.map(side);
    ASSERT_EQ(img.channels, 4);
    for (int row = 0; row < img.height; ++row)
      for (int c = 0; c < img.width; ++c) {
        const float* f = img.px(c, row);
        EXPECT_LE(f[0] + f[1], 1 + 1e-5);
        EXPECT_GE(f[2], f[0] - 1e-6);
        EXPECT_LE(f[3], f[1] + 1e-6);
        if (row < T) {
          EXPECT_GT(f[0] + f[1], 0.95) << side << " row " << row;
        }
      }
  }
  // The weft (other IOR) has its own tables.
  EXPECT_NE(m["raywave"]["yarns"]["warp"]["files"]["high"], m["raywave"]["yarns"]["weft"]["files"]["high"]);
  // Diffraction tables: what diffraction_*_table computes for this fabric, stored as float.
  const json& dif = m["raywave"]["diffraction"];
  ASSERT_EQ(dif["mode"], "tables");
  const auto ds = loom::diffraction_settings(loom::Quality::Draft);
  const auto srgb = loom::spectral_rgb(loom::ColourConverter(), ds.step_nm);
  const auto gap = loom::gap_widths(spec);
  ASSERT_GT(gap[0], 0);
  const auto want_gap = loom::diffraction_gap_table(gap[0], gap[1], 10.0, srgb, ds);
  const auto want_edge = loom::diffraction_edge_table(10.0, srgb, ds);
  for (auto [name, want] : {std::pair{"diffraction_gap", &want_gap}, {"diffraction_edge", &want_edge}}) {
    ASSERT_EQ(dif["files"].value(name == std::string("diffraction_gap") ? "gap" : "edge", ""), name);
    const auto& img = atlas.map(name);
    ASSERT_EQ(img.width, want->width());
    ASSERT_EQ(img.height, want->height());
    for (int y = 0; y < img.height; y += 5)
      for (int x = 0; x < img.width; x += 3)
        for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(img.px(x, y)[c], want->px(x, y)[c]);
  }
  // Noise tiles: the draft tiles of the fixed seeds, at their blur levels (level 0 the tile).
  const json& noise = m["raywave"]["noise"];
  const auto ns = loom::noise_settings(loom::Quality::Draft);
  EXPECT_EQ(noise["theta_count"], ns.theta_count);
  EXPECT_EQ(noise["levels"], LOOM_NOISE_LEVELS);
  int k = 0;
  for (const char* which : {"refl", "high"}) {
    const auto want = loom::speckle_noise_tile(ns, 10.0, loom::kNoiseSeed + uint64_t(k++));
    const auto& img = atlas.map(noise["files"][which].get<std::string>());
    ASSERT_EQ(img.width, want.width);
    ASSERT_EQ(img.height, want.height * LOOM_NOISE_LEVELS);
    // Stored as half floats: 11 significant bits (relative 2^-11), subnormals below 6.1e-5.
    for (size_t i = 0; i < want.data.size(); i += 7)
      ASSERT_NEAR(img.data[i], want.data[i], std::ldexp(std::fabs(want.data[i]), -11) + 6.1e-5);
  }
  // eval noise --stats reads them back: unit means (64 x 128 texels of nearly independent
  // speckle at the draft resolution: +-0.05 is over 4 standard errors).
  std::string out;
  ASSERT_EQ(run(loom::test::bake_exe() + " eval noise --stats --atlas " + dir.string(), &out), 0)
      << out;
  const json st = json::parse(out);
  for (const char* which : {"refl", "high"}) {
    ASSERT_EQ(st[which].size(), size_t(ns.instances));
    for (const auto& b : st[which][0]["bands"]) {
      EXPECT_NEAR(b["mean"].get<double>(), 1.0, 0.05) << which;
      EXPECT_GT(b["variance"].get<double>(), 0.3) << which;
      EXPECT_GE(b["min"].get<double>(), 0.0);
    }
  }
  // Absorption data per yarn; eval colour reconstructs a reachable colour through it.
  for (const char* yarn : {"warp", "weft"}) {
    const json& a = m["raywave"]["yarns"][yarn]["absorption"];
    ASSERT_TRUE(a.is_object()) << yarn;
    EXPECT_EQ(a["sigma_per_mm"].size(), a["lambda_nm"].size());
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(a["rgb_spectrum"][c].get<double>(), a["colour_linear"][c].get<double>(), 2e-3);
  }
  ASSERT_EQ(run(loom::test::bake_exe() + " eval colour --rgb 0.5,0.3,0.1 --yarn weft --atlas " +
                    dir.string(),
                &out),
            0)
      << out;
  const json col = json::parse(out);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(col["rgb_reconstructed"][c].get<double>(), col["rgb"][c].get<double>(), 0.01);
  EXPECT_NE(run(loom::test::bake_exe() + " eval colour --rgb 1.5,0,0 --atlas " + dir.string() +
                    " 2>&1",
                &out),
            0);
  EXPECT_NE(out.find("--rgb"), std::string::npos) << out;
}

void raywave_probe_answers_from_tables_and_simulation() {
  const auto& dir = raywave_atlas();
  auto atlas = loom::load_atlas(dir);
  auto t = loom::load_ply_tables(atlas, "warp");
  std::string out;
  // A grid point (theta_i node 0 is -80 deg, h node 3 of 7 is 0) and a forward direction.
  // (The angle as printed, so that both sides evaluate the very same theta_i.)
  const double th = std::stod(std::to_string(t.high.theta_i[2] * 180 / M_PI));
  ASSERT_EQ(run(loom::test::bake_exe() + " eval raywave --atlas " + dir.string() +
                    " --theta-i " + std::to_string(th) + " --h 0 --sigma 20 --wo 0,-1,-0.2 --raw",
                &out),
            0)
      << out;
  json j = json::parse(out);
  loom::Vec3d w{0, -1 / std::sqrt(1.04), -0.2 / std::sqrt(1.04)};
  EXPECT_NEAR(j["high"].get<double>(), loom::asg_table_eval(t.high, th * M_PI / 180, 0, 20, w), 1e-6);
  EXPECT_NEAR(j["refl"].get<double>(), loom::asg_table_eval(t.refl, th * M_PI / 180, 0, 0, w), 1e-6);
  EXPECT_NEAR(j["raw"]["h"].get<double>(), 0.0, 1e-12);
  EXPECT_NEAR(j["raw"]["theta_i_deg"].get<double>(), th, 1e-4);
  EXPECT_GE(j["raw"]["value"].get<double>(), 0.0);
  // A surface atlas has no tables: a clear error, non-zero exit.
  const fs::path& surf = loom::test::draft_atlas("plain", "surface");
  EXPECT_NE(run(loom::test::bake_exe() + " eval raywave --atlas " + surf.string() +
                    " --theta-i 0 --h 0 --wo 0,1,0 2>&1",
                &out),
            0);
  EXPECT_NE(out.find("no ray-wave tables"), std::string::npos) << out;
}

void validation_rejects_a_raywave_manifest_without_tables() {
  fs::path d = scratch("broken.atlas");
  fs::copy(raywave_atlas(), d);
  json m;
  {
    std::ifstream in(d / "manifest.json");
    m = json::parse(in);
  }
  m["raywave"]["yarns"]["weft"]["files"]["high"] = "../../etc/passwd";
  m["raywave"]["yarns"].erase("warp");
  {
    std::ofstream out(d / "manifest.json");
    out << m.dump(2);
  }
  auto errors = loom::validate_atlas(d);
  ASSERT_EQ(errors.size(), 2u);
  EXPECT_NE(errors[0].find("raywave.yarns.warp"), std::string::npos) << errors[0];
  EXPECT_NE(errors[1].find("raywave.yarns.weft.files.high"), std::string::npos) << errors[1];

  // Diffraction: a listed table must be a texture of the atlas; "delta" lists none.
  fs::copy(raywave_atlas() / "manifest.json", d / "manifest.json",
           fs::copy_options::overwrite_existing);
  {
    std::ifstream in(d / "manifest.json");
    m = json::parse(in);
  }
  m["raywave"]["diffraction"]["files"]["gap"] = "no_such_table";
  {
    std::ofstream out(d / "manifest.json");
    out << m.dump(2);
  }
  errors = loom::validate_atlas(d);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("raywave.diffraction.files.gap"), std::string::npos) << errors[0];
  m["raywave"]["diffraction"] = {{"mode", "delta"}};
  {
    std::ofstream out(d / "manifest.json");
    out << m.dump(2);
  }
  errors = loom::validate_atlas(d);
  EXPECT_TRUE(errors.empty()) << errors[0];
  m["raywave"]["noise"]["files"]["high"] = "noise_elsewhere";
  {
    std::ofstream out(d / "manifest.json");
    out << m.dump(2);
  }
  errors = loom::validate_atlas(d);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("raywave.noise.files.high"), std::string::npos) << errors[0];
  m["raywave"]["noise"]["files"]["high"] = "noise_high";
  m["raywave"]["diffraction"] = {{"mode", "wavy"}};
  {
    std::ofstream out(d / "manifest.json");
    out << m.dump(2);
  }
  errors = loom::validate_atlas(d);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("raywave.diffraction.mode"), std::string::npos) << errors[0];
}

void colour_only_change_reuses_the_simulation() {
  // Same directory as the first atlas (a sibling): found without being named.
  auto spec = raywave_draft();
  spec.warp.color_input = {0.1, 0.6, 0.2};
  spec.weft.color_input = {0.7, 0.7, 0.1};
  const fs::path d = raywave_atlas().parent_path() / "raywave-recoloured.atlas";
  fs::remove_all(d);
  const auto r = loom::bake_atlas(spec, d, {});
  EXPECT_EQ(fs::canonical(r.reused_simulation), fs::canonical(raywave_atlas()));
  json a, b;
  ASSERT_TRUE(loom::validate_atlas(raywave_atlas(), &a).empty());
  const auto errors = loom::validate_atlas(d, &b);
  ASSERT_TRUE(errors.empty()) << errors[0];
  for (const char* t : {"ply_high_warp", "ply_refl_weft", "double_layer_front", "diffraction_edge",
                        "noise_high"})
    EXPECT_EQ(a["textures"][t]["sha256"], b["textures"][t]["sha256"]) << t;
  EXPECT_EQ(a["raywave"]["simulation_key"], b["raywave"]["simulation_key"]);
  // The colour-dependent parts follow the new colours.
  for (const char* t : {"albedo_reflect", "ply_tint_warp", "layer_factors_front"})
    EXPECT_NE(a["textures"][t]["sha256"], b["textures"][t]["sha256"]) << t;
  const json& ab = b["raywave"]["yarns"]["warp"]["absorption"];
  const loom::ColourConverter cc;
  const auto lin = cc.srgb_to_linear({0.1, 0.6, 0.2});
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(ab["rgb_spectrum"][c].get<double>(), lin[size_t(c)], 2e-3);
  EXPECT_LT(ab["sigma_rgb_per_mm"][1].get<double>(), ab["sigma_rgb_per_mm"][0].get<double>());
  // The copied surface maps and closure LUT are what the new spec itself bakes to (they do not
  // depend on colour): computed afresh here and compared with the atlas's files (maps in half).
  spec.warp.color_linear = loom::ColourConverter().srgb_to_linear(spec.warp.color_input);
  spec.weft.color_linear = loom::ColourConverter().srgb_to_linear(spec.weft.color_input);
  const auto fresh = loom::bake_surface_maps(spec);
  const auto atlas = loom::load_atlas(d);
  for (size_t k = 0; k < fresh.images.size(); ++k) {
    const auto& want = fresh.images[k];
    const auto& got = atlas.map(fresh.info[k].name);
    ASSERT_EQ(got.data.size(), want.data.size()) << fresh.info[k].name;
    for (size_t i = 0; i < want.data.size(); i += 5)
      ASSERT_NEAR(got.data[i], want.data[i], std::ldexp(std::fabs(want.data[i]), -10) + 1e-4)
          << fresh.info[k].name << " " << i;
  }
  const auto lut = loom::bake_closure_lut(spec);
  ASSERT_EQ(atlas.closure_lut.data.size(), lut.data.size());
  for (size_t i = 0; i < lut.data.size(); ++i) ASSERT_FLOAT_EQ(atlas.closure_lut.data[i], lut.data[i]);
}

TEST(PlyTables, SimulationKeyIgnoresOnlyColourAndName) {
  auto canon = [](auto edit) {
    auto d = loom::preset("plain");
    d["model"]["tier"] = "raywave";
    edit(d);
    auto r = loom::parse_spec(d);
    EXPECT_TRUE(r.ok());
    return loom::canonical_spec(r.spec);
  };
  const auto key = [](const json& c, const std::string& colour = "cc", const std::string& id = "b") {
    return loom::raywave_simulation_key(c, colour, id);
  };
  const json base = canon([](json&) {});
  const std::string k = key(base);
  EXPECT_EQ(k, key(canon([](json& d) { d["yarn"]["color"] = {{"srgb", {0.1, 0.2, 0.3}}}; })));
  EXPECT_EQ(k, key(canon([](json& d) { d["name"] = "renamed"; })));
  EXPECT_NE(k, key(canon([](json& d) { d["yarn"]["ior"] = 1.6; })));
  EXPECT_NE(k, key(canon([](json& d) { d["model"]["quality"] = "final"; })));
  EXPECT_NE(k, key(canon([](json& d) { d["wave"] = {{"beam_waist_um", 20}}; })));
  EXPECT_NE(k, key(base, "another colour config"));
  EXPECT_NE(k, key(base, "cc", "another baker"));
}

// One test, so that the (slow under the sanitizers) ray-wave bake runs once per process.
TEST(PlyTables, RaywaveAtlas) {
  {
    SCOPED_TRACE("the atlas holds the fitted tables exactly");
    atlas_holds_the_fitted_tables_exactly();
  }
  {
    SCOPED_TRACE("eval raywave");
    raywave_probe_answers_from_tables_and_simulation();
  }
  {
    SCOPED_TRACE("validation");
    validation_rejects_a_raywave_manifest_without_tables();
  }
  {
    SCOPED_TRACE("ray-wave shading");
    loom::test::raywave_bsdf_atlas_checks(raywave_atlas());
  }
  {
    SCOPED_TRACE("colour-only change");
    colour_only_change_reuses_the_simulation();
  }
}
