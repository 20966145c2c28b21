#include "asg_fit_grid.h"

namespace loom {

namespace sh = shading;

FitGrid make_grid(const PlySimResult& sim, bool refl) {
  const PlySimSettings& st = sim.settings;
  const int pool = st.theta_o_count > 32 ? 2 : 1;
  FitGrid g;
  g.rows = st.theta_o_count / pool;
  g.cols = st.phi_o_count / pool;
  g.K = refl ? 1 : int(st.sigmas.size());
  for (int r = 0; r < g.rows; ++r)
    for (int c = 0; c < g.cols; ++c) {
      double w = 0;
      Vec3d d{0, 0, 0};
      for (int a = 0; a < pool; ++a)
        for (int b = 0; b < pool; ++b) {
          int t = r * pool + a, p = c * pool + b;
          double om = ply_sim_bin_solid_angle(st, t);
          Vec3d v = ply_sim_bin_direction(st, t, p);
          w += om;
          d = {d.x + om * v.x, d.y + om * v.y, d.z + om * v.z};
        }
      g.dir.push_back(sh::normalize(sh::vec3(float(d.x), float(d.y), float(d.z))));
      g.weight.push_back(w);
    }
  const size_t fine = size_t(st.theta_o_count) * size_t(st.phi_o_count);
  g.values.assign(sim.slices.size() * size_t(g.K) * g.bins(), 0.0);
  for (size_t s = 0; s < sim.slices.size(); ++s)
    for (int k = 0; k < g.K; ++k) {
      const float* src = refl ? sim.slices[s].refl.data() : &sim.slices[s].high[size_t(k) * fine];
      double* dst = &g.values[(s * size_t(g.K) + size_t(k)) * g.bins()];
      for (int r = 0; r < g.rows; ++r)
        for (int c = 0; c < g.cols; ++c) {
          double sum = 0, w = 0;
          for (int a = 0; a < pool; ++a)
            for (int b = 0; b < pool; ++b) {
              int t = r * pool + a, p = c * pool + b;
              double om = ply_sim_bin_solid_angle(st, t);
              sum += om * src[size_t(t) * size_t(st.phi_o_count) + size_t(p)];
              w += om;
            }
          dst[size_t(r) * size_t(g.cols) + size_t(c)] = sum / w;
        }
    }
  return g;
}

}  // namespace loom
