// Internal to the ASG fit (asg_fit.cpp): the outgoing directions it fits on and the simulated
// data there (S.4's bins).
#ifndef LOOM_SRC_ASG_FIT_GRID_H
#define LOOM_SRC_ASG_FIT_GRID_H

#include <cstddef>
#include <vector>

#include "loom/ply_scattering.h"
#include "loom/shading.h"

namespace loom {

/// The outgoing directions the fit uses (the simulation's bins, pooled when fine), with their
/// solid angles, and the data of every slice and level on them.
struct FitGrid {
  int rows = 0, cols = 0;
  std::vector<shading::vec3> dir;
  std::vector<double> weight;  // solid angle
  // values[(slice * K + k) * bins + b]
  std::vector<double> values;
  int K = 1;
  size_t bins() const { return dir.size(); }
  const double* slice(size_t s, int k) const { return &values[(s * size_t(K) + size_t(k)) * bins()]; }
};

/// The simulation's (theta_o, phi_o) bins, pooled 2 x 2 when finer than 32 rows, with the f_high
/// (all absorption levels) or, for refl, the f_refl data averaged over each pooled bin.
FitGrid make_grid(const PlySimResult& sim, bool refl);

}  // namespace loom

#endif  // LOOM_SRC_ASG_FIT_GRID_H
