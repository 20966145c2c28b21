#include "loom/multi_ply.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace loom {
namespace {

constexpr int kMaxLevels = 16;

struct V2 {
  double x = 0, y = 0;
};

/// The plies in ply 0's normal plane (unit circles) and their axes in ply 0's frame.
struct Layout {
  std::vector<V2> centre;
  std::vector<Vec3d> axis;
};

Layout layout(const MultiPlyGeometry& g) {
  // Ply 0's frame: y = r_0 (towards the light), z = t_0, x = y x z; in the basis (r_0, tau_0, Y)
  // t_0 = cos a Y + sin a tau_0, so Y = (sin a, 0, cos a) and tau_0 = (-cos a, 0, sin a).
  const double a = g.twist;
  const Vec3d Y{std::sin(a), 0, std::cos(a)}, tau0{-std::cos(a), 0, std::sin(a)}, r0{0, 1, 0};
  Layout L;
  for (int p = 0; p < g.plies; ++p) {
    const double D = 2 * M_PI * p / g.plies;
    const Vec3d rp = r0 * std::cos(D) + tau0 * std::sin(D);
    const Vec3d taup = tau0 * std::cos(D) - r0 * std::sin(D);
    const Vec3d c = (rp - r0) * g.centre_distance;
    L.centre.push_back({c.x, c.y});
    L.axis.push_back(normalized(Y * std::cos(a) + taup * std::sin(a)));
  }
  return L;
}

/// First ply (other than `skip`) a 2D ray from o along unit u meets; a start inside a ply hits
/// it at once. Returns -1 for none; `q` receives the hit point.
int first_hit(const Layout& L, V2 o, V2 u, int skip, V2& q) {
  int best = -1;
  double best_t = INFINITY;
  for (int p = 0; p < int(L.centre.size()); ++p) {
    if (p == skip) continue;
    const double ox = o.x - L.centre[size_t(p)].x, oy = o.y - L.centre[size_t(p)].y;
    const double cc = ox * ox + oy * oy - 1;
    double t;
    if (cc <= 0) {
      t = 0;
    } else {
      const double b = ox * u.x + oy * u.y, disc = b * b - cc;
      if (disc < 0) continue;
      t = -b - std::sqrt(disc);
      if (t < 0) continue;
    }
    if (t < best_t) best_t = t, best = p;
  }
  if (best >= 0) q = {o.x + u.x * best_t, o.y + u.y * best_t};
  return best;
}

bool direction_2d(const Vec3d& w, V2& u) {
  const double l = std::hypot(w.x, w.y);
  if (l < 1e-9) return false;
  u = {w.x / l, w.y / l};
  return true;
}

/// Bilinear weights of the four simulated slices around (theta, h), clamped to the grids.
struct SliceWeights {
  size_t slice[4];
  double w[4];
};
SliceWeights slice_weights(const PlySimResult& s, double theta, double h) {
  auto locate = [](const std::vector<double>& g, double x, int& i0, double& f) {
    const int n = int(g.size());
    double u = (std::clamp(x, g.front(), g.back()) - g.front()) / (g.back() - g.front()) * (n - 1);
    i0 = std::clamp(int(std::floor(u)), 0, n - 2);
    f = std::clamp(u - i0, 0.0, 1.0);
  };
  int m, n;
  double fm, fn;
  locate(s.theta_i, theta, m, fm);
  locate(s.h, h, n, fn);
  const size_t N = s.h.size();
  return {{size_t(m) * N + size_t(n), size_t(m) * N + size_t(n + 1), size_t(m + 1) * N + size_t(n),
           size_t(m + 1) * N + size_t(n + 1)},
          {(1 - fm) * (1 - fn), (1 - fm) * fn, fm * (1 - fn), fm * fn}};
}

}  // namespace

MultiPlyGeometry multi_ply_geometry(const YarnSpec& y, const PlySimResult& single) {
  MultiPlyGeometry g;
  const PlyParams p = ply_params_from_yarn(y);
  g.plies = std::max(1, y.plies);
  const double rho = single.silhouette_radius_um > 0 ? single.silhouette_radius_um : p.ply_radius;
  g.centre_distance = p.ply_centre_radius / rho;
  g.twist = p.twist_sign * y.ply_twist_deg * M_PI / 180;
  return g;
}

