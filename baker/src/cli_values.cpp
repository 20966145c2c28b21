#include "loom/cli_values.h"

#include <fmt/format.h>

#include <algorithm>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <optional>
#include <system_error>

namespace loom {

namespace {

constexpr size_t kQuoteBytes = 48;

/// `s` in double quotes for a message: printable ASCII as it is (quote and backslash escaped),
/// every other byte as \xNN, at most kQuoteBytes of it.
std::string quote(std::string_view s) {
  std::string out = "\"";
  for (size_t i = 0; i < std::min(s.size(), kQuoteBytes); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c == '"' || c == '\\')
      out += '\\', out += char(c);
    else if (c >= 0x20 && c < 0x7f)
      out += char(c);
    else
      out += fmt::format("\\x{:02x}", c);
  }
  out += '"';
  if (s.size() > kQuoteBytes) out += fmt::format("... ({} bytes)", s.size());
  return out;
}

[[noreturn]] void fail(std::string_view option, std::string_view expected, const std::string& why) {
  std::string msg;
  if (!option.empty()) msg = fmt::format("{}: ", option);
  msg += fmt::format("expected {}; {}", expected, why);
  throw CliValueError(msg);
}

std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

/// One number (syntax in cli_values.h); `allow_inf`: +-infinity too. Empty optional and `why`
/// set when it is not one.
std::optional<double> number(std::string_view item, bool allow_inf, std::string& why) {
  const std::string_view tok = trim(item);
  if (tok.empty()) {
    why = "an item is empty";
    return std::nullopt;
  }
  std::string_view digits = tok;
  // One leading '+' (std::from_chars takes none), before a digit, a point or "inf" only.
  if (digits.size() > 1 && digits[0] == '+' && digits[1] != '+' && digits[1] != '-')
    digits.remove_prefix(1);
  double v = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v,
                                         std::chars_format::general);
  if (ec == std::errc::result_out_of_range) {
    why = fmt::format("{} is outside a double's range (above 1.8e308, or so small it rounds to "
                      "zero)",
                      quote(tok));
    return std::nullopt;
  }
  if (ec != std::errc() || end != digits.data() + digits.size()) {
    why = fmt::format("{} is not a number", quote(tok));
    return std::nullopt;
  }
  if (std::isnan(v) || (std::isinf(v) && !allow_inf)) {
    why = fmt::format("{} is not a finite number", quote(tok));
    return std::nullopt;
  }
  return v;
}

/// Exactly `count` numbers separated by commas, or fail().
std::vector<double> numbers(std::string_view option, std::string_view text, size_t count,
                            std::string_view expected, bool allow_inf) {
  std::vector<std::string_view> items;
  for (size_t pos = 0;;) {
    const size_t comma = text.find(',', pos);
    items.push_back(text.substr(pos, comma == std::string_view::npos ? comma : comma - pos));
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  if (items.size() != count)
    fail(option, expected,
         fmt::format("{} has {} comma-separated item{}", quote(text), items.size(),
                     items.size() == 1 ? "" : "s"));
  std::vector<double> out;
  out.reserve(count);
  for (size_t k = 0; k < items.size(); ++k) {
    std::string why;
    const auto v = number(items[k], allow_inf, why);
    if (!v)
      fail(option, expected,
           count == 1 ? why : fmt::format("item {} of {}: {}", k + 1, quote(text), why));
    out.push_back(*v);
  }
  return out;
}

template <size_t N>
std::array<double, N> to_array(const std::vector<double>& v) {
  std::array<double, N> a{};
  std::copy_n(v.begin(), N, a.begin());
  return a;
}

}  // namespace

double parse_cli_number(std::string_view option, std::string_view text) {
  return numbers(option, text, 1, "a finite number", false)[0];
}

double parse_cli_number_in(std::string_view option, std::string_view text, double lo, double hi) {
  const std::string expected = fmt::format("a finite number in [{}, {}]", lo, hi);
  const double v = numbers(option, text, 1, expected, false)[0];
  if (!(v >= lo && v <= hi)) fail(option, expected, fmt::format("{} is outside", quote(text)));
  return v;
}

