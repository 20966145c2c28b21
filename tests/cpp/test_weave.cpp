// Weave topology from the spec's patterns.
#include <gtest/gtest.h>

#include "loom/weave.h"

namespace {
loom::WeaveSpec ws(const std::string& p) {
  loom::WeaveSpec w;
  w.pattern = p;
  return w;
}
}  // namespace

TEST(Weave, PlainAlternates) {
  auto w = loom::make_weave(ws("plain"));
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      EXPECT_NE(w.at(r, c), w.at(r, c + 1));
      EXPECT_NE(w.at(r, c), w.at(r + 1, c));
    }
}

TEST(Weave, TwillStepsDiagonallyWithItsFloats) {
  for (auto dir : {"S", "Z"})
    for (auto [up, down] : {std::pair{2, 1}, std::pair{2, 2}, std::pair{3, 1}, std::pair{1, 3}}) {
      auto s = ws("twill");
      s.up = up, s.down = down, s.direction = dir;
      auto w = loom::make_weave(s);
      int n = up + down, d = std::string(dir) == "Z" ? 1 : -1;
      ASSERT_EQ(w.rows(), n);
      for (int r = 0; r < n; ++r) {
        for (int c = 0; c < n; ++c) EXPECT_EQ(w.at(r + 1, c + d), w.at(r, c));  // diagonal step
        // each row: one float of `up` ones and one of `down` zeros, cyclically
        int ones = 0, runs = 0;
        for (int c = 0; c < n; ++c) {
          ones += w.at(r, c);
          runs += w.at(r, c) != w.at(r, c + 1);
        }
        EXPECT_EQ(ones, up);
        EXPECT_EQ(runs, 2);
      }
    }
}

TEST(Weave, SatinHasNoAdjacentInterlacings) {
  for (auto [h, s] : {std::pair{5, 2}, std::pair{5, 3}, std::pair{8, 3}, std::pair{7, 2}}) {
    auto spec = ws("satin");
    spec.harness = h, spec.shift = s;
    auto w = loom::make_weave(spec);
    for (int r = 0; r < h; ++r) {
      int zeros = 0;
      for (int c = 0; c < h; ++c) {
        zeros += w.at(r, c) == 0;
        if (w.at(r, c) == 0)
          for (int dr = -1; dr <= 1; ++dr)
            for (int dc = -1; dc <= 1; ++dc) {
              if (dr || dc) {
                EXPECT_EQ(w.at(r + dr, c + dc), 1) << h << "/" << s;
              }
            }
      }
      EXPECT_EQ(zeros, 1);  // a float of h-1
    }
  }
}

TEST(Weave, BasketGroupsAndCustom) {
  auto b = ws("basket");
  b.group = 3;
  auto w = loom::make_weave(b);
  ASSERT_EQ(w.rows(), 6);
  EXPECT_EQ(w.at(0, 0), w.at(2, 2));
  EXPECT_NE(w.at(0, 0), w.at(0, 3));
  auto c = ws("custom");
  c.matrix = {{1, 1, 0}, {0, 1, 1}};
  auto wc = loom::make_weave(c);
  EXPECT_EQ(wc.rows(), 2);
  EXPECT_EQ(wc.cols(), 3);
  EXPECT_EQ(wc.at(1, 3), 0);  // periodic
}
