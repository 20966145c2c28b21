// Values on loom-bake's command line: the hand-written string -> value parsers (numbers in a
// range, comma-separated lists, directions, the fiber region, the diffraction aperture, colours
// and ASG lobes). They live in loom_core so that unit tests (tests/cpp/test_cli_values.cpp) and a
// fuzzer (tests/fuzz/fuzz_cli_values.cpp) reach them; loom-bake (baker/tools/cli/) only calls them.
//
// Contract: every function returns a value within its documented range (every number finite
// unless stated otherwise) or throws CliValueError, whose what() is a one-line message naming the
// option (when one is given), what was expected and what was wrong; loom-bake prints it after
// "error: " and exits 2. Nothing else is thrown and nothing crashes, whatever the bytes
// (fuzz_cli_values checks this).
//
// Number syntax, the choices:
//   * decimal or scientific notation as std::from_chars reads it ("1", "-0.5", ".5", "2.", "1e-3"),
//     independent of the process's locale; one leading '+' is allowed; blanks (space, tab)
//     around a number are ignored, so "0, 0.5, 1" reads like "0,0.5,1";
//   * rejected: an empty item, trailing junk ("1x", "1e"), hexadecimal floats ("0x1p3"), "nan",
//     "inf" (the aperture alone takes "inf", "+inf" and "-inf" for an unbounded side), a value
//     beyond a double's range ("1e400") and one so small that it would round to zero
//     ("1e-400"; subnormal doubles such as "1e-310" are read);
//   * lists are separated by ',' and must have exactly the expected count;
//   * a message quotes at most 48 bytes of the input, control and non-ASCII bytes as \xNN.
#pragma once
#include <array>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace loom {

/// A command-line value that does not parse or is out of range; what() says why.
struct CliValueError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// One finite number (syntax above). `option` (e.g. "--waist") prefixes the message; empty:
/// no prefix (a CLI11 validator, which adds the option's name itself).
double parse_cli_number(std::string_view option, std::string_view text);

/// One finite number in [lo, hi].
double parse_cli_number_in(std::string_view option, std::string_view text, double lo, double hi);

/// Exactly `count` finite numbers separated by commas; `shape` (e.g. "X,Y,Z") names them in the
/// message.
std::vector<double> parse_cli_numbers(std::string_view option, std::string_view text,
                                      size_t count, std::string_view shape);

/// A direction X,Y,Z: three finite numbers, not all zero, returned scaled to unit length (any
/// finite components: tiny and huge ones are scaled before normalising, so "1e-300,0,0" and
/// "1e300,1e300,0" are directions like "1,0,0" and "1,1,0").
std::array<double, 3> parse_cli_direction(std::string_view option, std::string_view text);

/// A texture coordinate U,V: two finite numbers within a float's range (|x| <= 3.4e38; the
/// evaluators are float and wrap u, v into the repeat themselves).
std::array<double, 2> parse_cli_uv(std::string_view option, std::string_view text);

/// The fiber tier's region X0,Y0,X1,Y1 in um: finite, X0 < X1 and Y0 < Y1 (the fabric's own
/// extent is checked when the region is realized, loom/fiber_region.h).
std::array<double, 4> parse_cli_region(std::string_view option, std::string_view text);

/// A diffraction aperture XW,XE,YS,YN in um (loom::Aperture's order): XW <= XE, YS <= YN; XW and
/// YS may be -inf and XE and YN +inf (an unbounded side, written "inf", "+inf" or "-inf"); no
/// side is NaN, no west or south side +inf and no east or north side -inf (those are not
/// unbounded sides but empty apertures at infinity).
std::array<double, 4> parse_cli_aperture(std::string_view option, std::string_view text);

/// A scene-linear colour R,G,B, each in [0, 1].
std::array<double, 3> parse_cli_rgb01(std::string_view option, std::string_view text);

/// One ASG lobe THETA_Z,PHI_Z,PHI_XY,MU1,MU2,C (angles in radians): finite numbers within a
/// float's range (the lobe math is float), MU1, MU2 and C >= 0.
std::array<double, 6> parse_cli_asg_lobe(std::string_view option, std::string_view text);

}  // namespace loom
