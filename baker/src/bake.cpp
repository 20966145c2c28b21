// bake_atlas: the bake as its stages in order (bake_stages.h), the reuse of an atlas that holds
// the same bake, and the manifest; the AtlasWriter writes and publishes (atlas_writer.h).
#include "loom/bake.h"

#include <chrono>
#include <fmt/format.h>
#include <fstream>
#include <optional>

#include "bake_stages.h"
#include "loom/closure_lut.h"
#include "loom/fitted_closures.h"
#include "loom/atlas_writer.h"
#include "loom/average_fit.h"
#include "loom/colour.h"
#include "loom/ply_maps.h"
#include "loom/surface_swatch.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace loom {

namespace {

/// A valid ray-wave atlas among the candidates whose simulation key is `key`: the given
/// directories, the destination, then the destination's siblings (the add-on's cache keeps
/// every atlas in one directory). Returns its directory and manifest.
std::optional<std::pair<fs::path, json>> find_simulation(const std::string& key, const fs::path& dir,
                                                         const std::vector<fs::path>& extra) {
  std::vector<fs::path> cands(extra.begin(), extra.end());
  cands.push_back(dir);
  std::error_code ec;
  int scanned = 0;
  for (fs::directory_iterator it(dir.parent_path(), ec), end; !ec && it != end; it.increment(ec)) {
    if (++scanned > 512) break;  // a crowded directory is not worth a long search
    const auto name = it->path().filename().string();
    if (!name.empty() && name[0] != '.' && it->path() != dir) cands.push_back(it->path());
  }
  for (const fs::path& c : cands) {
    std::ifstream in(c / "manifest.json");
    if (!in) continue;
    json m = json::parse(in, nullptr, false);
    if (m.is_discarded() || !m.is_object() || !m.contains("raywave") ||
        string_field(m["raywave"], "simulation_key") != key)
      continue;
    if (!validate_atlas(c, &m).empty()) continue;
    return std::pair{fs::absolute(c), m};
  }
  return std::nullopt;
}

/// What decides whether an existing atlas can be reused: the spec, the colour conversion and
/// the very baker binary that made it (a rebuilt baker may bake the same spec differently, and a
/// version number that someone must remember to bump would let stale atlases through).
const std::string& baker_id() {
  static const std::string id = [] {
    std::error_code ec;
    auto exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string(kBakerVersion) : sha256_file(exe);
  }();
  return id;
}

json manifest_of(const BakeContext& ctx, const std::string& bake_key, const json& repeat,
                 json textures, json raywave) {
  const FabricSpec& spec = ctx.spec;
  json manifest = {
      {"schema", kAtlasSchema},
      {"baker_version", kBakerVersion},
      {"spec_sha256", sha256_string(ctx.canonical_spec.dump())},
      {"bake_key", bake_key},
      {"spec", ctx.canonical_spec},
      {"tier", to_string(spec.tier)},
      {"quality", to_string(spec.quality)},
      {"repeat", repeat},
      {"texels_per_cell", texels_per_cell(spec.quality)},
      {"colour", ctx.cc.describe()},
      {"yarn_colours_linear", {{"warp", spec.warp.color_linear}, {"weft", spec.weft.color_linear}}},
      {"conventions",
       {{"frame", "tangent frame: x along the warp (u), y along the weft (v), z the normal"},
        {"rows", "row 0 of every file is the top (v = 1); Blender's v = 0 is the bottom"},
        {"uv", "one weave repeat spans uv [0,1)^2; shaders wrap uv themselves"}}},
      {"textures", std::move(textures)}};
  if (!raywave.is_null()) manifest["raywave"] = std::move(raywave);
  return manifest;
}

}  // namespace

std::string raywave_simulation_key(json canon, const std::string& colour,
                                   const std::string& baker_id) {
  canon.erase("name");
  if (canon.contains("model") && canon["model"].is_object()) canon["model"].erase("colour_reading");
  for (const char* y : {"warp", "weft"})
    if (canon.contains(y) && canon[y].is_object()) canon[y].erase("color");
  return sha256_string(canon.dump() + colour + baker_id);
}

namespace {

void write_map(const BakeContext& ctx, const SurfaceMaps& maps, size_t k) {
  const MapInfo& mi = maps.info[k];
  ctx.out.write(maps.images[k], mi.name, true, "periodic",
                {{"channels", mi.channels},
                 {"range", mi.range},
                 {"units", mi.units},
                 {"tiling", "periodic"},
                 {"period_uv", {1.0, 1.0}},
                 {"description", mi.description}});
}

}  // namespace

