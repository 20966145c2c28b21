// The ray-wave tier's stages of a bake (bake_stages.h): ply tables, double layer, (diffraction
// and noise: bake_wave.cpp), colour from absorption and the render tables at the yarn colours.
// Each stage keeps what a later one reads in memory; a colour-only change reads the copied
// tables from the atlas it copies them from.
#include <chrono>
#include <fmt/format.h>
#include <optional>

#include "bake_stages.h"
#include "loom/absorption.h"
#include "loom/double_layer.h"
#include "loom/fiber_truth.h"
#include "loom/ply_tables.h"
#include "loom/render_tables.h"
#include "loom/spectral_upsampling.h"
#include "loom/swatch.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace loom {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Textures of a ray-wave atlas that do not depend on the yarn colours.
bool colour_independent_texture(const std::string& name) {
  for (const char* prefix : {"ply_high_", "ply_refl_", "double_layer_", "diffraction_", "noise_",
                             "microfacet_albedo"})
    if (name.rfind(prefix, 0) == 0) return true;
  return false;
}

/// The colour-independent tables as the render-table stage reads them: by texture name.
using Tables = std::map<std::string, Image>;

/// What the colour stages need of the simulation, per yarn (0 warp, 1 weft).
struct Simulated {
  std::optional<AbsorptionCurve> curves[2];
  SwatchCurve swatch;  ///< rho(sigma) of the cloth's swatch (swatch.h)
  double sigma_max[2] = {0, 0};
  Tables tables;
};

/// Each yarn's ply tables (Eq. S.1-S.12, multi-ply S.13-S.19): fitted ASG lobes, scale-downs and
/// residuals. The tables do not depend on the yarn colour (colour is absorption, applied through
/// the tables' levels): a weft that differs only in colour shares the warp's tables.
std::array<std::optional<PlyTables>, 2> ply_tables_stage(const BakeContext& ctx, json& raywave,
                                                         Tables& tables) {
  json canon_warp = ctx.canonical_spec["warp"], canon_weft = ctx.canonical_spec["weft"];
  canon_warp.erase("color");
  canon_weft.erase("color");
  std::array<std::optional<PlyTables>, 2> yarn_tables;
  auto table = [&](Image img, const json& name, std::vector<std::string> channels,
                   const std::string& what) {
    ctx.out.write_table(img, name.get<std::string>(), channels, what);
    tables[name.get<std::string>()] = std::move(img);
  };
  for (const char* yarn : {"warp", "weft"}) {
    const bool weft_same = std::string(yarn) == "weft" && canon_weft == canon_warp;
    if (weft_same) {
      raywave["yarns"]["weft"] = raywave["yarns"]["warp"];
      raywave["yarns"]["weft"]["yarn"] = "weft";
      raywave["yarns"]["weft"]["same_as"] = "warp";
      continue;
    }
    const YarnSpec& y = std::string(yarn) == "warp" ? ctx.spec.warp : ctx.spec.weft;
    PlyTables& pt = yarn_tables[std::string(yarn) == "warp" ? 0 : 1].emplace(
        bake_ply_tables(y, ctx.spec.quality, ctx.progress_fn, std::string("plysim ") + yarn,
                        ctx.spec.components.multi_ply));
    json entry = ply_tables_manifest(pt, yarn);
    const json& files = entry["files"];
    table(asg_nodes_image(pt.high), files["high"], {"theta_z|mu2", "phi_z|c", "phi_xy|0", "mu1|0"},
          "f_high ASG corner nodes, two texels per (h node, lobe) in lobe-major columns, rows "
          "theta_i nodes (layout: baker/include/loom/ply_tables.h)");
    table(asg_scale_image(pt.high), files["high_scale"], {"s"},
          "f_high absorption scale-downs s_{l,k} per corner node, column j L + l, row i K + k "
          "(layout: baker/include/loom/ply_tables.h)");
    table(asg_nodes_image(pt.refl), files["refl"], {"theta_z|mu2", "phi_z|c", "phi_xy|0", "mu1|0"},
          "f_refl ASG corner nodes, two texels per (h node, lobe) in lobe-major columns, rows "
          "theta_i nodes (layout: baker/include/loom/ply_tables.h)");
    table(asg_residual_image(pt.high), files["high_residual"], {"energy"},
          "f_high energy the lobes miss (baker/include/loom/asg_residual.h), column "
          "side N + n (0 backward, 1 forward), row m K + k");
    table(asg_residual_image(pt.refl), files["refl_residual"], {"energy"},
          "f_refl energy the lobes miss (baker/include/loom/asg_residual.h), column "
          "side N + n (0 backward, 1 forward), row m");
    raywave["yarns"][yarn] = entry;
  }
  return yarn_tables;
}

