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

/// The single-ply simulation's outgoing bins and the plies' layout: what every slice's pass
/// reads.
struct BinGrid {
  const PlySimResult& single;
  const Layout& L;
  int T = 0, P = 0, K = 0;
  size_t B = 0;
  std::vector<double> omega;  ///< solid angle per bin
  std::vector<Vec3d> dir;     ///< centre direction per bin, ply 0's frame
};

BinGrid bin_grid(const PlySimResult& single, const Layout& L) {
  const PlySimSettings& st = single.settings;
  BinGrid G{single, L, st.theta_o_count, st.phi_o_count, int(st.sigmas.size()), 0, {}, {}};
  G.B = size_t(G.T) * size_t(G.P);
  G.omega.resize(G.B);
  G.dir.resize(G.B);
  for (int t = 0; t < G.T; ++t)
    for (int p = 0; p < G.P; ++p) {
      G.omega[size_t(t * G.P + p)] = ply_sim_bin_solid_angle(st, t);
      G.dir[size_t(t * G.P + p)] = ply_sim_bin_direction(st, t, p);
    }
  return G;
}

/// Residual band weights for incidence theta_i: a Gaussian in theta_o about -theta_i (f_1 of
/// Eq. S.19), as energy fractions per bin.
std::vector<double> residual_weights(const BinGrid& G, double theta_i) {
  std::vector<double> w(G.B, 0.0);
  double sum = 0;
  for (int t = 0; t < G.T; ++t) {
    const double th = -M_PI / 2 + M_PI * (t + 0.5) / G.T, d = (th + theta_i) / kResidualWidth;
    for (int p = 0; p < G.P; ++p) {
      const size_t b = size_t(t * G.P + p);
      w[b] = std::exp(-0.5 * d * d) * G.omega[b];
      sum += w[b];
    }
  }
  for (double& v : w) v /= sum;
  return w;
}

/// Ply 0's shadow tests towards w from `origins` points on its chord at offset h: the fraction
/// V that no other ply blocks, and per ply the fraction r that hits it with the hits' mean
/// offset hp along the ply's own x axis (its incident position h_p) and hq in the 2D plane
/// across the 2D ray (where the secondary light starts from).
struct ChordShadow {
  double V = 1;
  std::vector<double> r, hp, hq;
};

ChordShadow chord_shadow(const Layout& L, int origins, double h, const Vec3d& w) {
  const int J = origins, Pl = int(L.centre.size());
  const double half = std::sqrt(std::max(0.0, 1 - h * h));
  ChordShadow s;
  s.r.assign(size_t(Pl), 0.0);
  s.hp.assign(size_t(Pl), 0.0);
  s.hq.assign(size_t(Pl), 0.0);
  V2 u;
  if (!direction_2d(w, u)) return s;
  s.V = 0;
  for (int j = 0; j < J; ++j) {
    V2 o{h, half * (2 * (j + 0.5) / J - 1)}, q;
    const int p = first_hit(L, o, u, 0, q);
    if (p < 0) {
      s.V += 1.0 / J;
      continue;
    }
    s.r[size_t(p)] += 1.0 / J;
    // Offset along ply p's x axis for light coming from -w: y_p ~ -w, x_p = y_p x t_p.
    const Vec3d tp = L.axis[size_t(p)], win = w * -1;
    const Vec3d yp = normalized(win - tp * dot(win, tp)), xp = cross(yp, tp);
    const double qx = q.x - L.centre[size_t(p)].x, qy = q.y - L.centre[size_t(p)].y;
    s.hp[size_t(p)] += (qx * xp.x + qy * xp.y) / J;
    s.hq[size_t(p)] += (-qx * u.y + qy * u.x) / J;
  }
  for (int p = 1; p < Pl; ++p)
    if (s.r[size_t(p)] > 0) {
      s.hp[size_t(p)] = std::clamp(s.hp[size_t(p)] / s.r[size_t(p)], -1.0, 1.0);
      s.hq[size_t(p)] = std::clamp(s.hq[size_t(p)] / s.r[size_t(p)], -1.0, 1.0);
    }
  return s;
}

/// The secondary interaction's tallies per absorption level: the light it sends out per bin
/// (conv) and the energies s2 (all of it) and s3 (what leaves unshadowed) of Eq. S.16-S.18.
struct SecondaryTally {
  std::vector<double> conv, s2, s3;
};

/// Secondary interaction at ply p of light arriving along w_m (travel direction, ply 0's
/// frame) with energy e_in per level, at offset hpv along ply p's x axis and hqv across the 2D
/// ray: scattered as the single-ply simulation interpolated at ply p's own incidence, or
/// crossing it unscattered, each kept where no other ply blocks it.
void secondary_interaction(const BinGrid& G, int p, const Vec3d& wm, double hpv, double hqv,
                           const std::vector<double>& e_in, SecondaryTally& tally) {
  const PlySimResult& single = G.single;
  const PlySimSettings& st = single.settings;
  const Layout& L = G.L;
  const size_t B = G.B;
  const int K = G.K, P = G.P;
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
      e2[k] = e * G.omega[b2];
      any += e2[k];
    }
    if (any <= 0) continue;
    const Vec3d d = xp * G.dir[b2].x + yp * G.dir[b2].y + tp * G.dir[b2].z;
    int t, q;
    ply_sim_bin_of(st, d, t, q);
    const size_t bo = size_t(t * P + q);
    const double vis = visible_from_p(d);
    for (int k = 0; k < K; ++k) {
      const double e = e_in[size_t(k)] * e2[k];
      tally.conv[size_t(k) * B + bo] += e * vis;
      tally.s2[size_t(k)] += e;
      tally.s3[size_t(k)] += e * vis;
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
      tally.conv[size_t(k) * B + bo] += e * vis;
      tally.s2[size_t(k)] += e;
      tally.s3[size_t(k)] += e * vis;
    }
  }
}