json bake_surface_stage(const BakeContext& ctx) {
  const bool reuse = ctx.source.has_value();
  SurfaceMaps maps = bake_surface_maps(ctx.spec, ctx.progress_fn, /*horizons=*/!reuse);
  // (Before the maps are written: the "write" progress is the stage's last.)
  const Image lut = reuse ? Image() : bake_closure_lut(ctx.spec, ctx.progress_fn);
  for (size_t k = 0; k < maps.images.size(); ++k) {
    const MapInfo& mi = maps.info[k];
    if (reuse && mi.name.rfind("albedo_", 0) != 0) {  // only the albedo maps hold colour
      ctx.out.copy(ctx.source->first, ctx.source->second, mi.name);
      continue;
    }
    write_map(ctx, maps, k);
    ctx.progress("write", double(k + 1) / (maps.images.size() + 1));
  }
  if (reuse) {
    ctx.out.copy(ctx.source->first, ctx.source->second, "closure_lut");  // per unit colour
  } else {
    ctx.out.write(
        lut, "closure_lut", false, "clamp",
        {{"channels", {"g | h", "ax | r1", "ay | r2", "0 | l"}},
         {"range", {{0, kClosureLutMaxWeight}, {0, 1}, {0, 1}, {0, kClosureLutMaxWeight}}},
         {"units", {"", "", "", ""}},
         {"tiling", "clamp"},
         {"description",
          fmt::format("fitted closure parameters per unit k (closure_mapping.h, closure_fit.h): "
                      "left panel reflection (GGX weight g, alpha_x along t, alpha_y, 0), right "
                      "panel transmission (hair transmission weight h, roughness r1, r2, "
                      "translucent weight l), each {2} columns of the view azimuth about t over "
                      "[0, pi]; rows kind-major (warp, then weft, from the bottom), then {0} slices "
                      "of the ply tangent elevation t_z in [0, {1}], then {2} rows of "
                      "cos theta_view (row j at max(j/{3}, {4}))",
                      LOOM_LUT_SLICES, LOOM_LUT_TZ_MAX, LOOM_CLOSURE_LUT_SIZE,
                      LOOM_CLOSURE_LUT_SIZE - 1, kLutMinCos)}});
  }
  return {{"warp_yarns", maps.warp_yarns},
          {"weft_yarns", maps.weft_yarns},
          {"size_um", {maps.repeat_um[0], maps.repeat_um[1]}}};
}

/// The surface tier's swatch reading (surface_swatch.h): the albedo maps rewritten with each
/// colour's solved albedo; adds the manifest's "swatch" section.
void bake_surface_swatch_stage(const BakeContext& ctx, json& manifest) {
  ctx.progress("swatch", 0.0);
  const Atlas a = ctx.out.load_written(manifest);
  auto white = [](const std::array<double, 3>&) { return std::array<double, 3>{1, 1, 1}; };
  const SurfaceSwatchCurve curve =
      surface_swatch_curve(a, bake_surface_maps(with_colours(ctx.spec, white), {}, false),
                           surface_swatch_settings(ctx.spec.quality));
  ctx.progress("swatch", 0.7);
  json yarns = json::object();
  auto solve = [&](const std::string& name, const std::array<double, 3>& picked) {
    const SurfaceSwatchColour c = surface_swatch_albedo(curve, picked);
    yarns[name] = {{"colour_linear", picked}, {"albedo", c.albedo}, {"swatch_rho", c.rho},
                   {"swatch_out_of_reach", c.out_of_reach}};
    return c.albedo;
  };
  solve("warp", ctx.spec.warp.color_linear);
  solve("weft", ctx.spec.weft.color_linear);
  for (const YarnType& t : ctx.spec.yarn_types) solve("type " + t.name, t.color_linear);
  const FabricSpec solved = with_colours(ctx.spec, [&](const std::array<double, 3>& c) {
    return surface_swatch_albedo(curve, c).albedo;
  });
  const SurfaceMaps maps = bake_surface_maps(solved, {}, false);
  for (size_t k = 0; k < maps.images.size(); ++k)
    if (maps.info[k].name.rfind("albedo_", 0) == 0) write_map(ctx, maps, k);
  manifest["textures"] = ctx.out.hashed_textures();
  manifest["swatch"] = {
      {"definition", "each yarn colour is the swatch of its cloth folded to opacity, d:8, as "
                     "the closures render it (baker/include/loom/surface_swatch.h)"},
      {"rho_at_albedo_0", curve.at0.rho},
      {"rho_at_albedo_1", curve.at1.rho},
      {"albedo_max", curve.albedo_max},
      {"albedo_max_why",
       fmt::format("the yarns' directional albedo at most {} at every point and view of the "
                   "swatch's quadrature (but never below 1), and no albedo texel above 1",
                   kSurfaceSwatchMaxAlbedo)},
      {"yarns", yarns}};
  ctx.progress("swatch", 1.0);
}