/// Double-layer factors (Eq. S.20): warp over weft seen from the front, weft over warp from the
/// back. components.double_layer off: one layer, B_total = B_t and F_total = F_t (k_b = 0,
/// k_f = 1: double_layer_factors.h) and no diffuse part (s = 0), without simulating the second
/// layer.
json double_layer_stage(const BakeContext& ctx, const PlySimResult& warp_sim,
                        const PlySimResult& weft_sim, Tables& tables) {
  const Layer warp_layer{&warp_sim, {1, 0, 0}}, weft_layer{&weft_sim, {0, 1, 0}};
  const DoubleLayerSettings dls = double_layer_settings(ctx.spec.quality);
  const bool two_layers = ctx.spec.components.double_layer;
  json dl = {{"theta_count", dls.theta_count},
             {"phi_count", dls.phi_count},
             {"sigma_per_mm", warp_sim.settings.sigmas},
             {"blend", two_layers ? ctx.spec.double_layer_blend : 0.0},
             {"mode", two_layers ? "tables" : "off"},
             {"files", {{"front", "double_layer_front"}, {"back", "double_layer_back"}}},
             {"layout",
              "B_t, F_t, B_total, F_total (Eq. S.20) per direction xi towards the light: "
              "column p at azimuth (p + 0.5) 360 / phi_count deg, row k theta_count + t at "
              "level sigma_k and angle from the normal (t + 0.5) 90 / theta_count deg; the "
              "back table takes xi mirrored to +z"}};
  ctx.progress("double layer", 0.0);
  for (int side = 0; side < 2; ++side) {
    DoubleLayerTable t;
    if (two_layers) {
      t = side == 0 ? double_layer_table(warp_layer, weft_layer, dls)
                    : double_layer_table(weft_layer, warp_layer, dls);
    } else {
      t.settings = dls;
      t.sigmas = warp_sim.settings.sigmas;
      t.values.assign(t.sigmas.size() * size_t(dls.theta_count * dls.phi_count),
                      DoubleLayerFactors{1, 1, 1, 1, 1, 1});
    }
    const int K = int(t.values.size()) / (dls.theta_count * dls.phi_count);
    Image img(dls.phi_count, dls.theta_count * K, 4);
    for (int row = 0; row < dls.theta_count * K; ++row)
      for (int c = 0; c < dls.phi_count; ++c) {
        const DoubleLayerFactors& f = t.values[size_t(row * dls.phi_count + c)];
        float* px = img.px(c, row);
        px[0] = float(f.Bt), px[1] = float(f.Ft), px[2] = float(f.Btotal), px[3] = float(f.Ftotal);
      }
    const std::string name = side == 0 ? "double_layer_front" : "double_layer_back";
    ctx.out.write_table(img, name, {"B_t", "F_t", "B_total", "F_total"},
                        "double-layer reflection and transmission factors (layout: manifest "
                        "raywave.double_layer.layout)");
    tables[name] = std::move(img);
    ctx.progress("double layer", 0.5 * (side + 1));
  }
  return dl;
}

