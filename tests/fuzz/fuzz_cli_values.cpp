// libFuzzer target: loom-bake's command-line value parsers (baker/include/loom/cli_values.h) on
// arbitrary bytes, each input given to every parser.
//
// Properties beyond "no crash, no sanitizer report": a parser either returns a value within its
// documented range (finite numbers, unit directions, ordered regions and apertures, colours in
// [0, 1], lobes with MU1, MU2, C >= 0 in a float's range) or throws CliValueError whose message
// starts with the option's name and says what was expected; any other exception escapes and is
// reported as a crash. An accepted number printed in its shortest form (what loom-bake's
// finite_range validator hands CLI11) parses back to the same double.
//
//   build-fuzz/fuzz_cli_values tests/fuzz/corpus/cli_values -max_total_time=60   (scripts/fuzz.sh)
#include <fmt/format.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

#include "loom/cli_values.h"

namespace {

void check(bool ok) {
  if (!ok) std::abort();
}

/// Runs one parser: its value goes to `good` (which checks the range), its CliValueError's
/// message is checked; anything else propagates (a crash for libFuzzer).
template <class Parse, class Good>
void one(const char* option, Parse&& parse, Good&& good) {
  try {
    good(parse(option));
  } catch (const loom::CliValueError& e) {
    const std::string_view msg = e.what();
    const std::string prefix = std::string(option) + ": expected ";
    check(msg.substr(0, prefix.size()) == prefix && msg.size() > prefix.size() + 8);
  }
}

bool fin(double x) { return std::isfinite(x); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const size_t count = 1 + size % 6;
  static const double ranges[][2] = {{-1, 1}, {1e-3, 1e6}, {0, 1e6}, {-90, 90}};
  const double lo = ranges[size % 4][0], hi = ranges[size % 4][1];

  one("--n", [&](const char* o) { return loom::parse_cli_number(o, text); },
      [](double v) { check(fin(v)); });
  one("--r", [&](const char* o) { return loom::parse_cli_number_in(o, text, lo, hi); },
      [&](double v) {
        check(v >= lo && v <= hi);
        // The validator's round trip: shortest form, parsed again, the same double.
        const double back = loom::parse_cli_number("--r", fmt::format("{}", v));
        check(std::memcmp(&back, &v, sizeof v) == 0);
      });
  one("--list", [&](const char* o) { return loom::parse_cli_numbers(o, text, count, "A,B"); },
      [&](const std::vector<double>& v) {
        check(v.size() == count);
        for (double x : v) check(fin(x));
      });
  one("--wo", [&](const char* o) { return loom::parse_cli_direction(o, text); },
      [](const std::array<double, 3>& d) {
        for (double x : d) check(fin(x));
        check(std::fabs(std::hypot(d[0], d[1], d[2]) - 1) < 1e-14);
      });
  one("--uv", [&](const char* o) { return loom::parse_cli_uv(o, text); },
      [](const std::array<double, 2>& uv) {
        for (double x : uv) check(fin(x) && std::fabs(x) <= double(FLT_MAX));
      });
  one("--region", [&](const char* o) { return loom::parse_cli_region(o, text); },
      [](const std::array<double, 4>& r) {
        for (double x : r) check(fin(x));
        check(r[0] < r[2] && r[1] < r[3]);
      });
  one("--aperture", [&](const char* o) { return loom::parse_cli_aperture(o, text); },
      [](const std::array<double, 4>& a) {
        for (double x : a) check(!std::isnan(x));
        check(a[0] <= a[1] && a[2] <= a[3]);
        check(a[0] != INFINITY && a[2] != INFINITY && a[1] != -INFINITY && a[3] != -INFINITY);
      });
  one("--rgb", [&](const char* o) { return loom::parse_cli_rgb01(o, text); },
      [](const std::array<double, 3>& c) {
        for (double x : c) check(x >= 0 && x <= 1);
      });
  one("--lobe", [&](const char* o) { return loom::parse_cli_asg_lobe(o, text); },
      [](const std::array<double, 6>& q) {
        for (double x : q) check(fin(x) && std::fabs(x) <= double(FLT_MAX));
        check(q[3] >= 0 && q[4] >= 0 && q[5] >= 0);
      });
  return 0;
}