/// The per-texel fitted closures (fitted_closures.h; model.closures "fitted"), fitted against the
/// atlas as written so far; adds their texture.
void bake_fitted_closures_stage(const BakeContext& ctx, json& manifest) {
  const Atlas a = ctx.out.load_written(manifest);
  const Image img = fit_texel_closures(a, fitted_closure_options(ctx.spec.quality),
                                       [&](double x) { ctx.progress("fitted closures", x); });
  ctx.out.write_table(
      img, "fitted_closures", {"a_np | m_g", "a_ns | m_h", "b_np | l", "b_ns | 0"},
      fmt::format("per-texel closure weights fitted to the model (fitted_closures.h), per unit "
                  "colour term: {} tiles side by side, (a_np, a_ns, b_np, b_ns) and (m_g, m_h, "
                  "l, 0) for the front, then the same for the back; each tile the maps' width "
                  "plus a column either side repeating the opposite edge",
                  LOOM_FITTED_TILES),
      false, "periodic");
  ctx.out.write_table(
      horizon_strip(a), "horizon_strip", {"h_k", "h_k+1", "0", "0"},
      fmt::format("the horizon maps' sines for the shaders' V(V) with fitted closures "
                  "(fitted_closures.h): {} tiles side by side, tile k holding the sines of "
                  "azimuths k and k + 1; each tile the maps' width plus a column either side "
                  "repeating the opposite edge",
                  LOOM_HORIZON_DIRS),
      false, "periodic");
  manifest["textures"] = ctx.out.hashed_textures();
}

/// The repeat-averaged closures (average_fit.h), fitted against the atlas as written so far;
/// adds their texture and the manifest's "average" section.
void bake_average_stage(const BakeContext& ctx, json& manifest) {
  const Atlas a = ctx.out.load_written(manifest);
  const AverageFitOptions o = average_fit_options(to_string(ctx.spec.quality));
  const AverageFit f =
      fit_average_closures(a, o, [&](double x) { ctx.progress("average", x); });
  ctx.out.write_table(
      f.table, "average_closures", {"w.r", "w.g", "w.b", "alpha"},
      fmt::format("the repeat-averaged closures (average_closures.h): {} + 1 columns of the view "
                  "azimuth; rows by side, then panel (diffuse, translucent, GGX glossy, GGX "
                  "refraction: its weight w, and alpha a_x, a_y, a_t, 0 in turn), then {} rows of "
                  "cos theta_v",
                  LOOM_AVERAGE_PHI, LOOM_AVERAGE_THETA));
  manifest["average"] = average_manifest(f, o);
  manifest["textures"] = ctx.out.hashed_textures();
}

BakeResult bake_atlas(FabricSpec spec, const fs::path& dir_in, const BakeOptions& opt) {
  auto t0 = std::chrono::steady_clock::now();
  fs::path dir = fs::absolute(dir_in).lexically_normal();
  if (dir.filename().empty()) dir = dir.parent_path();
  ColourConverter cc(opt.ocio_config);
  resolve_yarn_colours(spec, cc);
  const json canon = canonical_spec(spec);
  const std::string bake_key = sha256_string(canon.dump() + cc.describe().dump() + baker_id());

  BakeResult res;
  res.dir = dir;
  if (fs::exists(fs::symlink_status(dir))) {
    json m;
    if (!opt.force && validate_atlas(dir, &m).empty() && string_field(m, "bake_key") == bake_key) {
      res.reused = true;
      res.bytes = atlas_dir_bytes(dir);
      return res;
    }
    check_bake_destination(dir);
  }
  {
    AtlasWriter out(dir);
    // A colour-only change of a ray-wave spec: an atlas with the same simulation key (the
    // destination's previous bake, a sibling in the cache, or --reuse) holds every table that
    // does not depend on the colours; they are copied instead of computed.
    const std::string sim_key = raywave_simulation_key(canon, cc.describe().dump(), baker_id());
    BakeContext ctx{spec, canon, cc, opt.progress, out, std::nullopt};
    if (spec.tier == Tier::Raywave && !opt.force)
      ctx.source = find_simulation(sim_key, dir, opt.reuse_from);
    const json repeat = bake_surface_stage(ctx);
    json raywave;
    if (spec.tier == Tier::Raywave) {
      raywave = bake_raywave_stages(ctx, sim_key);
      if (ctx.source) res.reused_simulation = ctx.source->first;
    }
    json manifest =
        manifest_of(ctx, bake_key, repeat, out.hashed_textures(), std::move(raywave));
    // The fitted closures hold no colour, so they come first: the swatch's colour solve then
    // sees the closures that render.
    if (spec.closures == ClosureSource::Fitted) bake_fitted_closures_stage(ctx, manifest);
    if (spec.tier == Tier::Surface && spec.colour_reading == ColourReading::Swatch)
      bake_surface_swatch_stage(ctx, manifest);
    bake_average_stage(ctx, manifest);
    res.reused = out.publish(manifest, bake_key, opt.force);
  }
  res.bytes = atlas_dir_bytes(dir);
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace loom
