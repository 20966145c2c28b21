// validate_atlas: what stands between a manifest and its readers (the contract in atlas.h).
#include <fmt/format.h>

#include <map>
#include <string>
#include <vector>

#include "loom/atlas.h"
#include "loom/closure_lut.h"
#include "loom/ply_tables.h"
#include "loom/render_tables.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace loom {

std::string string_field(const json& j, const char* key) {
  if (!j.is_object()) return "";
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : "";
}

namespace {

const char* const kSurfaceMaps[] = {"ply_frame",   "ply_normal",      "yarn_info",
                                   "albedo_reflect", "albedo_transmit", "spec_params",
                                   "horizon_0",   "horizon_1",       "closure_lut"};

/// The type and range checks of the manifest's fields that the deep readers (load_ply_tables,
/// load_raywave, the shading tables) take as they are: `errors` gets one message naming the
/// field for each problem.
struct FieldChecks {
  std::vector<std::string>& errors;

  /// parent[key] if parent is an object holding it, else null.
  static const json& at(const json& parent, const char* key) {
    static const json null;
    if (!parent.is_object()) return null;
    const auto it = parent.find(key);
    return it == parent.end() ? null : *it;
  }
  bool string(const json& parent, const char* key, const std::string& path, bool required) {
    const json& v = at(parent, key);
    if (v.is_string() || (v.is_null() && !required && !parent.contains(key))) return true;
    errors.push_back(fmt::format("{}: expected a string{}", path, v.is_null() ? " (missing)" : ""));
    return false;
  }
  bool integer(const json& parent, const char* key, const std::string& path, long long lo,
               long long hi, bool required = true) {
    const json& v = at(parent, key);
    if (!required && !parent.contains(key)) return true;
    if (v.is_number_integer() && v.get<long long>() >= lo && v.get<long long>() <= hi &&
        !(v.is_number_unsigned() && v.get<unsigned long long>() > (unsigned long long)hi))
      return true;
    errors.push_back(fmt::format("{}: expected an integer in [{}, {}]{}", path, lo, hi,
                                 v.is_null() ? " (missing)" : ", not " + v.dump()));
    return false;
  }
  bool number(const json& parent, const char* key, const std::string& path, double lo, double hi,
              bool required = true) {
    const json& v = at(parent, key);
    if (!required && !parent.contains(key)) return true;
    if (v.is_number() && v.get<double>() >= lo && v.get<double>() <= hi) return true;
    errors.push_back(fmt::format("{}: expected a number in [{}, {}]{}", path, lo, hi,
                                 v.is_null() ? " (missing)" : ", not " + v.dump()));
    return false;
  }
  /// An array of min_n to max_n numbers in [lo, hi], strictly increasing if `increasing`.
  bool numbers(const json& parent, const char* key, const std::string& path, size_t min_n,
               size_t max_n, double lo, double hi, bool increasing) {
    const json& v = at(parent, key);
    bool ok = v.is_array() && v.size() >= min_n && v.size() <= max_n;
    for (size_t k = 0; ok && k < v.size(); ++k)
      ok = v[k].is_number() && v[k].get<double>() >= lo && v[k].get<double>() <= hi &&
           (!increasing || k == 0 || v[k].get<double>() > v[k - 1].get<double>());
    if (ok) return true;
    errors.push_back(fmt::format("{}: expected {} to {} numbers in [{}, {}]{}", path, min_n, max_n,
                                 lo, hi, increasing ? ", increasing" : ""));
    return false;
  }
};

/// What load_ply_tables and load_raywave read besides the texture names (checked by the caller):
/// their types, and for the integers the ranges that keep the readers' arithmetic in range.
/// The readers check the values' meaning themselves (grids, lobe counts, curves, image sizes).
void check_raywave_fields(const json& m, std::vector<std::string>& errors) {
  FieldChecks c{errors};
  const json& rw = FieldChecks::at(m, "raywave");
  const json& repeat = FieldChecks::at(m, "repeat");
  c.integer(repeat, "warp_yarns", "repeat.warp_yarns", 1, kMaxMapSide);
  c.integer(repeat, "weft_yarns", "repeat.weft_yarns", 1, kMaxMapSide);
  const json& yarns = FieldChecks::at(rw, "yarns");
  for (const char* yarn : {"warp", "weft"}) {
    const json& y = FieldChecks::at(yarns, yarn);
    if (!y.is_object()) continue;  // reported by the caller
    const std::string p = fmt::format("raywave.yarns.{}", yarn);
    c.string(y, "yarn", p + ".yarn", false);
    for (const char* which : {"high", "refl"})
      c.number(FieldChecks::at(y, which), "nrmse", fmt::format("{}.{}.nrmse", p, which), 0, 1e30,
               false);
    const json& ab = FieldChecks::at(y, "absorption");
    if (!ab.is_object()) {
      errors.push_back(p + ".absorption: expected an object (the yarn's absorption)");
      continue;
    }
    c.numbers(ab, "sigma_rgb_per_mm", p + ".absorption.sigma_rgb_per_mm", 3, 3, 0, 1e30, false);
    const json& curve = FieldChecks::at(ab, "curve");
    if (!curve.is_object())
      errors.push_back(p + ".absorption.curve: expected an object");
    else
      c.integer(curve, "rays", p + ".absorption.curve.rays", 0, (1LL << 62), false);
  }
  const json& dl = FieldChecks::at(rw, "double_layer");
  c.integer(dl, "theta_count", "raywave.double_layer.theta_count", 1, 2 * kMaxMapSide);
  c.integer(dl, "phi_count", "raywave.double_layer.phi_count", 1, kMaxMapSide);
  c.numbers(dl, "sigma_per_mm", "raywave.double_layer.sigma_per_mm", 1, 2 * kMaxMapSide, 0, 1e30,
            true);
  c.number(dl, "blend", "raywave.double_layer.blend", 0, 1, false);
  c.string(FieldChecks::at(rw, "shading"), "sigma_interpolation",
           "raywave.shading.sigma_interpolation", false);
  const json& dif = FieldChecks::at(rw, "diffraction");
  const json& dfiles = FieldChecks::at(dif, "files");
  if (dfiles.is_object() && dfiles.contains("gap")) {
    c.integer(dif, "tile_size", "raywave.diffraction.tile_size", 2, kMaxMapSide);
    c.number(dif, "spot_s", "raywave.diffraction.spot_s", 0, 1e30);
    c.numbers(dif, "gap_fraction", "raywave.diffraction.gap_fraction", 2, 2, 0, 1, false);
    if (!dfiles.contains("gap_sampling"))
      errors.push_back("raywave.diffraction.files.gap_sampling: missing (the gap table needs it)");
  }
  const json& nz = FieldChecks::at(rw, "noise");
  const json& nfiles = FieldChecks::at(nz, "files");
  if (nfiles.is_object() && (nfiles.contains("refl") || nfiles.contains("high"))) {
    if (!nfiles.contains("refl") || !nfiles.contains("high"))
      errors.push_back("raywave.noise.files: expected both \"refl\" and \"high\", or neither");
    c.integer(nz, "levels", "raywave.noise.levels", 0, 64);
    c.integer(nz, "instances", "raywave.noise.instances", 1, 2 * kMaxMapSide);
    c.integer(nz, "theta_count", "raywave.noise.theta_count", 1, kMaxMapSide);
  }
}

/// validate_atlas, keeping in `node_files` (when given) the bytes of every texture's node_file
/// it hashed and checked, by texture name, for load_atlas to decode.
/// The repeat-averaged closures (average_fit.h; optional: readers that need them say so): a
/// texture of the atlas in average_closures.h's layout and the repeat's mean gap.
void check_average_fields(const json& m, const json& tex, std::vector<std::string>& errors) {
  if (!m.contains("average")) return;
  FieldChecks f{errors};
  const json& a = m["average"];
  if (!a.is_object()) {
    errors.push_back("average: expected an object");
    return;
  }
  if (f.string(a, "texture", "average.texture", true)) {
    const std::string name = a["texture"].get<std::string>();
    const json want = {LOOM_AVERAGE_PHI + 1, 2 * LOOM_AVERAGE_PANELS * LOOM_AVERAGE_THETA};
    if (!tex.contains(name))
      errors.push_back("average.texture: not a texture of the atlas");
    else if (tex[name].value("size", json()) != want)
      errors.push_back(fmt::format("textures.{}: size {} is not {} (average_closures.h's layout: "
                                   "re-bake the atlas)",
                                   name, tex[name].value("size", json()).dump(), want.dump()));
  }
  f.number(a, "gap_mean", "average.gap_mean", 0.0, 0.999);
}

/// The atlas's manifest.json, read and parsed, of this schema and with textures; or the one
/// error that makes `dir` no atlas (in `error`).
std::optional<json> read_manifest(const fs::path& dir, std::string& error) {
  fs::path mp = dir / "manifest.json";
  auto fail = [&](std::string e) {
    error = std::move(e);
    return std::nullopt;
  };
  AtlasFile manifest_file;
  try {
    manifest_file = read_atlas_file(dir, "manifest.json");
  } catch (const AtlasFileError& e) {
    if (e.kind == AtlasFileError::Kind::SymbolicLink)
      return fail(fmt::format("{}: is a symbolic link; an atlas's files must be regular files in "
                              "its directory",
                              mp.string()));
    if (e.kind == AtlasFileError::Kind::Missing)
      return fail(fmt::format("{}: missing or unreadable (not an atlas)", mp.string()));
    return fail(fmt::format("{} (not an atlas)", e.what()));
  }
  json m;
  try {
    m = json::parse(manifest_file.bytes);
  } catch (const std::exception& e) {
    return fail(fmt::format("{}: not valid JSON: {}", mp.string(), e.what()));
  }
  if (!m.is_object() || !m.contains("schema") || !m["schema"].is_string())
    return fail(fmt::format("{}: no \"schema\" field", mp.string()));
  if (m["schema"] != kAtlasSchema)
    return fail(fmt::format("{}: schema {} is not supported; this baker reads \"{}\" (re-bake "
                            "the atlas)",
                            mp.string(), m["schema"].dump(), kAtlasSchema));
  if (!m.contains("textures") || !m["textures"].is_object() || m["textures"].empty())
    return fail(fmt::format("{}: no \"textures\"", mp.string()));
  return m;
}

/// Each texture the manifest lists: both files plain names inside `dir`, regular files whose
/// SHA-256 matches and whose header matches the size and channels listed; the node files kept
/// in `node_files` if given.
void check_texture_files(const fs::path& dir, json& m,
                         std::map<std::string, AtlasFile>* node_files,
                         std::vector<std::string>& errors) {
  for (auto& [name, t] : m["textures"].items()) {
    if (!t.is_object()) {
      errors.push_back(fmt::format("textures.{}: expected an object", name));
      continue;
    }
    for (const char* key : {"file", "node_file"}) {
      if (!t.contains(key) || !t[key].is_string() || !plain_atlas_file_name(t[key].get<std::string>())) {
        errors.push_back(fmt::format("textures.{}.{}: must be a plain file name inside the atlas "
                                     "directory",
                                     name, key));
        continue;
      }
      fs::path f = dir / t[key].get<std::string>();
      std::string hkey = std::string(key) == "file" ? "sha256" : "node_sha256";
      // Choice: no symbolic links at all, to a file inside the atlas or outside it. Only the
      // ones leaving the directory are a danger (an atlas from elsewhere reading any file the
      // user can), but a link inside is never written by the baker, and refusing every link at
      // the read itself (read_atlas_file: O_NOFOLLOW) leaves no window for a swap.
      AtlasFile file;
      try {
        file = read_atlas_file(dir, t[key].get<std::string>());
      } catch (const AtlasFileError& e) {
        using Kind = AtlasFileError::Kind;
        if (e.kind == Kind::SymbolicLink)
          errors.push_back(fmt::format("textures.{}.{}: {} is a symbolic link; an atlas's files "
                                       "must be regular files in its directory",
                                       name, key, f.string()));
        else if (e.kind == Kind::Missing || e.kind == Kind::NotRegular)
          errors.push_back(fmt::format("textures.{}: {} is missing{}", name, f.string(),
                                       e.kind == Kind::NotRegular ? " (not a regular file)" : ""));
        else
          errors.push_back(fmt::format("textures.{}: {}", name, e.what()));
        continue;
      }
      if (!t.contains(hkey) || !t[hkey].is_string() || sha256_string(file.bytes) != t[hkey]) {
        errors.push_back(
            fmt::format("textures.{}: {} does not match its sha256 (corrupted or changed)", name,
                        f.string()));
        continue;
      }
      std::array<int, 3> s{};
      try {
        s = atlas_image_header(file);
      } catch (const std::runtime_error& e) {
        errors.push_back(fmt::format("textures.{}: {}", name, e.what()));
        continue;
      }
      if (!t.contains("size") || t["size"] != json::array({s[0], s[1]}) ||
          !t.contains("channels") || !t["channels"].is_array() ||
          int(t["channels"].size()) != s[2]) {
        errors.push_back(fmt::format("textures.{}: {} is {}x{}x{}, the manifest says otherwise",
                                     name, f.string(), s[0], s[1], s[2]));
        continue;
      }
      if (node_files && std::string(key) == "node_file") (*node_files)[name] = std::move(file);
    }
  }
}

/// The surface contract of the evaluators and shaders: the maps, their sizes, the closure LUT's
/// layout and the fitted closures' tiles.
void check_surface_contract(const json& tex, std::vector<std::string>& errors) {
  // The contract the evaluators rely on: every map, four channels, one size for all maps, and
  // the closure LUT's layout.
  std::optional<json> map_size;
  for (const char* name : kSurfaceMaps) {
    if (!tex.contains(name)) {
      errors.push_back(fmt::format("textures.{}: missing from the manifest", name));
      continue;
    }
    const json& t = tex[name];
    if (!t.is_object() || !t.contains("size") || !t.contains("channels") ||
        !t["channels"].is_array() || t["channels"].size() != 4) {
      errors.push_back(fmt::format("textures.{}: expected 4 channels and a size", name));
      continue;
    }
    if (std::string(name) == "closure_lut") {
      const int w = LOOM_LUT_PANELS * LOOM_CLOSURE_LUT_SIZE,
                h = 2 * LOOM_LUT_SLICES * LOOM_CLOSURE_LUT_SIZE;
      if (t["size"] != json::array({w, h}))
        errors.push_back(fmt::format("textures.closure_lut: size {} is not {} x {} (another "
                                     "baker's layout: re-bake the atlas)",
                                     t["size"].dump(), w, h));
    } else if (!map_size) {
      map_size = t["size"];
    } else if (*map_size != t["size"]) {
      errors.push_back(fmt::format("textures.{}: size {} differs from the other maps' {}", name,
                                   t["size"].dump(), map_size->dump()));
    }
  }
  // The per-texel fitted closures (model.closures "fitted"): their tiles follow the maps' size.
  if (tex.contains("fitted_closures") && map_size && map_size->is_array() &&
      map_size->size() == 2 && (*map_size)[0].is_number_integer()) {
    // (And the horizon strip they read V(V) from.)
    for (const auto& [name, tiles] :
         {std::pair<const char*, int>{"fitted_closures", LOOM_FITTED_TILES},
          std::pair<const char*, int>{"horizon_strip", LOOM_HORIZON_DIRS}}) {
      const json want = {tiles * ((*map_size)[0].get<int>() + 2), (*map_size)[1]};
      const json& t = tex.value(name, json());
      if (!t.is_object() || !t.contains("size") || t["size"] != want)
        errors.push_back(fmt::format("textures.{}: size {} is not {} (the maps' {} tiles of "
                                     "their width plus two: re-bake the atlas)",
                                     name, t.is_object() ? t.value("size", json()).dump() : t.dump(),
                                     want.dump(), tiles));
    }
  }
}

/// A ray-wave atlas's tables: each listed file a texture of the atlas, each layout this
/// baker's.
void check_raywave_tables(const json& m, const json& tex, std::vector<std::string>& errors) {
  // Ray-wave atlases: every yarn's tables are textures of this atlas.
  if (m.contains("tier") && m["tier"] == "raywave") {
    if (!m.contains("raywave") || !m["raywave"].is_object() || !m["raywave"].contains("yarns") ||
        !m["raywave"]["yarns"].is_object()) {
      errors.push_back("raywave: missing (a ray-wave atlas lists its ply tables there)");
    } else {
      for (const char* yarn : {"warp", "weft"}) {
        const json& y = m["raywave"]["yarns"].value(yarn, json());
        if (!y.is_object() || !y.contains("files") || !y["files"].is_object()) {
          errors.push_back(fmt::format("raywave.yarns.{}: missing or without \"files\"", yarn));
          continue;
        }
        if (!y.contains("node_layout") || y["node_layout"] != kAsgNodeLayout)
          errors.push_back(fmt::format("raywave.yarns.{}.node_layout: {} is not this baker's \"{}\" "
                                       "(another baker's layout: re-bake the atlas)",
                                       yarn, y.value("node_layout", json("missing")).dump(),
                                       kAsgNodeLayout));
        for (const char* f : {"high", "high_scale", "refl", "tint", "high_residual",
                              "refl_residual", "residual"}) {
          const json& name = y["files"].value(f, json());
          if (!name.is_string() || !tex.contains(name.get<std::string>()))
            errors.push_back(fmt::format("raywave.yarns.{}.files.{}: not a texture of the atlas",
                                         yarn, f));
        }
      }
      const json& dl = m["raywave"].value("double_layer", json());
      for (const char* f : {"front", "back"}) {
        const json& name = dl.is_object() && dl.contains("files") && dl["files"].is_object()
                               ? dl["files"].value(f, json())
                               : json();
        if (!name.is_string() || !tex.contains(name.get<std::string>()))
          errors.push_back(fmt::format("raywave.double_layer.files.{}: not a texture of the atlas",
                                       f));
      }
      // Shading tables at the yarn colours.
      const json& sh = m["raywave"].value("shading", json());
      for (const char* f : {"front", "back"}) {
        const json& name = sh.is_object() && sh.contains("factors") && sh["factors"].is_object()
                               ? sh["factors"].value(f, json())
                               : json();
        if (!name.is_string() || !tex.contains(name.get<std::string>()))
          errors.push_back(fmt::format("raywave.shading.factors.{}: not a texture of the atlas", f));
      }
      if (!sh.is_object() || !sh.contains("factors_layout") ||
          sh["factors_layout"] != kLayerFactorsLayout)
        errors.push_back(fmt::format(
            "raywave.shading.factors_layout: {} is not this baker's \"{}\" (double-layer factors "
            "of another baker: re-bake the atlas)",
            sh.is_object() && sh.contains("factors_layout") ? sh["factors_layout"].dump()
                                                            : std::string("missing"),
            kLayerFactorsLayout));
      if (!sh.is_object() || !sh.value("asg_integral", json()).is_string() ||
          !tex.contains(sh["asg_integral"].get<std::string>()))
        errors.push_back("raywave.shading.asg_integral: not a texture of the atlas (an atlas from "
                         "an older loom-bake: re-bake it)");
      if (!sh.is_object() || !sh.value("microfacet_albedo", json()).is_string() ||
          !tex.contains(sh["microfacet_albedo"].get<std::string>()))
        errors.push_back("raywave.shading.microfacet_albedo: not a texture of the atlas");
      // Noise: the listed tiles (none when wave.noise is off) are textures of the atlas.
      const json& noise = m["raywave"].value("noise", json());
      if (!noise.is_object() || !noise.contains("files") || !noise["files"].is_object())
        errors.push_back("raywave.noise.files: missing");
      else
        for (auto& [k, name] : noise["files"].items())
          if (!name.is_string() || !tex.contains(name.get<std::string>()))
            errors.push_back(fmt::format("raywave.noise.files.{}: not a texture of the atlas", k));
      // Diffraction: "tables" lists its files; "delta" (the non-wave variant) has none.
      const json& dif = m["raywave"].value("diffraction", json());
      const json& mode_j = FieldChecks::at(dif, "mode");
      const std::string mode = mode_j.is_string() ? mode_j.get<std::string>() : "";
      if (mode != "tables" && mode != "delta") {
        errors.push_back("raywave.diffraction.mode: expected \"tables\" or \"delta\"");
      } else if (mode == "tables") {
        const json& files = dif.value("files", json());
        if (!files.is_object() || !files.contains("edge"))
          errors.push_back("raywave.diffraction.files: missing (needs at least \"edge\")");
        else
          for (auto& [k, name] : files.items())
            if (!name.is_string() || !tex.contains(name.get<std::string>()))
              errors.push_back(
                  fmt::format("raywave.diffraction.files.{}: not a texture of the atlas", k));
      }
      check_raywave_fields(m, errors);
    }
  }
}

std::vector<std::string> validate_atlas_files(const fs::path& dir, json* manifest_out,
                                              std::map<std::string, AtlasFile>* node_files) {
  std::string error;
  std::optional<json> read = read_manifest(dir, error);
  if (!read) return {error};
  json& m = *read;
  std::vector<std::string> errors;
  check_texture_files(dir, m, node_files, errors);
  const auto& tex = m["textures"];
  check_surface_contract(tex, errors);
  if (m.contains("tier") && !m["tier"].is_string())
    errors.push_back(fmt::format("tier: expected a string, not {}", m["tier"].dump()));
  check_average_fields(m, tex, errors);
  check_raywave_tables(m, tex, errors);
  if (manifest_out) *manifest_out = m;
  return errors;
}

}  // namespace

std::vector<std::string> validate_atlas(const fs::path& dir, json* manifest_out) {
  return validate_atlas_files(dir, manifest_out, nullptr);
}

std::vector<std::string> validate_atlas(const fs::path& dir, json* manifest_out,
                                        std::map<std::string, AtlasFile>* node_files) {
  return validate_atlas_files(dir, manifest_out, node_files);
}

}  // namespace loom
