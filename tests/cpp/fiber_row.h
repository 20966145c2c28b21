// A row of parallel straight fibers along x, periodic in y: the fiber-level truth's simplest
// scene (test_fiber_truth.cpp traces it independently in two dimensions; test_truth_error.cpp
// uses it for the truth's Monte Carlo error).
#pragma once
#include <array>
#include <cstdint>

#include "loom/fiber_region.h"

namespace loom::test {

struct Row {
  double r, period, yc;  // circles of radius r at (yc + k period, 0)
  std::array<double, 3> sigma;
  double ior;
};

/// The same row as fibers: straight curves along x, one per tile of width `period` in y.
inline loom::FiberCurves row_curves(const Row& row, double tile_x) {
  loom::FiberCurves c;
  c.first.push_back(0);
  for (int v = 0; v <= 20; ++v)
    c.points.insert(c.points.end(), {float(-tile_x + v * 3 * tile_x / 20), float(row.yc), 0.0f});
  c.first.push_back(uint32_t(c.vertices()));
  c.radius.push_back(float(row.r));
  c.hair.push_back(0), c.yarn.push_back(0), c.ply.push_back(0), c.fiber.push_back(0);
  c.first_k.push_back(0);
  return c;
}

}  // namespace loom::test