PlySimResult multi_ply_scattering(const PlySimResult& single, const MultiPlyGeometry& g,
                                  std::vector<MultiPlyEnergy>* energies) {
  if (g.plies < 2) return single;  // single-ply yarns skip all of it
  if (g.origins < 1) throw std::invalid_argument("multi_ply: at least one shadow-test origin");
  if (single.settings.sigmas.size() > size_t(kMaxLevels))
    throw std::invalid_argument("multi_ply: at most 16 absorption levels");
  const PlySimSettings& st = single.settings;
  const int T = st.theta_o_count, P = st.phi_o_count, K = int(st.sigmas.size());
  const size_t B = size_t(T) * size_t(P);
  const Layout L = layout(g);
  std::vector<double> omega(B);
  std::vector<Vec3d> dir(B);
  for (int t = 0; t < T; ++t)
    for (int p = 0; p < P; ++p) {
      omega[size_t(t * P + p)] = ply_sim_bin_solid_angle(st, t);
      dir[size_t(t * P + p)] = ply_sim_bin_direction(st, t, p);
    }
  // Pooled incident cells for the secondary interaction (about 16 x 16 over the sphere).
  const int pt = std::max(1, T / 16), pp = std::max(1, P / 16);
  const int CT = (T + pt - 1) / pt, CP = (P + pp - 1) / pp;
  // Residual band weights per theta_i sample: Gaussian in theta_o about -theta_i (Eq. S.19).
  auto residual_weights = [&](double theta_i) {
    std::vector<double> w(B, 0.0);
    double sum = 0;
    for (int t = 0; t < T; ++t) {
      const double th = -M_PI / 2 + M_PI * (t + 0.5) / T, d = (th + theta_i) / kResidualWidth;
      for (int p = 0; p < P; ++p) {
        const size_t b = size_t(t * P + p);
        w[b] = std::exp(-0.5 * d * d) * omega[b];
        sum += w[b];
      }
    }
    for (double& v : w) v /= sum;
    return w;  // energy fractions per bin
  };

  PlySimResult out = single;
  if (energies) energies->assign(single.slices.size() * size_t(K), {});
  const size_t M = single.theta_i.size(), N = single.h.size();
  tbb::parallel_for(size_t(0), M * N, [&](size_t si) {
    const size_t m = si / N, n = si % N;
    const PlySimSlice& s0 = single.slices[si];
    const double theta_i = single.theta_i[m], h = single.h[n];
    // (1) Shadow tests from the chord of ply 0: visibility per bin and hit fractions and mean hit
    // offsets per (bin, ply).
    const int J = g.origins, Pl = g.plies;
    const double half = std::sqrt(std::max(0.0, 1 - h * h));
    // hp: offset of the hit point along ply p's own x axis (its incident position h_p); hq: the
    // same offset in the 2D plane, across the 2D ray (where the secondary light starts from).
    auto shadow = [&](const Vec3d& w, double& V, std::vector<double>& r, std::vector<double>& hp,
                      std::vector<double>& hq) {
      r.assign(size_t(Pl), 0.0);
      hp.assign(size_t(Pl), 0.0);
      hq.assign(size_t(Pl), 0.0);
      V2 u;
      if (!direction_2d(w, u)) {
        V = 1;
        return;
      }
      V = 0;
      for (int j = 0; j < J; ++j) {
        V2 o{h, half * (2 * (j + 0.5) / J - 1)}, q;
        const int p = first_hit(L, o, u, 0, q);
        if (p < 0) {
          V += 1.0 / J;
          continue;
        }
        r[size_t(p)] += 1.0 / J;
        // Offset along ply p's x axis for light coming from -w: y_p ~ -w, x_p = y_p x t_p.
        const Vec3d tp = L.axis[size_t(p)], win = w * -1;
        const Vec3d yp = normalized(win - tp * dot(win, tp)), xp = cross(yp, tp);
        const double qx = q.x - L.centre[size_t(p)].x, qy = q.y - L.centre[size_t(p)].y;
        hp[size_t(p)] += (qx * xp.x + qy * xp.y) / J;
        hq[size_t(p)] += (-qx * u.y + qy * u.x) / J;
      }
      for (int p = 1; p < Pl; ++p)
        if (r[size_t(p)] > 0) {
          hp[size_t(p)] = std::clamp(hp[size_t(p)] / r[size_t(p)], -1.0, 1.0);
          hq[size_t(p)] = std::clamp(hq[size_t(p)] / r[size_t(p)], -1.0, 1.0);
        }
    };
    std::vector<double> V(B);
    std::vector<std::vector<double>> r(B), hp(B), hq(B);
    for (size_t b = 0; b < B; ++b) shadow(dir[b], V[b], r[b], hp[b], hq[b]);
    const Vec3d delta_dir{0, -std::cos(theta_i), -std::sin(theta_i)};
    double V_delta;
    std::vector<double> r_delta, h_delta, q_delta;
    shadow(delta_dir, V_delta, r_delta, h_delta, q_delta);

    // Energies of ply 0 per bin and level (refl + high), and the unscattered delta.
    auto E0 = [&](size_t b, int k) {
      return (double(s0.refl[b]) + double(s0.high[size_t(k) * B + b])) * omega[b];
    };
    const double unsc0 = s0.energy[0].unscattered;

    std::vector<double> conv(size_t(K) * B, 0.0);
    std::vector<double> s2(size_t(K), 0.0), s3(size_t(K), 0.0);
    // (2) Secondary interaction from ply p for light arriving from direction w_m (travel
    // direction, ply 0's frame) with energy e_in[k], at offset h_p.
    auto secondary = [&](int p, const Vec3d& wm, double hpv, double hqv,
                         const std::vector<double>& e_in) {
      const Vec3d tp = L.axis[size_t(p)], win = wm * -1;
      const double th_p = std::asin(std::clamp(dot(win, tp), -1.0, 1.0));
      Vec3d yp = win - tp * dot(win, tp);
      if (dot(yp, yp) < 1e-18) return;  // along ply p's axis: never meets it
      yp = normalized(yp);
      const Vec3d xp = cross(yp, tp);
      const SliceWeights sw = slice_weights(single, th_p, hpv);
      // Secondary light leaves ply p from its chord point across the 2D ray.
      V2 u_in{0, -1};
      direction_2d(wm, u_in);
      const V2 origin{L.centre[size_t(p)].x - hqv * u_in.y, L.centre[size_t(p)].y + hqv * u_in.x};
      auto visible_from_p = [&](const Vec3d& w) {
        V2 u, q;
        if (!direction_2d(w, u)) return 1.0;
        return first_hit(L, origin, u, p, q) < 0 ? 1.0 : 0.0;
      };
      for (size_t b2 = 0; b2 < B; ++b2) {
        double e2[kMaxLevels];
        double any = 0;
        for (int k = 0; k < K; ++k) {
          double e = 0;
          for (int c = 0; c < 4; ++c) {
            if (sw.w[c] <= 0) continue;
            const PlySimSlice& sl = single.slices[sw.slice[c]];
            e += sw.w[c] * (double(sl.refl[b2]) + double(sl.high[size_t(k) * B + b2]));
          }
          e2[k] = e * omega[b2];
          any += e2[k];
        }
        if (any <= 0) continue;
        const Vec3d d = xp * dir[b2].x + yp * dir[b2].y + tp * dir[b2].z;
        int t, q;
        ply_sim_bin_of(st, d, t, q);
        const size_t bo = size_t(t * P + q);
        const double vis = visible_from_p(d);
        for (int k = 0; k < K; ++k) {
          const double e = e_in[size_t(k)] * e2[k];
          conv[size_t(k) * B + bo] += e * vis;
          s2[size_t(k)] += e;
          s3[size_t(k)] += e * vis;
        }
      }
      // Light that crosses ply p without meeting a fiber continues along w_m.
      double un = 0;
      for (int c = 0; c < 4; ++c) un += sw.w[c] * single.slices[sw.slice[c]].energy[0].unscattered;
      if (un > 0) {
        int t, q;
        ply_sim_bin_of(st, wm, t, q);
        const size_t bo = size_t(t * P + q);
        const double vis = visible_from_p(wm);
        for (int k = 0; k < K; ++k) {
          const double e = e_in[size_t(k)] * un;
          conv[size_t(k) * B + bo] += e * vis;
          s2[size_t(k)] += e;
          s3[size_t(k)] += e * vis;
        }
      }
    };
    std::vector<double> e_in(static_cast<size_t>(K));
    for (int p = 1; p < Pl; ++p) {
      for (int ct = 0; ct < CT; ++ct)
        for (int cp = 0; cp < CP; ++cp) {
          // Pool the cell: energy into ply p per level, its mean direction and offset.
          std::fill(e_in.begin(), e_in.end(), 0.0);
          Vec3d wsum{0, 0, 0};
          double hsum = 0, qsum = 0, wtot = 0;
          for (int t = ct * pt; t < std::min(T, (ct + 1) * pt); ++t)
            for (int q = cp * pp; q < std::min(P, (cp + 1) * pp); ++q) {
              const size_t b = size_t(t * P + q);
              const double rp = r[b][size_t(p)];
              if (rp <= 0) continue;
              for (int k = 0; k < K; ++k) e_in[size_t(k)] += E0(b, k) * rp;
              const double w0 = E0(b, 0) * rp;
              wsum = wsum + dir[b] * w0;
              hsum += hp[b][size_t(p)] * w0;
              qsum += hq[b][size_t(p)] * w0;
              wtot += w0;
            }
          if (wtot <= 0) continue;
          secondary(p, normalized(wsum), std::clamp(hsum / wtot, -1.0, 1.0),
                    std::clamp(qsum / wtot, -1.0, 1.0), e_in);
        }
      if (r_delta[size_t(p)] > 0 && unsc0 > 0) {
        std::fill(e_in.begin(), e_in.end(), unsc0 * r_delta[size_t(p)]);
        secondary(p, delta_dir, h_delta[size_t(p)], q_delta[size_t(p)], e_in);
      }
    }

    // (1) + (4) + S.15-S.19 into the output slice.
    PlySimSlice& so = out.slices[si];
    const std::vector<double> rw = residual_weights(theta_i);
    double refl_e = 0;
    for (size_t b = 0; b < B; ++b) {
      so.refl[b] = float(double(s0.refl[b]) * V[b]);
      refl_e += double(so.refl[b]) * omega[b];
    }
    for (int k = 0; k < K; ++k) {
      double s1 = unsc0 * (1 - V_delta);
      for (size_t b = 0; b < B; ++b) s1 += E0(b, k) * (1 - V[b]);
      double resi = 0;
      const double S2 = s2[size_t(k)], S3 = s3[size_t(k)];
      if (s1 > 1e-15 && S3 > 0) {
        // S.16-S.18: s_farfield = s3/s1, s_rescatter = (s2 - s3)/s1.
        const double denom = std::max(s1 - (S2 - S3), 1e-15);
        resi = std::clamp(s1 * S3 / denom - S3, 0.0, std::max(0.0, s1 - S3));
      }
      double high_e = 0;
      for (size_t b = 0; b < B; ++b) {
        const double e = double(s0.high[size_t(k) * B + b]) * omega[b] * V[b] +
                         conv[size_t(k) * B + b] + resi * rw[b];
        so.high[size_t(k) * B + b] = float(e / omega[b]);
        high_e += double(so.high[size_t(k) * B + b]) * omega[b];
      }
      PlySimEnergy& en = so.energy[size_t(k)];
      en.reflected = refl_e;
      en.unscattered = unsc0 * V_delta;
      en.higher_order = high_e;
      en.truncated = s0.energy[size_t(k)].truncated;
      en.absorbed = std::max(0.0, 1 - en.reflected - en.unscattered - en.higher_order - en.truncated);
      if (energies) {
        double direct = unsc0 * V_delta;
        for (size_t b = 0; b < B; ++b) direct += E0(b, k) * V[b];
        (*energies)[si * size_t(K) + size_t(k)] = {s1, S2, S3, resi, direct};
      }
    }
  });
  return out;
}

}  // namespace loom
