// A check shared by the fit and atlas tests: interpolated lobes (S.7) move continuously and
// never sweep round the ply between two fitting-block corners.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "loom/asg_fit.h"
#include "loom/shading.h"

namespace loom::test {

inline void expect_no_sweeping_lobes(const loom::AsgTable& t) {
  namespace sh = loom::shading;
  const int L = t.lobes;
  // No lobe sweeps round the ply between two corners: along every block edge the path of each
  // lobe's centre is at most about the turn its angles may make (pi in phi_z, plus theta_z), and
  // its x axis turns by at most a few quarter turns.
  for (int axis = 0; axis < 2; ++axis)
    for (size_t e = 0; e + 2 < (axis == 0 ? t.theta_i.size() : t.h.size()); e += 2) {
      const double other = axis == 0 ? t.h[1] : t.theta_i[1];
      const auto& g = axis == 0 ? t.theta_i : t.h;
      std::vector<sh::vec3> prev, prev_x;
      std::vector<double> path(size_t(L), 0.0), path_x(size_t(L), 0.0);
      for (int i = 0; i <= 64; ++i) {
        const double x = g[e] + (g[e + 2] - g[e]) * i / 64;
        auto lobes = axis == 0 ? loom::asg_table_lobes(t, x, other, 0)
                               : loom::asg_table_lobes(t, other, x, 0);
        for (int l = 0; l < L; ++l) {
          sh::vec3 ax, ay, az;
          sh::asg_frame(float(lobes[size_t(l)].theta_z), float(lobes[size_t(l)].phi_z),
                        float(lobes[size_t(l)].phi_xy), ax, ay, az);
          if (i > 0) {
            path[size_t(l)] +=
                std::acos(std::clamp(double(sh::dot(az, prev[size_t(l)])), -1.0, 1.0));
            path_x[size_t(l)] +=
                std::acos(std::clamp(double(sh::dot(ax, prev_x[size_t(l)])), -1.0, 1.0));
          }
          if (prev.size() < size_t(L)) prev.resize(size_t(L)), prev_x.resize(size_t(L));
          prev[size_t(l)] = az;
          prev_x[size_t(l)] = ax;
        }
      }
      for (int l = 0; l < L; ++l) {
        EXPECT_LT(path[size_t(l)], 1.5 * M_PI) << "axis " << axis << " edge " << e << " lobe " << l;
        // ... nor spins its anisotropy axes (phi_xy within pi/2, plus what the centre turns).
        EXPECT_LT(path_x[size_t(l)], 2 * M_PI) << "axis " << axis << " edge " << e << " lobe " << l;
      }
    }
}

}  // namespace loom::test
