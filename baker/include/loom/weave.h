// Weave topology: the interlacing matrix of one weave repeat.
#pragma once
#include <vector>

#include "loom/spec.h"

namespace loom {

/// M[r][c] = 1 where warp yarn r lies over weft yarn c, 0 where the weft is on top.
/// Warp yarns run along x (the texture's u) and are stacked along y; weft yarns run along y.
struct Weave {
  std::vector<std::vector<int>> m;
  int rows() const { return static_cast<int>(m.size()); }           ///< warp yarns in a repeat
  int cols() const { return m.empty() ? 0 : static_cast<int>(m[0].size()); }  ///< weft yarns
  int at(int r, int c) const {  ///< periodic access
    int R = rows(), C = cols();
    return m[((r % R) + R) % R][((c % C) + C) % C];
  }
};

/// Builds the repeat of a weave spec:
///  plain   M = [[1,0],[0,1]]
///  twill   period n = up+down; warp r is over weft c when (c - d r) mod n < up, d = +1 for a
///          Z twill (diagonal rising to the right), -1 for S
///  satin   warp-faced, harness n, shift s: warp r is under weft c only where c = r s mod n
///  basket  plain weave of groups of g yarns side by side
///  custom  the spec's matrix
/// tiled to hold whole yarn sequences (w.tile_rows, w.tile_cols: the least common multiples).
Weave make_weave(const WeaveSpec& w);

}  // namespace loom
