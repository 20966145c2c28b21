// A small simulation of the default yarn's ply (3000 rays per slice, 24 x 48 outgoing bins,
// absorption levels 0, 30, 300 per mm), shared by the tests that build on ply scattering.
#pragma once
#include "loom/ply_scattering.h"

namespace loom::test {

inline PlySimResult small_ply_sim(int theta_i_count, int h_count) {
  YarnSpec y;
  auto p = ply_params_from_yarn(y);
  PlySimSettings s;
  s.theta_i_count = theta_i_count, s.h_count = h_count, s.theta_o_count = 24, s.phi_o_count = 48;
  s.rays_per_slice = 3000;
  s.sigmas = {0, 30, 300};
  return simulate_ply_scattering(p, y.ior, s);
}

}  // namespace loom::test
