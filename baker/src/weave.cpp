#include "loom/weave.h"

#include <algorithm>
#include <numeric>

namespace loom {

Weave make_weave(const WeaveSpec& w) {
  Weave out;
  if (w.pattern == "twill") {
    int n = w.up + w.down, d = w.direction == "Z" ? 1 : -1;
    out.m.assign(n, std::vector<int>(n, 0));
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) out.m[r][c] = (((c - d * r) % n + n) % n) < w.up ? 1 : 0;
  } else if (w.pattern == "satin") {
    int n = w.harness;
    out.m.assign(n, std::vector<int>(n, 1));
    for (int r = 0; r < n; ++r) out.m[r][(r * w.shift) % n] = 0;
  } else if (w.pattern == "basket") {
    int g = w.group, n = 2 * g;
    out.m.assign(n, std::vector<int>(n, 0));
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) out.m[r][c] = ((r / g) + (c / g)) % 2 == 0 ? 1 : 0;
  } else if (w.pattern == "custom") {
    out.m = w.matrix;
  } else {
    out.m = {{1, 0}, {0, 1}};
  }
  // Tiled to hold whole yarn sequences (WeaveSpec::tile_rows, tile_cols).
  const int R = out.rows(), C = out.cols();
  if (R == 0 || C == 0) return out;
  const int rows = std::min(std::lcm(R, std::max(w.tile_rows, 1)), kMaxRepeatYarns);
  const int cols = std::min(std::lcm(C, std::max(w.tile_cols, 1)), kMaxRepeatYarns);
  if (rows == R && cols == C) return out;
  Weave tiled;
  tiled.m.assign(size_t(rows), std::vector<int>(size_t(cols), 0));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) tiled.m[size_t(r)][size_t(c)] = out.at(r, c);
  return tiled;
}

}  // namespace loom
