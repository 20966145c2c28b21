// The fabric spec: one JSON file describes a fabric (schema "loom.fabric/1").
//
// Every field has a unit, a default and an allowed range (the README's spec table; `loom-bake
// check` prints the canonical spec with every default filled in). Parsing never throws on bad
// input: it returns every problem found, one message per problem, each naming the JSON path and
// the allowed range.
#pragma once

#include <array>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace loom {

inline constexpr const char* kSpecSchema = "loom.fabric/1";

enum class Quality { Draft, Preview, Final, Reference };
enum class Tier { Surface, Raywave, Fiber };

const char* to_string(Quality q);
enum class ColourReading { Swatch, PlyAlbedo };
/// What the surface tier's shaders render (issue 31): closures mapped from the model per sample
/// (closure_mapping.h), or fitted per texel at bake time (fitted_closures.h).
enum class ClosureSource { Mapped, Fitted };
const char* to_string(ColourReading r);
const char* to_string(Tier t);

/// One yarn system (warp or weft). Lengths in micrometres.
struct YarnSpec {
  int plies = 2;                       ///< plies per yarn, [1, 8]
  int fibers_per_ply = 40;             ///< [1, 1000]
  double yarn_diameter_um = 300;       ///< [10, 5000]
  double ply_diameter_um = 170;        ///< [5, 5000], <= yarn diameter
  double fiber_diameter_um = 15;       ///< [1, 200], <= ply diameter
  double fiber_twist_pitch_um = 2000;  ///< [50, 100000]
  double ply_twist_deg = 25;           ///< angle of the plies to the yarn axis, [0, 60]
  std::string twist = "S";             ///< "S" or "Z"
  double ior = 1.55;                   ///< [1, 3]
  std::array<double, 3> color_linear{0.5, 0.5, 0.5};  ///< scene-linear RGB after conversion
  std::array<double, 3> color_input{0.5, 0.5, 0.5};   ///< as written in the spec
  std::string color_space = "srgb";    ///< "srgb" or "linear"
  double roughness = 0.25;             ///< SGGX fiber roughness, [0.001, 1]
  double specular = 0.3;               ///< fraction of light scattered specularly, [0, 1]
  double transmission = 0.25;          ///< fraction of it transmitted, [0, 1]
  // Procedural fibers (Luan et al. 2017, Eq. 2-4), used by the ray-wave and fiber tiers.
  double migration_min = 0.1;          ///< r_min of Eq. 2, [0, 1]
  double migration_max = 1.0;          ///< r_max of Eq. 2, [migration_min, 1]
  double migration_period = 2.0;       ///< s of Eq. 2: migration cycles per twist, [0.1, 10]
  double density_epsilon = 0.1;        ///< epsilon of Eq. 3, [0, 0.5]
  double density_beta = 0.5;           ///< beta of Eq. 3, [0.01, 10]
  double loop_flyaways_per_mm = 0.0;   ///< rho_loop, loops per mm of ply, [0, 100]
  double hair_flyaways_per_mm = 0.0;   ///< rho_hair, hairs per mm of ply, [0, 100]
};

struct WeaveSpec {
  std::string pattern = "plain";  ///< plain | twill | satin | basket | custom
  int up = 2, down = 1;           ///< twill float lengths, [1, 8] each
  std::string direction = "Z";    ///< twill diagonal, "S" or "Z"
  int harness = 5, shift = 2;     ///< satin, harness [5, 16], shift [2, harness-2], coprime
  int group = 2;                  ///< basket, [2, 4]
  std::vector<std::vector<int>> matrix;  ///< custom: rows = warp yarns, cols = weft yarns
  /// The repeat is tiled to a multiple of these (the warp's and weft's yarn sequences: one
  /// repeat holds whole sequences); not part of the canonical weave.
  int tile_rows = 1, tile_cols = 1;
};

/// A yarn type of the per-thread sequences: its own colour. (Types that differ in more than
/// colour are not yet supported: issue 33.)
struct YarnType {
  std::string name;
  std::array<double, 3> color_linear{0.5, 0.5, 0.5};  ///< scene-linear RGB after conversion
  std::array<double, 3> color_input{0.5, 0.5, 0.5};   ///< as written in the spec
  std::string color_space = "srgb";
};

/// `count` threads of yarn type `type` side by side.
struct ThreadRun {
  std::string type;
  int count = 1;
};

struct PerlinSpec {
  bool enabled = false;
  unsigned seed = 1;           ///< [0, 2^31)
  double amplitude = 0.15;     ///< in-plane tangent rotation, radians, [0, 1]
  int cells_per_repeat = 4;    ///< lattice period over one weave repeat, [1, 64]
};

struct ComponentSpec {
  bool transmission = true;  ///< diffuse + specular transmission through yarns
  bool gaps = true;          ///< delta transmission through open gaps between yarns
  bool shadowing = true;     ///< ply/yarn shadowing-masking (horizon visibility)
  /// Ray-wave tier: multi-ply scattering (Eq. S.13-S.19) for yarns of several plies; false
  /// treats the yarn's plies as one ply (the supplement's "multi-ply off").
  bool multi_ply = true;
  /// Ray-wave tier: double-layer scattering (Eq. S.20-S.22); false bakes no double-layer
  /// factors and renders one layer (k_b = 0, k_f = 1 in double_layer_factors.h, no diffuse
  /// part).
  bool double_layer = true;
};

