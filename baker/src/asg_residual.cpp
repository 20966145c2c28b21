#include "loom/asg_residual.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "loom/shading.h"

namespace loom {

namespace {
constexpr int kFractionSteps = 2048;  // midpoint nodes in the disk's polar angle

/// Integral of exp(-k rho^2) rho d rho over [r0, r1] (closed form, no cancellation for small k).
double radial(double k, double r0, double r1) {
  if (!(k > 1e-12)) return 0.5 * (r1 * r1 - r0 * r0);
  return 0.5 * std::exp(-k * r0 * r0) * -std::expm1(-k * (r1 * r1 - r0 * r0)) / k;
}
}  // namespace

double asg_side_fraction(const AsgLobe& q, const Vec3d& n, int steps) {
  shading::vec3 x, y, z;
  shading::asg_frame(float(q.theta_z), float(q.phi_z), float(q.phi_xy), x, y, z);
  const double m1 = std::clamp(q.mu1, 0.0, double(LOOM_ASG_MU_MAX));
  const double m2 = std::clamp(q.mu2, 0.0, double(LOOM_ASG_MU_MAX));
  const double xn = x.x * n.x + x.y * n.y + x.z * n.z, yn = y.x * n.x + y.y * n.y + y.z * n.z,
               qz = z.x * n.x + z.y * n.y + z.z * n.z;
  steps = std::max(steps, 8);
  double all = 0, side = 0;
  for (int i = 0; i < steps; ++i) {
    // On the ray (a, b) = rho (cos psi, sin psi) of the disk, v = a x + b y + sqrt(1 - rho^2) z
    // and the integrand is exp(-k rho^2) rho, k = mu1 cos^2 + mu2 sin^2 (asg.h).
    const double psi = (i + 0.5) * 2 * M_PI / steps, c = std::cos(psi), sn = std::sin(psi);
    const double k = m1 * c * c + m2 * sn * sn;
    const double full = radial(k, 0, 1);
    all += full;
    // v.n = rho p + sqrt(1 - rho^2) qz changes sign at most once on [0, 1], at
    // rho* = |qz| / hypot(p, qz): the part on the side is an interval, integrated exactly.
    const double p = c * xn + sn * yn;
    if (qz > 0) {
      side += p >= 0 ? full : radial(k, 0, qz / std::hypot(p, qz));
    } else if (qz < 0) {
      if (p > 0) side += radial(k, -qz / std::hypot(p, qz), 1);
    } else if (p > 0) {
      side += full;
    }
  }
  if (!(all > 0)) return qz > 0 ? 1.0 : 0.0;
  return std::clamp(side / all, 0.0, 1.0);
}

double asg_backward_fraction(const AsgLobe& q) {
  return asg_side_fraction(q, Vec3d{0, 1, 0}, kFractionSteps);
}

void ply_sim_side_energy(const PlySimSettings& s, const float* density, double& back,
                         double& forward) {
  back = forward = 0;
  for (int t = 0; t < s.theta_o_count; ++t) {
    const double om = ply_sim_bin_solid_angle(s, t);
    for (int p = 0; p < s.phi_o_count; ++p) {
      const double e = double(density[size_t(t) * size_t(s.phi_o_count) + size_t(p)]) * om;
      (ply_sim_bin_direction(s, t, p).y > 0 ? back : forward) += e;
    }
  }
}

std::vector<double> asg_fit_residual(const PlySimResult& sim, const AsgTable& t, bool refl) {
  const size_t M = sim.theta_i.size(), N = sim.h.size();
  const size_t K = refl ? 1 : t.sigmas.size();
  if (M != t.theta_i.size() || N != t.h.size() || (!refl && K != sim.settings.sigmas.size()))
    throw std::invalid_argument("asg_fit_residual: the table and the simulation differ in grids");
  const size_t bins = size_t(sim.settings.theta_o_count) * size_t(sim.settings.phi_o_count);
  std::vector<double> out(M * N * K * 2, 0.0);
  for (size_t m = 0; m < M; ++m)
    for (size_t n = 0; n < N; ++n) {
      const PlySimSlice& sl = sim.slice(int(m), int(n));
      // The lobes at this slice (S.6, S.7); the side fractions do not depend on sigma.
      const std::vector<AsgLobe> q0 = asg_table_lobes(t, sl.theta_i, sl.h, 0.0);
      std::vector<double> frac(q0.size());
      for (size_t l = 0; l < q0.size(); ++l) frac[l] = asg_backward_fraction(q0[l]);
      for (size_t k = 0; k < K; ++k) {
        const std::vector<AsgLobe> q =
            refl ? q0 : asg_table_lobes(t, sl.theta_i, sl.h, t.sigmas[k]);
        double fb = 0, ff = 0;
        for (size_t l = 0; l < q.size(); ++l) {
          const double I = shading::asg_integral(float(q[l].mu1), float(q[l].mu2), float(q[l].c));
          fb += frac[l] * I;
          ff += (1 - frac[l]) * I;
        }
        double db, df;
        ply_sim_side_energy(sim.settings, refl ? sl.refl.data() : sl.high.data() + k * bins, db,
                            df);
        double* r = &out[((m * N + n) * K + k) * 2];
        const double over_b = std::max(0.0, fb - db), over_f = std::max(0.0, ff - df);
        r[0] = std::max(0.0, db - fb - over_f);
        r[1] = std::max(0.0, df - ff - over_b);
      }
    }
  return out;
}

void asg_residual_at(const AsgTable& t, double theta_i, double h, double sigma, double& back,
                     double& forward) {
  back = forward = 0;
  const size_t M = t.theta_i.size(), N = t.h.size(), K = t.sigmas.size();
  if (t.residual.size() != M * N * K * 2 || M < 2 || N < 2) return;
  auto coord = [](double x, const std::vector<double>& g, size_t& i0, double& f) {
    double u = (x - g.front()) / (g.back() - g.front()) * double(g.size() - 1);
    if (!(u >= 0)) u = 0;
    u = std::min(u, double(g.size() - 1));
    i0 = std::min(size_t(u), g.size() - 2);
    f = u - double(i0);
  };
  size_t m0, n0;
  double fm, fn;
  coord(theta_i, t.theta_i, m0, fm);
  coord(h, t.h, n0, fn);
  int k;
  double ts;
  sigma_interval(t.sigmas, sigma, t.absorption, k, ts);
  const size_t k1 = std::min(size_t(k) + 1, K - 1);
  double out[2] = {0, 0};
  for (int side = 0; side < 2; ++side)
    for (size_t dm = 0; dm < 2; ++dm)
      for (size_t dn = 0; dn < 2; ++dn) {
        const double w = (dm ? fm : 1 - fm) * (dn ? fn : 1 - fn);
        const size_t s = (m0 + dm) * N + (n0 + dn);
        const double a = t.residual[(s * K + size_t(k)) * 2 + size_t(side)];
        const double b = t.residual[(s * K + k1) * 2 + size_t(side)];
        out[side] += w * ((1 - ts) * a + ts * b);
      }
  back = out[0];
  forward = out[1];
}

}  // namespace loom
