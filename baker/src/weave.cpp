#include "loom/weave.h"

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
  return out;
}

}  // namespace loom