/// Wave optics of the ray-wave tier (ray-wave supplement, sections 4 and 5).
struct WaveSpec {
  /// Gaussian-beam aperture diffraction (section 4) through gaps and past ply edges; false is
  /// the papers' "non-wave" variant, delta transmission, and bakes no diffraction tables.
  bool diffraction = true;
  /// w_0 of Eq. S.25, um, [1, 1000]. The text's worked example (Eq. S.36) uses 10 um; it is the
  /// size of the coherent patch the light brings (tens of um for sunlight, less for lamps).
  double beam_waist_um = 10.0;
  /// Speckle noise tiles (section 5) baked for the shaders to modulate the ply scattering.
  bool noise = true;
  /// w of the speckle PSD (speckle_noise.h): the width of the patch that scatters coherently,
  /// um, [1, 1000]. Grains are about lambda / w radians wide. Defaults to the beam waist's
  /// default (the same coherent patch).
  double speckle_width_um = 10.0;
};

struct FabricSpec {
  std::string name = "default";
  WeaveSpec weave;
  YarnSpec warp, weft;
  double warp_per_cm = 28, weft_per_cm = 28;  ///< thread counts, [1, 400]
  Tier tier = Tier::Surface;
  Quality quality = Quality::Preview;
  /// What a yarn colour means (swatch.h): the ply's single-scattering albedo (absorption.h; the
  /// default, and all the surface and fiber tiers read yet), or the colour of a swatch of the
  /// cloth folded to opacity (ray-wave tier: the fibers' absorption solved for it). The default
  /// changes to the swatch once the surface tier is solved for it too (issue 35): until then
  /// the two tiers would differ the more.
  ColourReading colour_reading = ColourReading::PlyAlbedo;
  /// model.closures: parse_spec's default is "fitted" on the surface tier (its only tier) and
  /// "mapped" elsewhere; the canonical spec names it on the surface tier only (where it must:
  /// without it a mapped spec would read back as fitted).
  ClosureSource closures = ClosureSource::Mapped;
  double optical_thickness = 4.0;  ///< SpongeCake T, [0.01, 100]
  double diffuse_blend = 0.5;      ///< w of Eq. 3/6, [0, 1]
  /// s of the ray-wave supplement's Eq. S.22: the share of double-layer transmission that turns
  /// diffuse, [0, 1]. The text gives no value; 0.5 splits evenly.
  double double_layer_blend = 0.5;
  ComponentSpec components;
  PerlinSpec perlin;
  WaveSpec wave;
  /// Per-thread yarn types ("yarn_types", and "sequence" in "warp" / "weft": runs repeating
  /// across the cloth; stripes, checks, tartans): empty sequence, every thread the system's
  /// own yarn. Surface tier only for now.
  std::vector<YarnType> yarn_types;  ///< sorted by name
  std::vector<ThreadRun> warp_sequence, weft_sequence;
};

/// Threads in one repeat of a sequence (0 for none).
int sequence_length(const std::vector<ThreadRun>& runs);
/// The scene-linear colour of warp (system 1) or weft (system 2) thread `index` (any integer;
/// the sequence repeats), the system's own colour without a sequence.
std::array<double, 3> thread_colour_linear(const FabricSpec& s, int system, int index);
/// Whether any thread's colour differs from its system's own (a reader that knows one colour per
/// system says "not yet" then).
bool has_thread_sequences(const FabricSpec& s);
/// The "not yet" message of a reader of one colour per system (`what`: e.g. "eval truth")
/// given a spec with sequences, naming the field; empty when it has none.
std::string thread_sequences_not_yet(const FabricSpec& s, const std::string& what);

struct SpecResult {
  FabricSpec spec;
  std::vector<std::string> errors;
  bool ok() const { return errors.empty(); }
};

/// Parse and validate a spec document. `quality_override` (if non-empty) replaces model.quality.
SpecResult parse_spec(const nlohmann::json& doc, const std::string& quality_override = "");
/// Parse text (JSON syntax errors become one error message with line/column).
SpecResult parse_spec_text(const std::string& text, const std::string& quality_override = "");
/// Read a file or a built-in preset name ("preset:plain", or a bare preset name).
SpecResult load_spec(const std::string& file_or_preset, const std::string& quality_override = "");
/// A spec from a WIF draft (wif.h) with `user` (a spec document, {} for none) laid over it;
/// `draft_name` names the draft in messages. load_spec takes a .wif file (or any file whose
/// first section is [WIF]) directly, and a JSON spec naming one as "weave": {"wif": path}.
SpecResult spec_with_draft(const nlohmann::json& user, const std::string& wif_text,
                           const std::string& draft_name, const std::string& quality_override = "");

/// The canonical form: every field present with its effective value, keys sorted. Its sha256
/// identifies the bake (same canonical spec => same atlas).
nlohmann::json canonical_spec(const FabricSpec& s);

/// Built-in presets (plain, twill, satin, basket); "default" is plain.
std::vector<std::string> preset_names();
nlohmann::json preset(const std::string& name);  ///< throws std::out_of_range on unknown name

/// Texels per weave cell (one warp x weft crossing) for a quality preset.
int texels_per_cell(Quality q);

/// Upper bound on the atlas's map resolution (per side) that we accept; larger is an error
/// (the maps, their mip chain and the work buffers must fit comfortably in memory).
inline constexpr int kMaxMapSide = 4096;
/// A custom weave repeat's yarns per system at most (a draft's repeat, wif.h); the maps' side
/// (kMaxMapSide) limits it further by quality.
inline constexpr int kMaxRepeatYarns = 1024;

}  // namespace loom