/// The swatch of the cloth (swatch.h) as a function of the fibers' absorption: traced through
/// the fibers of a tile of the fabric, with more rays at higher quality (its Monte Carlo error
/// in rho, about 1 / sqrt(rays), is 0.7 % at draft).
json swatch_stage(const BakeContext& ctx, SwatchCurve& curve) {
  ctx.progress("swatch", 0.0);
  const auto t0 = std::chrono::steady_clock::now();
  SwatchSettings ss;
  ss.truth.rays = swatch_rays(ctx.spec.quality);
  const auto scene = make_truth_scene(ctx.spec, ss.truth.min_yarns);
  curve = SwatchPaths(*scene, ss).curve();
  std::vector<double> per_mm;
  for (double x : curve.sigma_per_um) per_mm.push_back(x * 1e3);
  return {{"sigma_per_mm", per_mm},
          {"rho", curve.rho},
          {"rays", ss.truth.rays},
          {"light_deg", ss.light_deg},
          {"seconds", seconds_since(t0)},
          {"definition", "the swatch reflectance of the cloth folded to opacity, d:8, with "
                         "every fiber absorbing sigma (baker/include/loom/swatch.h)"}};
}

/// The simulation's stages: ply tables, double layer, diffraction, noise and each yarn's
/// absorption curve (sigma -> energy of its ply).
Simulated simulate(const BakeContext& ctx, json& raywave) {
  Simulated s;
  const auto yarn_tables = ply_tables_stage(ctx, raywave, s.tables);
  const PlySimResult& warp_sim = yarn_tables[0]->raw;
  const PlySimResult& weft_sim = yarn_tables[1] ? yarn_tables[1]->raw : warp_sim;
  raywave["double_layer"] = double_layer_stage(ctx, warp_sim, weft_sim, s.tables);
  raywave["diffraction"] = bake_diffraction_stage(ctx);
  raywave["noise"] = bake_noise_stage(ctx);
  const auto ct0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 2; ++i) {
    const int src = yarn_tables[size_t(i)] ? i : 0;
    if (!s.curves[src])
      s.curves[src] = absorption_curve(src == 0 ? ctx.spec.warp : ctx.spec.weft, ctx.spec.quality);
    s.curves[i] = s.curves[src];
    s.sigma_max[i] = yarn_tables[size_t(src)]->sim.sigmas.back();
  }
  raywave["absorption_curve_seconds"] = seconds_since(ct0);
  return s;
}

/// A colour-only change: the colour-independent tables and the absorption curves of the atlas
/// found with the same simulation key, copied.
Simulated reuse_simulation(const BakeContext& ctx, json& raywave) {
  const auto& [dir, sm] = *ctx.source;
  const json status = raywave["status"];
  raywave = sm["raywave"];
  raywave["status"] = status;
  raywave["reused_from"] = dir.string();
  Simulated s;
  for (auto& [name, t] : sm["textures"].items())
    if (colour_independent_texture(name)) {
      ctx.out.copy(dir, sm, name);
      s.tables[name] = read_atlas_image(dir / t["node_file"].get<std::string>());
    }
  for (int i = 0; i < 2; ++i) {
    const char* yarn = i == 0 ? "warp" : "weft";
    const json& y = raywave["yarns"][yarn];
    s.curves[i] = absorption_curve_from_manifest(y, yarn);
    if (s.curves[i]->empty())
      throw std::runtime_error(fmt::format("reusing {}: raywave.yarns.{}.absorption.curve "
                                           "is missing", dir.string(), yarn));
    s.sigma_max[i] = y["high"]["sigma_per_mm"].back().get<double>();
  }
  const json& sw = raywave.value("swatch", json());
  if (sw.is_object() && sw.contains("sigma_per_mm") && sw.contains("rho")) {
    for (const json& x : sw["sigma_per_mm"]) s.swatch.sigma_per_um.push_back(x.get<double>() * 1e-3);
    s.swatch.rho = sw["rho"].get<std::vector<double>>();
  }
  return s;
}

