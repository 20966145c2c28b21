#include "loom/raywave_bsdf.h"

#include "loom/asg_residual.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <memory>
#include <stdexcept>
#include <tbb/parallel_for.h>

#include "loom/cycles_closures.h"
#include "raywave_point.h"

namespace loom {

using namespace shading;
using nlohmann::json;

namespace {

/// Polar nodes of asg_side_fraction for the model's forward light T (prepare): at 256 the
/// fraction is within 2e-3 of 2048 nodes' on the fitted lobes (test_asg_residual.cpp), an eighth
/// of the cost per shading point.
constexpr int kModelFractionSteps = 256;

/// Blender's linear image texture with EXTEND borders at (s, tv), tv from the bottom.
void sample_clamped(const Image& img, float s, float tv, float out[4]) {
  float px = std::clamp(s * float(img.width) - 0.5f, 0.0f, float(img.width - 1));
  float py = std::clamp(tv * float(img.height) - 0.5f, 0.0f, float(img.height - 1));
  if (!std::isfinite(px)) px = 0;
  if (!std::isfinite(py)) py = 0;
  int x0 = int(px), y0 = int(py);
  int x1 = std::min(x0 + 1, img.width - 1), y1 = std::min(y0 + 1, img.height - 1);
  float fx = px - float(x0), fy = py - float(y0);
  for (int c = 0; c < img.channels; ++c) {
    float a = img.px(x0, y0)[c] * (1 - fx) + img.px(x1, y0)[c] * fx;
    float b = img.px(x0, y1)[c] * (1 - fx) + img.px(x1, y1)[c] * fx;
    out[c] = a * (1 - fy) + b * fy;
  }
}

/// Bilinear, periodic in s (an Image Texture with REPEAT), clamped in tv.
void sample_periodic(const Image& img, float s, float tv, float out[4]) {
  float px = (s - std::floor(s)) * float(img.width) - 0.5f;
  float py = std::clamp(tv * float(img.height) - 0.5f, 0.0f, float(img.height - 1));
  if (!std::isfinite(px)) px = 0;
  if (!std::isfinite(py)) py = 0;
  const int x0 = int(std::floor(px)), y0 = int(py);
  const float fx = px - float(x0), fy = py - float(y0);
  const int xa = ((x0 % img.width) + img.width) % img.width, xb = (xa + 1) % img.width;
  const int y1 = std::min(y0 + 1, img.height - 1);
  for (int c = 0; c < img.channels; ++c) {
    float a = img.px(xa, y0)[c] * (1 - fx) + img.px(xb, y0)[c] * fx;
    float b = img.px(xa, y1)[c] * (1 - fx) + img.px(xb, y1)[c] * fx;
    out[c] = a * (1 - fy) + b * fy;
  }
}



/// A yarn's absorption (1/mm) as the tables take it: NaN none, negative none, at most 1e12 (far
/// beyond the tables' largest level, where the lobes are already gone).
double guard_sigma(double s) { return std::isnan(s) ? 0.0 : std::clamp(s, 0.0, 1e12); }

/// The noise averaged over a lobe with ply-space centre lz and bandwidths mu1, mu2 (Eq. S.39 as
/// the closures take it: speckle_noise.h, noise_lobe_uv, the two blur levels blended).
vec3 lobe_noise(const RaywavePoint::Impl& q, vec3 lz, bool is_refl, float mu1, float mu2) {
  float u, v0, v1, t, n0[4], n1[4];
  noise_lobe_uv(lz, q.wi_ply, is_refl ? 1 : 0, mu1, mu2, q.noise_instance, q.noise_shift,
                q.noise->instances, u, v0, v1, t);
  const Image& img = is_refl ? *q.noise->refl : *q.noise->high;
  sample_periodic(img, u, v0, n0);
  sample_periodic(img, u, v1, n1);
  return vec3(n0[0] * (1 - t) + n1[0] * t, n0[1] * (1 - t) + n1[1] * t,
              n0[2] * (1 - t) + n1[2] * t);
}

/// What the parts of raywave_prepare share of a point: the guarded texel, the yarn (0 warp, 1
/// weft), the side seen (0 front, 1 back), the ply space's theta_i and h, the yarns' absorption
/// and the layers' (their mean).
struct PointFrame {
  SurfacePoint p;
  int y = 0, side = 0;
  float theta_i = 0, h = 0;
  std::array<double, 3> sigma[2] = {}, sig_layers = {};
};

/// The gap diffraction the shaders sample at the point: the tiles they pick from
/// (diffraction_tile_pick) with their probabilities, averaged over the point's footprint (the
/// shader takes the offset at every shading position, the maps per texel, as an Image Texture
/// read 'Closest' or its average over the texel), and each tile's power outside the spot.
void prepare_gap_diffraction(RaywavePoint::Impl& q, const RaywaveData& d, const SurfacePoint& p) {
  const GapDiffraction& g = d.diffraction;
  q.dif = &g;
  q.albedo_lut = d.microfacet_albedo;
  q.gap = std::clamp(p.gap, 0.0f, 1.0f);
  const int n[2] = {g.table.tiles_x, g.table.tiles_y};
  const int sub = p.du > 0 || p.dv > 0 ? 4 : 1;
  std::vector<float> w(static_cast<size_t>(n[0] * n[1]), 0.0f);
  for (int a = 0; a < sub; ++a)
    for (int b = 0; b < sub; ++b) {
      const float uu = p.u + ((a + 0.5f) / sub - 0.5f) * p.du;
      const float vv = p.v + ((b + 0.5f) / sub - 0.5f) * p.dv;
      const float o[2] = {diffraction_gap_offset(uu, g.yarns[0], g.gap_fraction[0]),
                          diffraction_gap_offset(vv, g.yarns[1], g.gap_fraction[1])};
      int lo[2], hi[2];
      float w_hi[2];
      for (int k = 0; k < 2; ++k) {  // the expectation of diffraction_tile_pick
        lo[k] = diffraction_tile_pick(o[k], n[k], 1.0f);
        hi[k] = diffraction_tile_pick(o[k], n[k], 0.0f);
        const float f = diffraction_tile_coord(o[k], n[k]);
        w_hi[k] = hi[k] == lo[k] ? 0.0f : f - std::floor(f);
      }
      for (int ia = 0; ia < 2; ++ia)
        for (int ib = 0; ib < 2; ++ib)
          w[size_t((ib ? hi[1] : lo[1]) * n[0] + (ia ? hi[0] : lo[0]))] +=
              (ia ? w_hi[0] : 1 - w_hi[0]) * (ib ? w_hi[1] : 1 - w_hi[1]) / float(sub * sub);
    }
  for (int t = 0; t < n[0] * n[1]; ++t) {
    if (w[size_t(t)] <= 0) continue;
    const int tx = t % n[0], ty = t / n[0];
    float po[4], s, tv;
    diffraction_sample_uv(0.5f, g.table.size, tx, ty, n[0], n[1], g.table.size, s, tv);
    sample_clamped(*g.sampling, s, tv, po);
    q.tile.push_back(t);
    q.tile_w.push_back(w[size_t(t)]);
    q.p_out.push_back({po[0], po[1], po[2]});
  }
  q.tiles = int(q.tile.size());
}

/// The model at the point: the lobes at (theta_i, h) per channel, the double-layer factors,
/// the residual and the forward light T, with raywave_energy_budget's factors in the lobes'
/// amplitudes and the rest's (rest_scale).
void prepare_model(RaywavePoint::Impl& q, const RaywaveData& d, const PointFrame& f) {
  q.refl = asg_table_lobes(d.yarn[f.y].refl, f.theta_i, f.h, 0.0);
  for (int c = 0; c < 3; ++c)
    q.high[c] = asg_table_lobes(d.yarn[f.y].high, f.theta_i, f.h, f.sigma[f.y][size_t(c)]);
  // The point's forward light T: each lobe's integral times its fraction below the cloth's
  // plane (the plane's normal in ply space), which S.10 and S.11 leave the same for every
  // channel (they scale amplitudes only).
  const Vec3d n_ply{q.xp.z, q.yp.z, q.t.z};
  std::array<double, 3> fwd{0, 0, 0};
  // raywave_energy_budget in the closures' order, with each lobe's energy with the noise as
  // the closures take it: the lobe's integral per channel, its share above the plane for
  // b_refl, the visibility and the noise at its centre (the tiles at the blur of its width;
  // the model's own noise, the tile at each direction, averages to about that over the lobe).
  // The factors scale the lobes' amplitudes, per channel.
  for (int c = 0; c < 3; ++c)
    layer_factor_pair(double_layer_at(d.layers[f.side], q.V, f.sig_layers[size_t(c)]),
                      q.k_b[size_t(c)], q.k_f[size_t(c)]);
  const vec3 kf(q.k_f[0], q.k_f[1], q.k_f[2]), kb(q.k_b[0], q.k_b[1], q.k_b[2]);
  vec3 used(0, 0, 0);
  auto budget = [&](const AsgLobe& l, vec3 integral, bool is_refl, double above) {
    vec3 lx, ly, lz;
    asg_frame(float(l.theta_z), float(l.phi_z), float(l.phi_xy), lx, ly, lz);
    const float vis_z = q.back ? 1.0f : raywave_lobe_visibility(
                                            raywave_from_ply(lz, q.xp, q.yp, q.t), q.hor);
    vec3 en = raywave_lobe_energy(1.0f, integral, q.open, q.vis_v, vis_z, kf, q.s,
                                  float(above));
    if (q.noise) en = en * lobe_noise(q, lz, is_refl, float(l.mu1), float(l.mu2));
    const vec3 k = raywave_energy_budget(en, used, q.open);
    used = used + en * k;
    return k;
  };
  for (int c = 0; c < 3; ++c) q.refl_rgb[size_t(c)] = q.refl;
  for (size_t l = 0; l < q.refl.size(); ++l) {
    const AsgLobe& lobe = q.refl[l];
    const double above = asg_side_fraction(lobe, n_ply, kModelFractionSteps);
    const double integral = asg_integral(lobe.mu1, lobe.mu2, lobe.c);
    for (int c = 0; c < 3; ++c) fwd[size_t(c)] += (1 - above) * integral;
    const vec3 k = budget(lobe, vec3(float(integral)), true, above);
    for (int c = 0; c < 3; ++c) q.refl_rgb[size_t(c)][l].c *= k[c];
  }
  for (size_t l = 0; l < q.high[0].size(); ++l) {
    const double above = asg_side_fraction(q.high[0][l], n_ply, kModelFractionSteps);
    vec3 integral(0, 0, 0);
    for (int c = 0; c < 3; ++c) {
      const AsgLobe& lc = q.high[c][l];
      integral[c] = float(asg_integral(lc.mu1, lc.mu2, lc.c));
      fwd[size_t(c)] += (1 - above) * integral[c];
    }
    const vec3 k = budget(q.high[1][l], integral, false, above);
    for (int c = 0; c < 3; ++c) q.high[c][l].c *= k[c];
  }
  for (int c = 0; c < 3; ++c) {
    double rb, rf, hb, hf;
    asg_residual_at(d.yarn[f.y].refl, f.theta_i, f.h, 0.0, rb, rf);
    asg_residual_at(d.yarn[f.y].high, f.theta_i, f.h, f.sigma[f.y][size_t(c)], hb, hf);
    q.res_b[size_t(c)] = float(rb + hb);
    q.res_f[size_t(c)] = float(rf + hf);
    q.t_fwd[size_t(c)] = float(fwd[size_t(c)] + q.res_f[size_t(c)]);
  }
  const vec3 T(q.t_fwd[0], q.t_fwd[1], q.t_fwd[2]);
  const vec3 rest =
      raywave_residual_diffuse_weight(vec3(q.res_b[0], q.res_b[1], q.res_b[2]), q.open,
                                      q.vis_v) +
      raywave_residual_translucent_weight(vec3(q.res_f[0], q.res_f[1], q.res_f[2]), q.open,
                                          kf, q.s) +
      raywave_layer_diffuse_weight(T, q.open, q.vis_v, kb) +
      raywave_layer_translucent_weight(T, q.open, kf, q.s);
  const vec3 r = raywave_energy_budget(rest, used, q.open);
  q.rest_scale = {r.x, r.y, r.z};
}

/// The closures of one lobe table (f_refl's, or f_high's with its tint) as the shaders emit them
/// (loom_lobes in loom_cloth_raywave.osl), in order, each lobe within what the closures before
/// it left of the budget (`used`); adds each lobe's part of the forward light to t_fwd.
void add_lobe_closures(RaywavePoint::Impl& q, const RaywaveData& d, const PointFrame& f,
                       const AsgTable& tab, const Image& nodes, const Image* tint, vec3& t_fwd,
                       vec3& used, int& lobe_index) {
  const int M = int(tab.theta_i.size()), N = int(tab.h.size()), L = tab.lobes;
  const int rows = M / 2 + 1, cols = N / 2 + 1;
  const float fi = asg_node_coord(f.theta_i, float(tab.theta_i.front()),
                                  float(tab.theta_i.back()), M);
  const float fj = asg_node_coord(f.h, float(tab.h.front()), float(tab.h.back()), N);
  for (int l = 0; l < L; ++l) {
    float a[4], b[4], s, tv;
    asg_node_uv(fi, fj, 0, l, L, rows, cols, s, tv);
    sample_clamped(nodes, s, tv, a);
    asg_node_uv(fi, fj, 1, l, L, rows, cols, s, tv);
    sample_clamped(nodes, s, tv, b);
    std::array<float, 3> tintc = {1, 1, 1};
    if (tint) {
      float tp[4];
      asg_tint_uv(fi, fj, l, L, rows, cols, s, tv);
      sample_clamped(*tint, s, tv, tp);
      tintc = {tp[0], tp[1], tp[2]};
    }
    vec3 z, Nr, Tr, Nt;
    float axr, ayr, at, b_refl, b_refr;
    raywave_lobe_closures(q.V, q.xp, q.yp, q.t, vec3(a[0], a[1], a[2]), a[3],
                          vec3(b[0], b[1], b[2]), z, Nr, Tr, axr, ayr, Nt, at, b_refl, b_refr);
    float Er[4] = {0, 0, 0, 0}, Et[4] = {0, 0, 0, 0};
    if (b_refl > 0) {
      float ls, lt;
      microfacet_albedo_uv(dot(Nr, q.V), std::sqrt(axr * ayr), ls, lt);
      sample_clamped(*d.microfacet_albedo, ls, lt, Er);
    }
    if (b_refr > 0) {
      float ls, lt;
      microfacet_albedo_uv(dot(Nt, q.V), at, ls, lt);
      sample_clamped(*d.microfacet_albedo, ls, lt, Et);
    }
    const float vis_z = q.back ? 1.0f : raywave_lobe_visibility(z, q.hor);
    vec3 w[3];  // by kind: 0 reflection, 1 translucent, 2 refraction
    float h_lut[4], hs, ht;  // the lobe's integral (asg.h: asg_integral_from_lut)
    asg_integral_lut_uv(a[3], b[0], hs, ht);
    sample_clamped(*d.asg_integral, hs, ht, h_lut);
    const float integral = asg_integral_from_lut(h_lut[0], a[3], b[0], b[1]);
    const vec3 tint3(tintc[0], tintc[1], tintc[2]);
    raywave_lobe_weights(integral, Er[0], Et[1], tint3, q.open, q.vis_v, vis_z,
                         vec3(q.k_f[0], q.k_f[1], q.k_f[2]), q.s, b_refl, b_refr, w[0], w[2],
                         w[1]);
    t_fwd = t_fwd + raywave_lobe_forward(integral, tint3, b_refl);
    vec3 energy = raywave_lobe_energy(integral, tint3, q.open, q.vis_v, vis_z,
                                      vec3(q.k_f[0], q.k_f[1], q.k_f[2]), q.s, b_refl);
    if (q.noise) {  // Eq. S.39 per lobe (speckle_noise.h)
      vec3 lx, ly, lz;
      asg_frame(a[0], a[1], a[2], lx, ly, lz);
      const vec3 nz = lobe_noise(q, lz, tint == nullptr, a[3], b[0]);
      for (vec3& wk : w) wk = wk * nz;
      energy = energy * nz;
    }
    const vec3 budget = raywave_energy_budget(energy, used, q.open);
    for (vec3& wk : w) wk = wk * budget;
    used = used + energy * budget;
    const float share[3] = {b_refl, (1 - b_refl) * (1 - b_refr), (1 - b_refl) * b_refr};
    for (int kind = 0; kind < 3; ++kind) {
      if (!(share[kind] > 0)) continue;
      RaywaveClosure cl;
      cl.kind = kind;
      cl.lobe = lobe_index;
      cl.share = share[kind];
      cl.weight = {w[kind].x, w[kind].y, w[kind].z};
      cl.N = kind == 0 ? Nr : (kind == 2 ? Nt : vec3(0, 0, 1));
      cl.T = kind == 0 ? Tr : vec3(1, 0, 0);
      cl.alpha_x = kind == 0 ? axr : (kind == 2 ? at : 1.0f);
      cl.alpha_y = kind == 0 ? ayr : (kind == 2 ? at : 1.0f);
      // Cycles' closure setup raises the normal where needed (ensure_valid_specular_reflection).
      const vec3 Ng(0, 0, 1);
      if (kind == 0) {
        q.mf.emplace_back(cycles::ensure_valid_specular_reflection(Ng, q.V, cl.N), cl.T,
                          cl.alpha_x, cl.alpha_y, Ng, q.V, cycles::Distribution::Beckmann);
        q.mf_w.push_back(cl.weight);
      } else if (kind == 2) {
        q.refr.emplace_back(cycles::ensure_valid_specular_reflection(Ng, q.V, cl.N), cl.alpha_x,
                            float(LOOM_RAYWAVE_ETA), Ng, q.V, cycles::Distribution::Beckmann);
        q.refr_w.push_back(cl.weight);
      } else {
        for (int c = 0; c < 3; ++c) q.transl_w[size_t(c)] += cl.weight[size_t(c)];
      }
      q.list.push_back(cl);
    }
    ++lobe_index;
  }
}

/// The closures after the lobes: the energy residual (raywave_lobes.h: diffuse reflection and
/// diffuse transmission), the layers' light from the point's forward light T
/// (double_layer_factors.h: the diffuse BTDF of Eq. S.22 and the light returned backwards), and
/// the open gaps' transparent() (kind 4), less what the gap diffraction samples
/// (diffraction_sampling.h; those lobes are evaluated in expectation).
void add_diffuse_closures(RaywavePoint::Impl& q, const RaywaveData& d, const PointFrame& f,
                          vec3 t_fwd, vec3 used) {
  const AsgTable& tab = d.yarn[f.y].high;
  float eb[4], ef[4], s, tv;
  raywave_residual_uv(f.theta_i, f.h, float(tab.theta_i.front()), float(tab.theta_i.back()),
                      int(tab.theta_i.size()), int(tab.h.size()), 0, s, tv);
  sample_clamped(*d.residual[f.y], s, tv, eb);
  raywave_residual_uv(f.theta_i, f.h, float(tab.theta_i.front()), float(tab.theta_i.back()),
                      int(tab.theta_i.size()), int(tab.h.size()), 1, s, tv);
  sample_clamped(*d.residual[f.y], s, tv, ef);
  const vec3 kf(q.k_f[0], q.k_f[1], q.k_f[2]), kb(q.k_b[0], q.k_b[1], q.k_b[2]);
  t_fwd = t_fwd + vec3(ef[0], ef[1], ef[2]);
  for (int c = 0; c < 3; ++c) q.t_fwd[size_t(c)] = t_fwd[c];
  // After the lobes, within what they left of the budget (raywave_energy_budget).
  const vec3 eb3(eb[0], eb[1], eb[2]), ef3(ef[0], ef[1], ef[2]);
  const vec3 wlt0 = raywave_layer_translucent_weight(t_fwd, q.open, kf, q.s);
  const vec3 wld0 = raywave_layer_diffuse_weight(t_fwd, q.open, q.vis_v, kb);
  const vec3 wd0 = raywave_residual_diffuse_weight(eb3, q.open, q.vis_v);
  const vec3 wt0 = raywave_residual_translucent_weight(ef3, q.open, kf, q.s);
  const vec3 r = raywave_energy_budget(wlt0 + wld0 + wd0 + wt0, used, q.open);
  const vec3 wlt = wlt0 * r, wld = wld0 * r, wd = wd0 * r, wt = wt0 * r;
  // Translucent (kind 1) and diffuse (kind 3) closures, in this order: the layers' pair, then
  // the residual's (raywave_mapping_by_kind reads them by position).
  auto lambert = [&q](int kind, vec3 w) {
    RaywaveClosure cl;
    cl.kind = kind;
    cl.N = vec3(0, 0, 1);
    cl.weight = {w.x, w.y, w.z};
    std::array<float, 3>& sum = kind == 1 ? q.transl_w : q.diffuse_w;
    for (size_t c = 0; c < 3; ++c) sum[c] += cl.weight[c];
    q.list.push_back(cl);
  };
  lambert(1, wlt);
  lambert(3, wld);
  lambert(3, wd);
  lambert(1, wt);
  RaywaveClosure tp;
  tp.kind = 4;
  tp.N = vec3(0, 0, 1);
  for (int c = 0; c < 3; ++c) {
    float sampled = 0;
    for (int k = 0; k < q.tiles; ++k) sampled += q.tile_w[k] * q.p_out[k][size_t(c)];
    tp.weight[size_t(c)] = (1.0f - q.open) * (1.0f - sampled);
    // With the tables, no gap closures below LOOM_DIFFRACTION_MIN_GAP (as the shaders).
    if (d.diffraction.present && !diffraction_gap_sampled(1.0f - q.open)) tp.weight[size_t(c)] = 0;
  }
  q.list.push_back(tp);
}

/// The closure mixture the shaders emit at the point (Closures).
void prepare_closures(RaywavePoint::Impl& q, const RaywaveData& d, const PointFrame& f) {
  const DoubleLayerGrid& g = d.layers[f.side];
  float fac[LOOM_DOUBLE_LAYER_BLOCKS][4];
  for (int b = 0; b < LOOM_DOUBLE_LAYER_BLOCKS; ++b) {
    float s, tv;
    double_layer_uv(q.V, b, g.theta_count, g.phi_count, s, tv);
    sample_clamped(*d.factors[f.side], s, tv, fac[b]);
  }
  for (int c = 0; c < 3; ++c) {
    q.k_b[size_t(c)] = fac[0][c];
    q.k_f[size_t(c)] = fac[1][c];
  }
  vec3 t_fwd(0, 0, 0);  // the lobes' part of T (raywave_lobe_forward), e_f added after them
  vec3 used(0, 0, 0);   // what the closures so far send out (raywave_energy_budget)
  int lobe_index = 0;   // over f_refl's lobes, then f_high's
  add_lobe_closures(q, d, f, d.yarn[f.y].refl, *d.nodes_refl[f.y], nullptr, t_fwd, used,
                    lobe_index);
  add_lobe_closures(q, d, f, d.yarn[f.y].high, *d.nodes_high[f.y], d.tint[f.y], t_fwd, used,
                    lobe_index);
  add_diffuse_closures(q, d, f, t_fwd, used);
}

}  // namespace

RaywavePoint::Impl raywave_prepare(const RaywaveData& d, const SurfacePoint& p_in, vec3 wo,
                                   Evaluator e, bool gap_diffraction) {
  PointFrame f;
  // Texels and absorption outside their ranges are brought back first (guard_surface_point).
  f.p = guard_surface_point(p_in);
  const SurfacePoint& p = f.p;
  for (int y = 0; y < 2; ++y)
    for (size_t c = 0; c < 3; ++c) f.sigma[y][c] = guard_sigma(d.sigma_rgb[y][c]);
  RaywavePoint::Impl q;
  q.e = e;
  if (!(std::isfinite(wo.x) && std::isfinite(wo.y) && std::isfinite(wo.z)) || wo.z == 0.0f)
    return q;
  q.valid = true;
  q.back = wo.z < 0;
  q.V = normalize(vec3(wo.x, wo.y, std::fabs(wo.z)));
  q.t = p.t;
  q.s = float(d.blend);
  f.y = p.kind > 1.5f ? 1 : 0;
  raywave_ply_space(q.V, p.t, p.n_p, q.xp, q.yp, f.theta_i, f.h);
  q.open = 1.0f - std::clamp(p.gap, 0.0f, 1.0f);
  if (d.noise.present) {
    q.noise = &d.noise;
    noise_pick(p.ply_id, p.along, d.noise.instances, q.noise_instance, q.noise_shift);
    q.wi_ply = vec3(0.0f, std::cos(f.theta_i), std::sin(f.theta_i));
  }
  for (int k = 0; k < LOOM_HORIZON_DIRS; ++k) q.hor[k] = p.horizon[k];
  q.vis_v = q.back ? 1.0f : horizon_visibility(q.V, q.hor);
  f.side = q.back ? 1 : 0;
  for (size_t c = 0; c < 3; ++c) f.sig_layers[c] = 0.5 * (f.sigma[0][c] + f.sigma[1][c]);
  if (gap_diffraction && d.diffraction.present && diffraction_gap_sampled(p.gap))
    prepare_gap_diffraction(q, d, p);
  if (e == Evaluator::Model)
    prepare_model(q, d, f);
  else
    prepare_closures(q, d, f);
  return q;
}

namespace {

/// The model's gap diffraction at L (far side, tangent frame, V.z > 0): the open fraction times
/// obliquity times the pattern normalised to unit power (diffraction_sampling.h), the tiles
/// blended with their weights, the table read bilinearly in t.
std::array<float, 3> gap_diffraction_model(const RaywavePoint::Impl& q, vec3 L) {
  std::array<float, 3> out{0, 0, 0};
  const GapDiffraction& g = *q.dif;
  const DiffractionTable& t = g.table;
  const float obl = diffraction_obliquity(L, q.V);
  const float tx = diffraction_table_coord(L.x + q.V.x), ty = diffraction_table_coord(L.y + q.V.y);
  for (int k = 0; k < q.tiles; ++k)
    for (int c = 0; c < 3; ++c) {
      const DiffractionSampler& cl = g.sampler[size_t(q.tile[k] * 3 + c)];
      const double total = 4 * (cl.outside + cl.spot);  // the whole plane: four quadrants
      if (!(total > 0)) continue;
      const double D = t.at(q.tile[k] % t.tiles_x, q.tile[k] / t.tiles_x, tx, ty, c);
      out[size_t(c)] += float(q.tile_w[k] * q.gap * obl * D / total);
    }
  return out;
}

/// The closures' gap diffraction at L, in expectation over the shader's random numbers: the
/// sampled lobes (diffraction_sampling.h, Cycles' refraction closure) integrated against the
/// distribution the sampling table realises (DiffractionSampler::probability of each quadrature
/// cell, exact for its integrable spikes on the axes), by midpoint quadrature over direction sums
/// within 6 kernel widths of L's.
std::array<float, 3> gap_diffraction_closures(const RaywavePoint::Impl& q, vec3 L) {
  std::array<float, 3> out{0, 0, 0};
  const GapDiffraction& g = *q.dif;
  // 13 x 13 points over +-4 kernel widths: 0.994 of a lobe's integral (measured; 25 x 25 over
  // +-6 widths gives the same).
  const int n = 13;
  const float half = 4.0f * float(LOOM_DIFFRACTION_KERNEL_RAD), ds = 2 * half / n;
  const vec3 Ng(0, 0, 1);
  const float sx0 = L.x + q.V.x, sy0 = L.y + q.V.y;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      const float sx = sx0 - half + (a + 0.5f) * ds, sy = sy0 - half + (b + 0.5f) * ds;
      vec3 Ls, N;
      if (!diffraction_light_direction(q.V, sx, sy, Ls)) continue;
      float alpha;
      if (!diffraction_lobe_closure(q.V, Ls, N, alpha)) continue;  // (given to transparent())
      float ls, lt, E[4];
      microfacet_albedo_uv(dot(N, q.V), alpha, ls, lt);
      sample_clamped(*q.albedo_lut, ls, lt, E);
      const cycles::MicrofacetRefraction cl(cycles::ensure_valid_specular_reflection(Ng, q.V, N),
                                            alpha, float(LOOM_RAYWAVE_ETA), Ng, q.V,
                                            cycles::Distribution::Beckmann);
      const float f = cl.eval(L);
      if (!(f > 0)) continue;
      for (int k = 0; k < q.tiles; ++k)
        for (int c = 0; c < 3; ++c) {
          const double prob = g.sampler[size_t(q.tile[k] * 3 + c)].probability(
              sx - 0.5 * ds, sx + 0.5 * ds, sy - 0.5 * ds, sy + 0.5 * ds);
          // LOOM_DIFFRACTION_SAMPLES lobes per channel, each of this distribution.
          const float w = LOOM_DIFFRACTION_SAMPLES *
                          diffraction_lobe_weight(q.V, Ls, q.p_out[k][size_t(c)], E[1]);
          out[size_t(c)] += float(q.tile_w[k] * q.gap * prob * w * f);
        }
    }
  return out;
}

}  // namespace

