// Weaving drafts: the Weaving Information File (WIF 1.1, the format handweaving draft libraries
// publish) read into a draft, and the draft turned into Loom's interlacing matrix and spec.
//
// What is read: [WEAVING] Shafts, Treadles, Rising Shed; [WARP] / [WEFT] Threads, Color (the
// default palette index), Units (centimeters, inches, decipoints; centimeters when absent),
// Spacing and Thickness; [THREADING] (warp thread = shafts), [TIEUP] (treadle = shafts),
// [TREADLING] (pick = treadles) or [LIFTPLAN] (pick = shafts) instead of the last two;
// [COLOR PALETTE] Range (0,255 when absent), [COLOR TABLE] (index = r,g,b in that range),
// [WARP COLORS] / [WEFT COLORS] (thread = index). Keys and section names are case-insensitive,
// sections come in any order, ';' starts a comment, CRLF line ends are read as LF. A thread
// with no shaft (absent, empty or 0) never moves (under every pick with a rising shed, over
// every pick with a sinking one: refused as not interlacing); a value lists several shafts or
// treadles separated by commas. Other sections ([TEXT], [NOTES], per-thread spacing and
// thickness, ...) are ignored, whatever they hold.
//
// The interlacing (wif_interlacing): at pick j the shafts of its treadles' tie-ups (or of its
// lift-plan line) move; with a rising shed warp thread i lies over pick j when one of its shafts
// rises, with a sinking shed when none of its shafts sinks.
#pragma once
#include <array>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace loom {

/// A draft as read (indices 1-based as in the file; 0 entries dropped).
struct WifDraft {
  int shafts = 0, treadles = 0;
  bool rising_shed = true;
  int warp_threads = 0, weft_threads = 0;
  std::vector<std::vector<int>> threading;  ///< per warp thread: its shafts
  std::vector<std::vector<int>> tieup;      ///< per treadle: the shafts it moves
  std::vector<std::vector<int>> treadling;  ///< per pick: its treadles (empty with a lift plan)
  std::vector<std::vector<int>> liftplan;   ///< per pick: the shafts that move
  bool has_liftplan = false;
  /// Per thread: its colour as sRGB in [0, 1] (the palette's range mapped), or none (empty
  /// draft colours: the thread has no colour in the draft).
  std::vector<std::vector<double>> warp_colour, weft_colour;
  /// Spacing (centre to centre) and thickness in cm, 0 when the draft leaves them open; the
  /// line each came from (for messages).
  double warp_spacing_cm = 0, weft_spacing_cm = 0, warp_thickness_cm = 0, weft_thickness_cm = 0;
  int warp_spacing_line = 0, weft_spacing_line = 0, warp_thickness_line = 0,
      weft_thickness_line = 0;
};

struct WifResult {
  WifDraft draft;
  std::vector<std::string> errors;  ///< "NAME line N [SECTION]: ..." each
  bool ok() const { return errors.empty(); }
};

/// Limits: shafts and treadles in [1, 256], threads per system in [1, 16384], crossings (warp
/// threads x picks) at most 2^24.
inline constexpr int kWifMaxShafts = 256, kWifMaxThreads = 16384, kWifMaxCells = 1 << 24;

/// Reads a draft; `name` prefixes every message (e.g. the file name).
WifResult parse_wif(const std::string& text, const std::string& name);

/// True when text looks like a WIF file (its first section is [WIF]).
bool looks_like_wif(const std::string& text);

/// M[i][j] = 1 where warp thread i + 1 lies over pick j + 1 (rows = warp threads, as
/// WeaveSpec::matrix).
std::vector<std::vector<int>> wif_interlacing(const WifDraft& d);

/// The smallest repeat of a periodic matrix: the smallest row and column periods that divide
/// its size and under which it repeats.
std::vector<std::vector<int>> smallest_repeat(const std::vector<std::vector<int>>& m);

/// A spec document (loom.fabric/1) of the draft: weave.pattern "custom" with the smallest
/// repeat of its interlacing, the densities from Spacing, yarn diameters from Thickness (the
/// plies scaled with them in merge_draft_spec), a system of one colour its colour, one of
/// several a "sequence" of yarn types (one per distinct colour: "color_1", ...). Errors
/// (threads that never interlace) go to `errors`.
struct WifSpec {
  nlohmann::json doc;
};
WifSpec wif_spec(const WifDraft& d, const std::string& name, std::vector<std::string>& errors);

/// A spec document `user` (e.g. one naming the draft: "weave": {"wif": path}; {} for a draft
/// baked as it is) laid over the draft's: the user's fields win (a "yarn" field over the draft's
/// warp and weft ones), the draft's weave replaces the reference; a yarn diameter the draft gives
/// scales that system's ply diameter by `ply_per_yarn` unless the spec sets one; a colour the
/// spec gives a system replaces the draft's sequence there (yarn types no sequence uses are
/// dropped); "yarn_types" and "density" merge by name.
nlohmann::json merge_draft_spec(const nlohmann::json& user, const WifSpec& draft,
                                double ply_per_yarn, std::vector<std::string>& errors);

}  // namespace loom