/// Colour from absorption (section 6, Eq. S.42): each yarn's colour through its ply's simulated
/// sigma -> energy curve.
void absorption_stage(const BakeContext& ctx, Simulated& s, json& raywave) {
  // The swatch reading needs the swatch curve: the reused atlas's, or traced now (it depends on
  // the geometry only, like the tables; an atlas of the ply reading has none).
  if (ctx.spec.colour_reading == ColourReading::Swatch && s.swatch.rho.empty())
    raywave["swatch"] = swatch_stage(ctx, s.swatch);
  ctx.progress("absorption", 0.0);
  const auto at0 = std::chrono::steady_clock::now();
  const SpectralUpsampler up(ctx.cc, 5.0);
  for (int i = 0; i < 2; ++i) {
    const char* yarn = i == 0 ? "warp" : "weft";
    const AbsorptionCurve& curve = *s.curves[i];
    const AbsorptionFit fit = fit_absorption(curve);
    const YarnSpec& y = i == 0 ? ctx.spec.warp : ctx.spec.weft;
    const YarnAbsorption ya = yarn_absorption(y.color_linear, up, fit, curve, s.sigma_max[i]);
    // The reading of the colour (spec.h): the swatch's absorption, per channel, within the
    // tables' levels; or the ply albedo's (Eq. S.42 through the simulated curve).
    std::array<double, 3> sigma_rgb = ya.sigma_rgb, swatch_rho{};
    std::array<bool, 3> out_of_reach{};
    if (ctx.spec.colour_reading == ColourReading::Swatch) {
      const SwatchAbsorption a = swatch_absorption(s.swatch, y.color_linear, s.sigma_max[i]);
      sigma_rgb = a.sigma_per_mm, swatch_rho = a.rho, out_of_reach = a.out_of_reach;
    }
    raywave["yarns"][yarn]["absorption"] = {
        {"reading", to_string(ctx.spec.colour_reading)},
        {"sigma_rgb_ply_albedo_per_mm", ya.sigma_rgb},
        {"colour_linear", y.color_linear},
        {"sigmoid_coeffs", ya.spectrum.coeffs},
        {"lambda_nm", ya.lambda_nm},
        {"sigma_per_mm", ya.sigma_per_mm},
        {"sigma_rgb_per_mm", sigma_rgb},
        {"swatch_rho", ctx.spec.colour_reading == ColourReading::Swatch ? json(swatch_rho)
                                                                         : json(nullptr)},
        {"swatch_out_of_reach", out_of_reach},
        {"rgb_spectrum", ya.rgb_spectrum},
        {"rgb_ply", ya.rgb_ply},
        {"s42", {{"a_mm", fit.a},
                 {"b", fit.b},
                 {"rms_log_error", fit.rms_log_error},
                 {"sigma_per_mm", ya.sigma_s42_per_mm},
                 {"rgb_ply", ya.rgb_s42}}},
        {"curve", {{"sigma_per_mm", curve.sigma_per_mm},
                   {"energy", curve.energy},
                   {"rays", curve.rays}}},
        {"notes", "sigma(lambda) maps the sigmoid spectrum (Jakob and Hanika 2019) of the "
                  "yarn colour through the ply's simulated wide-beam sigma -> energy curve "
                  "at theta_i = 0; s42 is the text's exponential fit (Eq. S.42) for "
                  "comparison (baker/include/loom/absorption.h)"}};
  }
  raywave["absorption_seconds"] = seconds_since(at0);
}

