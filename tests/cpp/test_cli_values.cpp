// loom-bake's command-line value parsers (baker/include/loom/cli_values.h): valid, boundary and
// broken inputs against literal expectations, and the command line itself for a few of them.
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <string>

#include "loom/cli_values.h"
#include "test_util.h"

namespace {

/// The message of the CliValueError that `f` throws ("" and a test failure if none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const loom::CliValueError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "not a CliValueError: " << e.what();
    return "";
  }
  ADD_FAILURE() << "no error";
  return "";
}

bool has(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

}  // namespace

TEST(CliValues, NumbersInEveryAcceptedSpelling) {
  struct Case {
    const char* text;
    double value;
  } cases[] = {{"1", 1},          {"-0.5", -0.5},       {".5", 0.5},
               {"2.", 2},         {"1e-3", 0.001},      {"1E3", 1000},
               {"+1", 1},         {"+.25", 0.25},       {" 1 ", 1},
               {"\t-2\t", -2},    {"0", 0},             {"1e-310", 1e-310},
               {"4.9406564584124654e-324", 4.9406564584124654e-324},
               {"1.7976931348623157e308", DBL_MAX}};
  for (const auto& c : cases) EXPECT_EQ(loom::parse_cli_number("--x", c.text), c.value) << c.text;
  EXPECT_TRUE(std::signbit(loom::parse_cli_number("--x", "-0")));
}

TEST(CliValues, BrokenNumbersAreRefusedWithTheReason) {
  struct Case {
    std::string text;
    const char* reason;
  } cases[] = {{"", "empty"},
               {"  ", "empty"},
               {"nan", "not a finite number"},
               {"NaN", "not a finite number"},
               {"-nan(1)", "not a finite number"},
               {"inf", "not a finite number"},
               {"-Infinity", "not a finite number"},
               {"1,2", "2 comma-separated items"},
               {",", "2 comma-separated items"},
               {"1x", "is not a number"},
               {"1e", "is not a number"},
               {"1 2", "is not a number"},
               {"0x1p3", "is not a number"},
               {"++1", "is not a number"},
               {"+-1", "is not a number"},
               {"+", "is not a number"},
               {"-", "is not a number"},
               {"1e400", "outside a double's range"},
               {"-1e400", "outside a double's range"},
               {"1e-400", "outside a double's range"},
               {"1e99999999999999999999", "outside a double's range"},
               {std::string("1\0", 2), "is not a number"}};
  for (const auto& c : cases) {
    const std::string e = error_of([&] { loom::parse_cli_number("--waist", c.text); });
    EXPECT_TRUE(has(e, "--waist: expected a finite number")) << e;
    EXPECT_TRUE(has(e, c.reason)) << c.text << ": " << e;
  }
}

TEST(CliValues, MessagesQuoteTheInputSafelyAndBriefly) {
  std::string e = error_of([] { loom::parse_cli_number("--x", std::string("a\n\x01\xff\"", 5)); });
  EXPECT_TRUE(has(e, R"("a\x0a\x01\xff\"")")) << e;
  e = error_of([] { loom::parse_cli_number("--x", std::string(5000, '7') + "q"); });
  EXPECT_TRUE(has(e, "... (5001 bytes)")) << e;
  EXPECT_LT(e.size(), 200u) << e;
  // Without an option name (a CLI11 validator, which names the option itself): no prefix.
  e = error_of([] { loom::parse_cli_number_in("", "7", 0, 1); });
  EXPECT_EQ(e.rfind("expected a finite number in [0, 1]", 0), 0u) << e;
}

TEST(CliValues, RangesIncludeTheirEndsOnly) {
  EXPECT_EQ(loom::parse_cli_number_in("--h", "-1", -1, 1), -1);
  EXPECT_EQ(loom::parse_cli_number_in("--h", "1", -1, 1), 1);
  EXPECT_EQ(loom::parse_cli_number_in("--waist", "1e-3", 1e-3, 1e6), 1e-3);
  // The neighbouring doubles outside the range.
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_number_in("--h", "1.0000000000000002", -1, 1); }),
                  "is outside"));
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_number_in("--h", "-1.0000000000000002", -1, 1); }),
                  "is outside"));
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_number_in("--h", "nan", -1, 1); }),
                  "not a finite number"));
}

TEST(CliValues, ListsHaveExactlyTheirCount) {
  EXPECT_EQ(loom::parse_cli_numbers("--q", "1, 2,3 ", 3, "A,B,C"),
            (std::vector<double>{1, 2, 3}));
  for (const char* bad : {"1,2", "1,2,3,4", "1,,3", "1,2,", ",1,2", ""}) {
    const std::string e = error_of([&] { loom::parse_cli_numbers("--q", bad, 3, "A,B,C"); });
    EXPECT_TRUE(has(e, "--q: expected A,B,C (3 finite numbers)")) << e;
  }
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_numbers("--q", "1,x,3", 3, "A,B,C"); }),
                  "item 2 of \"1,x,3\""));
}