std::vector<double> parse_cli_numbers(std::string_view option, std::string_view text,
                                      size_t count, std::string_view shape) {
  return numbers(option, text, count,
                 fmt::format("{} ({} finite number{})", shape, count, count == 1 ? "" : "s"),
                 false);
}

std::array<double, 3> parse_cli_direction(std::string_view option, std::string_view text) {
  constexpr std::string_view expected = "X,Y,Z (three finite numbers, not all zero)";
  auto d = to_array<3>(numbers(option, text, 3, expected, false));
  const double m = std::max({std::fabs(d[0]), std::fabs(d[1]), std::fabs(d[2])});
  if (!(m > 0)) fail(option, expected, fmt::format("{} is the zero vector", quote(text)));
  double n = std::hypot(d[0], d[1], d[2]);
  // The common case divides by the length directly (as loom-bake always did); lengths that
  // overflow or fall below the normal doubles are taken after scaling by the largest component.
  if (!(std::isfinite(n) && n >= DBL_MIN)) {
    for (double& c : d) c /= m;
    n = std::hypot(d[0], d[1], d[2]);
  }
  for (double& c : d) c /= n;
  return d;
}

std::array<double, 2> parse_cli_uv(std::string_view option, std::string_view text) {
  constexpr std::string_view expected = "U,V (two finite numbers)";
  const auto uv = to_array<2>(numbers(option, text, 2, expected, false));
  for (double x : uv)
    if (std::fabs(x) > double(FLT_MAX))
      fail(option, expected,
           fmt::format("{}: {} is beyond a float's range (3.4e38)", quote(text), x));
  return uv;
}

std::array<double, 4> parse_cli_region(std::string_view option, std::string_view text) {
  constexpr std::string_view expected =
      "X0,Y0,X1,Y1 (four finite numbers, um, X0 < X1 and Y0 < Y1)";
  const auto r = to_array<4>(numbers(option, text, 4, expected, false));
  if (!(r[0] < r[2])) fail(option, expected, fmt::format("X0 {} is not below X1 {}", r[0], r[2]));
  if (!(r[1] < r[3])) fail(option, expected, fmt::format("Y0 {} is not below Y1 {}", r[1], r[3]));
  return r;
}

std::array<double, 4> parse_cli_aperture(std::string_view option, std::string_view text) {
  constexpr std::string_view expected =
      "XW,XE,YS,YN in um with XW <= XE and YS <= YN (numbers, or inf / -inf for an unbounded "
      "side)";
  const auto a = to_array<4>(numbers(option, text, 4, expected, true));
  if (a[0] == INFINITY || a[2] == INFINITY)
    fail(option, expected, "a west or south side is +inf (only -inf leaves it unbounded)");
  if (a[1] == -INFINITY || a[3] == -INFINITY)
    fail(option, expected, "an east or north side is -inf (only +inf leaves it unbounded)");
  if (!(a[0] <= a[1])) fail(option, expected, fmt::format("XW {} is above XE {}", a[0], a[1]));
  if (!(a[2] <= a[3])) fail(option, expected, fmt::format("YS {} is above YN {}", a[2], a[3]));
  return a;
}

std::array<double, 3> parse_cli_rgb01(std::string_view option, std::string_view text) {
  constexpr std::string_view expected = "R,G,B, three numbers in [0, 1] (scene-linear)";
  const auto rgb = to_array<3>(numbers(option, text, 3, expected, false));
  for (double c : rgb)
    if (!(c >= 0 && c <= 1)) fail(option, expected, fmt::format("{} is outside [0, 1]", c));
  return rgb;
}

std::array<double, 6> parse_cli_asg_lobe(std::string_view option, std::string_view text) {
  constexpr std::string_view expected =
      "THETA_Z,PHI_Z,PHI_XY,MU1,MU2,C (six finite numbers, MU1, MU2 and C >= 0)";
  const auto q = to_array<6>(numbers(option, text, 6, expected, false));
  for (double x : q)
    if (std::fabs(x) > double(FLT_MAX))
      fail(option, expected, fmt::format("{} is beyond a float's range (3.4e38)", x));
  if (q[3] < 0 || q[4] < 0 || q[5] < 0)
    fail(option, expected, "MU1, MU2 and C must be >= 0");
  return q;
}

}  // namespace loom