/// One slice (theta_i, h) of the multi-ply pass, into `so` (and `energies`, K entries, if
/// given): (1) ply 0's shadow tests per bin and for the unscattered light, (2) the light that
/// meets another ply scattered again there, pooled over about 16 x 16 incident cells, (3) what
/// that loses to the residual (S.15-S.19).
void multi_ply_slice(const BinGrid& G, int origins, size_t si, PlySimSlice& so,
                     MultiPlyEnergy* energies) {
  const PlySimResult& single = G.single;
  const int T = G.T, P = G.P, K = G.K, Pl = int(G.L.centre.size());
  const size_t B = G.B, N = single.h.size();
  const PlySimSlice& s0 = single.slices[si];
  const double theta_i = single.theta_i[si / N], h = single.h[si % N];
  std::vector<ChordShadow> sh(B);
  for (size_t b = 0; b < B; ++b) sh[b] = chord_shadow(G.L, origins, h, G.dir[b]);
  const Vec3d delta_dir{0, -std::cos(theta_i), -std::sin(theta_i)};
  const ChordShadow sd = chord_shadow(G.L, origins, h, delta_dir);

  // Energies of ply 0 per bin and level (refl + high), and the unscattered delta.
  auto E0 = [&](size_t b, int k) {
    return (double(s0.refl[b]) + double(s0.high[size_t(k) * B + b])) * G.omega[b];
  };
  const double unsc0 = s0.energy[0].unscattered;

  SecondaryTally tally{std::vector<double>(size_t(K) * B, 0.0), std::vector<double>(size_t(K), 0.0),
                       std::vector<double>(size_t(K), 0.0)};
  // Pooled incident cells for the secondary interaction (about 16 x 16 over the sphere).
  const int pt = std::max(1, T / 16), pp = std::max(1, P / 16);
  const int CT = (T + pt - 1) / pt, CP = (P + pp - 1) / pp;
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
            const double rp = sh[b].r[size_t(p)];
            if (rp <= 0) continue;
            for (int k = 0; k < K; ++k) e_in[size_t(k)] += E0(b, k) * rp;
            const double w0 = E0(b, 0) * rp;
            wsum = wsum + G.dir[b] * w0;
            hsum += sh[b].hp[size_t(p)] * w0;
            qsum += sh[b].hq[size_t(p)] * w0;
            wtot += w0;
          }
        if (wtot <= 0) continue;
        secondary_interaction(G, p, normalized(wsum), std::clamp(hsum / wtot, -1.0, 1.0),
                              std::clamp(qsum / wtot, -1.0, 1.0), e_in, tally);
      }
    if (sd.r[size_t(p)] > 0 && unsc0 > 0) {
      std::fill(e_in.begin(), e_in.end(), unsc0 * sd.r[size_t(p)]);
      secondary_interaction(G, p, delta_dir, sd.hp[size_t(p)], sd.hq[size_t(p)], e_in, tally);
    }
  }

  // (1) + (4) + S.15-S.19 into the output slice.
  const std::vector<double> rw = residual_weights(G, theta_i);
  double refl_e = 0;
  for (size_t b = 0; b < B; ++b) {
    so.refl[b] = float(double(s0.refl[b]) * sh[b].V);
    refl_e += double(so.refl[b]) * G.omega[b];
  }
  for (int k = 0; k < K; ++k) {
    double s1 = unsc0 * (1 - sd.V);
    for (size_t b = 0; b < B; ++b) s1 += E0(b, k) * (1 - sh[b].V);
    double resi = 0;
    const double S2 = tally.s2[size_t(k)], S3 = tally.s3[size_t(k)];
    if (s1 > 1e-15 && S3 > 0) {
      // S.16-S.18: s_farfield = s3/s1, s_rescatter = (s2 - s3)/s1.
      const double denom = std::max(s1 - (S2 - S3), 1e-15);
      resi = std::clamp(s1 * S3 / denom - S3, 0.0, std::max(0.0, s1 - S3));
    }
    double high_e = 0;
    for (size_t b = 0; b < B; ++b) {
      const double e = double(s0.high[size_t(k) * B + b]) * G.omega[b] * sh[b].V +
                       tally.conv[size_t(k) * B + b] + resi * rw[b];
      so.high[size_t(k) * B + b] = float(e / G.omega[b]);
      high_e += double(so.high[size_t(k) * B + b]) * G.omega[b];
    }
    PlySimEnergy& en = so.energy[size_t(k)];
    en.reflected = refl_e;
    en.unscattered = unsc0 * sd.V;
    en.higher_order = high_e;
    en.truncated = s0.energy[size_t(k)].truncated;
    en.absorbed = std::max(0.0, 1 - en.reflected - en.unscattered - en.higher_order - en.truncated);
    if (energies) {
      double direct = unsc0 * sd.V;
      for (size_t b = 0; b < B; ++b) direct += E0(b, k) * sh[b].V;
      energies[k] = {s1, S2, S3, resi, direct};
    }
  }
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
  const Layout L = layout(g);
  const BinGrid G = bin_grid(single, L);
  PlySimResult out = single;
  if (energies) energies->assign(single.slices.size() * size_t(G.K), {});
  const size_t M = single.theta_i.size(), N = single.h.size();
  tbb::parallel_for(size_t(0), M * N, [&](size_t si) {
    multi_ply_slice(G, g.origins, si, out.slices[si],
                    energies ? energies->data() + si * size_t(G.K) : nullptr);
  });
  return out;
}

}  // namespace loom