void raywave_model_noise(const RaywavePoint::Impl& q, const Vec3d& lp, float nr[4], float nh[4]) {
  for (int c = 0; c < 4; ++c) nr[c] = nh[c] = 1;
  if (!q.noise) return;
  const vec3 w(float(lp.x), float(lp.y), float(lp.z));
  float u, v;
  noise_tile_uv(noise_memory_effect_direction(q.wi_ply, w), q.noise_shift, q.noise_instance,
                q.noise->instances, u, v);
  sample_periodic(*q.noise->refl, u, noise_level_v(v, 0, LOOM_NOISE_LEVELS), nr);
  noise_tile_uv(w, q.noise_shift, q.noise_instance, q.noise->instances, u, v);
  sample_periodic(*q.noise->high, u, noise_level_v(v, 0, LOOM_NOISE_LEVELS), nh);
}

namespace {

std::array<float, 3> eval_prepared(const RaywavePoint::Impl& q, vec3 wi) {
  const Evaluator e = q.e;
  std::array<float, 3> out = {0, 0, 0};
  if (!q.valid || !(std::isfinite(wi.x) && std::isfinite(wi.y) && std::isfinite(wi.z)))
    return out;
  const vec3 L = normalize(q.back ? vec3(wi.x, wi.y, -wi.z) : wi);
  if (e == Evaluator::Model) {
    const Vec3d lp{dot(L, q.xp), dot(L, q.yp), dot(L, q.t)};
    // Eq. S.39: f_refl N_r(w'_o) + f_high N_h(w_o), the tiles themselves (level 0).
    float nr[4], nh[4];
    raywave_model_noise(q, lp, nr, nh);
    for (int c = 0; c < 3; ++c) {
      const size_t cc = size_t(c);
      const double f = asg_mixture_eval(q.refl_rgb[cc], lp) * nr[c] +
                       asg_mixture_eval(q.high[c], lp) * nh[c];
      double v;
      // the residual's lobes (asg_residual.h), within the budget's factor (raywave_lobes.h)
      const double lambert = std::fabs(L.z) / M_PI * q.rest_scale[cc];
      // double_layer_factors.h: backward R + k_b T, forward k_f T.
      if (L.z > 0) {
        const float vis_l = q.back ? 1.0f : horizon_visibility(L, const_cast<float*>(q.hor));
        v = q.open * q.vis_v *
            (vis_l * f + (q.res_b[cc] + q.k_b[cc] * q.t_fwd[cc]) * lambert);
      } else {
        v = q.open * q.k_f[cc] *
            ((1 - q.s) * (f + q.res_f[cc] * lambert) + q.s * q.t_fwd[cc] * lambert);
      }
      out[size_t(c)] = float(v);
    }
    if (q.dif && L.z < 0) {
      const auto g = gap_diffraction_model(q, L);
      for (int c = 0; c < 3; ++c) out[size_t(c)] += g[size_t(c)];
    }
    return out;
  }
  const vec3 n(0, 0, 1);
  const float tr = cycles::translucent_eval(n, L, n), df = cycles::diffuse_eval(n, L, n);
  for (int c = 0; c < 3; ++c)
    out[size_t(c)] = q.transl_w[size_t(c)] * tr + q.diffuse_w[size_t(c)] * df;
  if (q.dif && L.z < 0) {
    const auto g = gap_diffraction_closures(q, L);
    for (int c = 0; c < 3; ++c) out[size_t(c)] += g[size_t(c)];
  }
  for (size_t i = 0; i < q.refr.size(); ++i) {
    const float g = q.refr[i].eval(L);
    for (int c = 0; c < 3; ++c) out[size_t(c)] += q.refr_w[i][size_t(c)] * g;
  }
  for (size_t i = 0; i < q.mf.size(); ++i) {
    const float g = q.mf[i].eval(L);
    for (int c = 0; c < 3; ++c) out[size_t(c)] += q.mf_w[i][size_t(c)] * g;
  }
  return out;
}

}  // namespace

RaywavePoint::RaywavePoint(const RaywaveData& d, const SurfacePoint& p, vec3 wo, Evaluator e,
                           bool gap_diffraction)
    : impl_(std::make_shared<const Impl>(raywave_prepare(d, p, wo, e, gap_diffraction))) {}

std::array<float, 3> RaywavePoint::eval(vec3 wi) const { return eval_prepared(*impl_, wi); }

const std::vector<RaywaveClosure>& RaywavePoint::closures() const { return impl_->list; }

std::array<float, 3> raywave_eval(const RaywaveData& d, const SurfacePoint& p, vec3 wi, vec3 wo,
                                  Evaluator e) {
  return RaywavePoint(d, p, wo, e).eval(wi);
}

}  // namespace loom
