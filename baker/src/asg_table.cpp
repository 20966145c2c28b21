// Reading a fitted lobe table (asg_fit.h): the lobes at a ply-space view by S.5-S.7 and
// S.10-S.11, and the scattering density they sum to (S.1, S.8, S.12).
#include "loom/asg_fit.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "loom/shading.h"

namespace loom {

namespace sh = shading;

std::array<double, 4> asg_corner_weights(double r, double s) {
  return {(1 - r) * (1 - s), (1 - r) * s, r * (1 - s), r * s};
}

std::vector<AsgLobe> asg_table_lobes(const AsgTable& t, double theta_i, double h, double sigma) {
  const int L = t.lobes;
  auto locate = [](const std::vector<double>& grid, double x, int& block, double& frac) {
    const int n = int(grid.size());
    double u = (std::clamp(x, grid.front(), grid.back()) - grid.front()) /
               (grid.back() - grid.front()) * (n - 1);
    if (!std::isfinite(u)) u = 0;
    block = std::clamp(int(std::floor(u / 2)), 0, (n - 1) / 2 - 1);
    frac = std::clamp((u - 2 * block) / 2, 0.0, 1.0);  // S.6
  };
  int bm, bn;
  double r, s;
  locate(t.theta_i, theta_i, bm, r);
  locate(t.h, h, bn, s);
  // S.10: the absorption interval.
  const int K = int(t.sigmas.size());
  int k = 0;
  double tt = 0;
  sigma_interval(t.sigmas, sigma, t.absorption, k, tt);
  const int cols = t.node_cols(), U = t.node_rows() * cols * L;
  const int corner[4] = {bm * cols + bn, bm * cols + bn + 1, (bm + 1) * cols + bn,
                         (bm + 1) * cols + bn + 1};
  auto w = asg_corner_weights(r, s);
  std::vector<AsgLobe> out(static_cast<size_t>(L));
  for (int l = 0; l < L; ++l) {
    const AsgLobe* c[4] = {&t.node(bm, bn, l), &t.node(bm, bn + 1, l), &t.node(bm + 1, bn, l),
                           &t.node(bm + 1, bn + 1, l)};
    AsgLobe q{0, 0, 0, 0, 0, 0};
    for (int i = 0; i < 4; ++i) {  // S.7
      q.theta_z += w[size_t(i)] * c[i]->theta_z;
      q.phi_z += w[size_t(i)] * c[i]->phi_z;
      q.phi_xy += w[size_t(i)] * c[i]->phi_xy;
      q.mu1 += w[size_t(i)] * c[i]->mu1;
      q.mu2 += w[size_t(i)] * c[i]->mu2;
      q.c += w[size_t(i)] * c[i]->c;
    }
    double scale = 1;
    if (K > 1) {  // S.11 at the corners, then S.7's weights
      scale = 0;
      for (int i = 0; i < 4; ++i)
        scale += w[size_t(i)] * ((1 - tt) * t.scale[size_t(k * U + corner[i] * L + l)] +
                                 tt * t.scale[size_t((k + 1) * U + corner[i] * L + l)]);
    }
    q.c *= scale;
    out[size_t(l)] = q;
  }
  return out;
}

double asg_mixture_eval(const std::vector<AsgLobe>& lobes, const Vec3d& wo) {
  sh::vec3 v(float(wo.x), float(wo.y), float(wo.z));
  double s = 0;
  for (const AsgLobe& q : lobes)
    s += sh::asg_eval(float(q.theta_z), float(q.phi_z), float(q.phi_xy), float(q.mu1),
                      float(q.mu2), float(q.c), v);
  return s;
}

double asg_table_eval(const AsgTable& t, double theta_i, double h, double sigma, const Vec3d& wo) {
  return asg_mixture_eval(asg_table_lobes(t, theta_i, h, sigma), wo);  // S.8, S.12
}

}  // namespace loom