TEST(CliValues, DirectionsAreUnitWhateverTheScale) {
  using A = std::array<double, 3>;
  const double r2 = 1 / std::sqrt(2.0), r3 = 1 / std::sqrt(3.0);
  struct Case {
    const char* text;
    A unit;
  } cases[] = {{"0,0,2", {0, 0, 1}},
               {"3,4,0", {0.6, 0.8, 0}},
               {"0,-1,-0", {0, -1, 0}},
               {"1e-300,0,0", {1, 0, 0}},
               {"5e-324,0,-5e-324", {r2, 0, -r2}},
               {"1e300,1e300,0", {r2, r2, 0}},
               {"1.7e308,-1.7e308,1.7e308", {r3, -r3, r3}},
               {" 0.1 , 0 , 1 ", {0.1 / std::hypot(0.1, 1.0), 0, 1 / std::hypot(0.1, 1.0)}}};
  for (const auto& c : cases) {
    const A d = loom::parse_cli_direction("--wo", c.text);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(d[k], c.unit[k], 1e-15) << c.text << " [" << k << "]";
    EXPECT_NEAR(std::hypot(d[0], d[1], d[2]), 1.0, 1e-15) << c.text;
  }
  for (const char* bad : {"0,0,0", "-0,0,0", "1,2", "1,2,3,4", "0,0,nan", "inf,0,0", "0,0,1e400",
                          "a,b,c"}) {
    const std::string e = error_of([&] { loom::parse_cli_direction("--wo", bad); });
    EXPECT_TRUE(has(e, "--wo: expected X,Y,Z (three finite numbers, not all zero)")) << e;
  }
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_direction("--wi", "0,0,0"); }), "zero vector"));
}

TEST(CliValues, UvRegionApertureColourAndLobe) {
  EXPECT_EQ(loom::parse_cli_uv("--uv", "0.3,-7"), (std::array<double, 2>{0.3, -7}));
  EXPECT_EQ(loom::parse_cli_uv("--uv", "-3.4e38,0")[0], -3.4e38);
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_uv("--uv", "1e39,0"); }), "float's range"));

  EXPECT_EQ(loom::parse_cli_region("--region", "0,0,300,300.5"),
            (std::array<double, 4>{0, 0, 300, 300.5}));
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_region("--region", "0,0,-1,5"); }),
                  "X0 0 is not below X1 -1"));
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_region("--region", "0,5,1,5"); }),
                  "Y0 5 is not below Y1 5"));
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_region("--region", "0,0,inf,1"); }),
                  "--region: expected X0,Y0,X1,Y1"));

  EXPECT_EQ(loom::parse_cli_aperture("--aperture", "0,10,-inf,5"),
            (std::array<double, 4>{0, 10, -INFINITY, 5}));
  EXPECT_EQ(loom::parse_cli_aperture("--aperture", "-inf,+inf,-inf,inf"),
            (std::array<double, 4>{-INFINITY, INFINITY, -INFINITY, INFINITY}));
  EXPECT_EQ(loom::parse_cli_aperture("--aperture", "1,1,2,2"), (std::array<double, 4>{1, 1, 2, 2}));
  for (const char* bad : {"5,0,0,1", "0,1,1,0", "0,1,0", "inf,inf,0,1", "0,1,0,-inf",
                          "0,1,nan,1", "0,1,0,1e400"}) {
    const std::string e = error_of([&] { loom::parse_cli_aperture("--aperture", bad); });
    EXPECT_TRUE(has(e, "--aperture: expected XW,XE,YS,YN")) << bad << ": " << e;
  }

  EXPECT_EQ(loom::parse_cli_rgb01("--rgb", "0,1,0.5"), (std::array<double, 3>{0, 1, 0.5}));
  for (const char* bad : {"1.5,0,0", "0,-0.001,0", "0,0,nan", "0,0"})
    EXPECT_TRUE(has(error_of([&] { loom::parse_cli_rgb01("--rgb", bad); }), "--rgb: expected R,G,B"))
        << bad;

  EXPECT_EQ(loom::parse_cli_asg_lobe("--lobe", "0.1,-2,3,0,1,2"),
            (std::array<double, 6>{0.1, -2, 3, 0, 1, 2}));
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_asg_lobe("--lobe", "0,0,0,-1,1,1"); }), ">= 0"));
  EXPECT_TRUE(has(error_of([] { loom::parse_cli_asg_lobe("--lobe", "0,0,0,1e39,1,1"); }),
                  "float's range"));
}

TEST(CliValues, LoomBakeUsesThemAndExitsTwo) {
  const std::string exe = loom::test::bake_exe();
  std::string out;
  // Directions whose squared length over- or underflows are directions (they used to give NaN
  // or "not all zero").
  EXPECT_EQ(loom::test::run(exe + " eval asg --lobe 0,0,0,1,1,1 --v 1e-40,0,1e-40", &out), 0)
      << out;
  EXPECT_EQ(loom::test::run(exe + " eval diffraction --aperture 0,10,-inf,5 --wi 1.7e308,0,1.7e308 "
                                  "--wo 0.2,0.05,-1",
                            &out),
            0)
      << out;
  EXPECT_FALSE(has(out, "null") || has(out, "nan")) << out;
  struct Case {
    const char* args;
    const char* message;
  } cases[] = {
      {"eval asg --lobe 0,0,0,1,1 --v 0,0,1", "error: --lobe: expected THETA_Z"},
      {"eval asg --lobe 0,0,0,1,1,1 --v 0,0,0", "error: --v: expected X,Y,Z"},
      {"eval diffraction --aperture 0,1,0,1 --wi 0,0,1 --wo 0,0,-1 --waist 0x10",
       "--waist: expected a finite number in"},
      {"eval diffraction --aperture 0,1,0,1 --wi 0,0,1 --wo 0,0,-1 --lambda 1e400",
       "outside a double's range"},
      {"eval diffraction --aperture inf,inf,0,1 --wi 0,0,1 --wo 0,0,-1",
       "error: --aperture: expected XW,XE,YS,YN"},
      {"fibers --spec plain --region 0,0,1e400,5 --out /nonexistent/x",
       "error: --region: expected X0,Y0,X1,Y1"}};
  for (const auto& c : cases) {
    EXPECT_EQ(loom::test::run(exe + " " + c.args + " 2>&1", &out), 2) << c.args << ": " << out;
    EXPECT_TRUE(has(out, c.message)) << c.args << ": " << out;
  }
}