/// Render tables at the yarn colours (ray-wave shading: osl/include/loom/raywave_lobes.h,
/// double_layer_factors.h), from the colour-independent tables.
void render_tables_stage(const BakeContext& ctx, const Tables& tables, json& raywave) {
  ctx.progress("shading tables", 0.0);
  const auto st0 = std::chrono::steady_clock::now();
  auto table = [&](const json& name) -> const Image& { return tables.at(name.get<std::string>()); };
  std::array<double, 3> sig[2];
  for (int i = 0; i < 2; ++i) {
    const char* yarn = i == 0 ? "warp" : "weft";
    json& entry = raywave["yarns"][yarn];
    for (int c = 0; c < 3; ++c)
      sig[i][size_t(c)] = entry["absorption"]["sigma_rgb_per_mm"][size_t(c)].get<double>();
    const json& files = entry["files"];
    const AsgTable high = asg_table_from_images(entry, "high", table(files["high"]),
                                                &table(files["high_scale"]),
                                                &table(files["high_residual"]));
    const AsgTable refl = asg_table_from_images(entry, "refl", table(files["refl"]), nullptr,
                                                &table(files["refl_residual"]));
    const std::string name = std::string("ply_tint_") + yarn;
    ctx.out.write_table(ply_tint_image(high, sig[i]), name, {"s_r", "s_g", "s_b"},
                        "f_high lobe amplitude scale (Eq. S.10, S.11) at the yarn's absorption per "
                        "colour channel per corner node, column lobe (N' + 1) + h node, row "
                        "theta_i node (osl/include/loom/raywave_lobes.h)");
    entry["files"]["tint"] = name;
    const std::string rname = std::string("ply_residual_") + yarn;
    ctx.out.write_table(ply_residual_rgb_image(high, refl, sig[i]), rname, {"r", "g", "b"},
                        "energy residual of f_refl + f_high (baker/include/loom/asg_residual.h) "
                        "at the yarn's absorption per colour channel, column side N + n, row m "
                        "(osl/include/loom/raywave_lobes.h: raywave_residual_uv)");
    entry["files"]["residual"] = rname;
  }
  std::array<double, 3> sig_layers;
  for (int c = 0; c < 3; ++c) sig_layers[size_t(c)] = 0.5 * (sig[0][size_t(c)] + sig[1][size_t(c)]);
  const json& dl = raywave["double_layer"];
  json shading = {{"factors", json::object()},
                  {"factors_layout", kLayerFactorsLayout},
                  {"microfacet_albedo", "microfacet_albedo"},
                  {"layer_sigma_rgb_per_mm", sig_layers},
                  // Eq. S.10's weight between absorption levels (absorption_curve.h).
                  {"sigma_interpolation", kSigmaInterpolation}};
  for (const char* side : {"front", "back"}) {
    DoubleLayerGrid g;
    g.table = table(dl["files"][side]);
    g.theta_count = dl["theta_count"];
    g.phi_count = dl["phi_count"];
    g.sigmas = dl["sigma_per_mm"].get<std::vector<double>>();
    g.absorption = layer_absorption_curve(raywave);
    const std::string name = std::string("layer_factors_") + side;
    ctx.out.write_table(layer_factors_image(g, sig_layers), name, {"r", "g", "b"},
                        "per-point double-layer factors k_b = (B_total - B_t) / F_t, k_f = "
                        "F_total / F_t (Eq. S.20-S.22) at the yarns' absorption, two blocks of "
                        "phi_count + 2 columns (osl/include/loom/double_layer_factors.h)");
    shading["factors"][side] = name;
  }
  if (!ctx.out.has("microfacet_albedo"))  // (copied on a colour-only change)
    ctx.out.write_table(microfacet_albedo_image(), "microfacet_albedo",
                        {"E_reflect", "E_refract", "0"},
                        "directional albedos of Cycles' Beckmann reflection and refraction "
                        "closures over (cos(N, V), sqrt(alpha)) (osl/include/loom/raywave_lobes.h)");
  ctx.out.write_table(asg_integral_lut_image(), "asg_integral_lut", {"h"},
                      "asg_integral(mu1, mu2, 1) sqrt((1 + mu1) (1 + mu2)) / pi over the "
                      "bandwidths' log coordinates (osl/include/loom/asg.h: "
                      "asg_integral_from_lut)");
  shading["asg_integral"] = "asg_integral_lut";
  shading["seconds"] = seconds_since(st0);
  raywave["shading"] = shading;
  ctx.progress("shading tables", 1.0);
}

}  // namespace

json bake_raywave_stages(const BakeContext& ctx, const std::string& simulation_key) {
  json raywave = {
      {"status", "ply tables (Eq. S.1-S.12, multi-ply S.13-S.19) and double-layer "
                 "factors (S.20), aperture diffraction (S.34, S.35), speckle noise tiles "
                 "(S.37, S.38), absorption spectra from the yarn colours (S.42) and the "
                 "render tables at those colours baked; shading evaluates the lobes, the "
                 "double-layer factors, the gaps' diffraction and the speckle noise per "
                 "lobe; ply-edge diffraction at render time is not yet"},
      {"yarns", json::object()}};
  Simulated s = ctx.source ? reuse_simulation(ctx, raywave) : simulate(ctx, raywave);
  raywave["simulation_key"] = simulation_key;
  absorption_stage(ctx, s, raywave);
  render_tables_stage(ctx, s.tables, raywave);
  return raywave;
}

}  // namespace loom
