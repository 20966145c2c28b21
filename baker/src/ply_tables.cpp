#include "loom/ply_tables.h"

#include "loom/asg_residual.h"
#include "loom/multi_ply.h"
#include "loom/shading.h"

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <stdexcept>

namespace loom {

using nlohmann::json;

PlyTables bake_ply_tables(const YarnSpec& y, Quality q, const ProgressFn& progress,
                          const std::string& stage, bool multi_ply) {
  PlyTables out;
  const PlyParams p = ply_params_from_yarn(y);
  out.sim = ply_sim_settings(q);
  if (progress) progress(stage, 0.0);
  auto t0 = std::chrono::steady_clock::now();
  PlySimResult sim = simulate_ply_scattering(p, y.ior, out.sim);
  if (y.plies > 1 && multi_ply) {  // Eq. S.13-S.19; single-ply yarns skip it
    out.multi = multi_ply_geometry(y, sim);
    sim = multi_ply_scattering(sim, *out.multi);
  }
  auto t1 = std::chrono::steady_clock::now();
  if (progress) progress(stage, 0.5);
  out.high = asg_fit_high(sim, asg_fit_settings(q, false));
  out.refl = asg_fit_refl(sim, asg_fit_settings(q, true));
  out.high.residual = asg_fit_residual(sim, out.high, false);
  out.refl.residual = asg_fit_residual(sim, out.refl, true);
  auto t2 = std::chrono::steady_clock::now();
  if (progress) progress(stage, 1.0);
  out.rays = sim.rays;
  out.raw = std::move(sim);
  out.sim_seconds = std::chrono::duration<double>(t1 - t0).count();
  out.fit_seconds = std::chrono::duration<double>(t2 - t1).count();
  return out;
}

Image asg_nodes_image(const AsgTable& t) {
  const int rows = t.node_rows(), cols = t.node_cols(), L = t.lobes;
  Image img(cols * L * 2, rows, 4);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j)
      for (int l = 0; l < L; ++l) {
        const AsgLobe& q = t.node(i, j, l);
        float* a = img.px(shading::asg_node_column(0, l, j, cols, L), i);
        float* b = img.px(shading::asg_node_column(1, l, j, cols, L), i);
        a[0] = float(q.theta_z), a[1] = float(q.phi_z), a[2] = float(q.phi_xy), a[3] = float(q.mu1);
        b[0] = float(q.mu2), b[1] = float(q.c), b[2] = 0, b[3] = 0;
      }
  return img;
}

Image asg_scale_image(const AsgTable& t) {
  const int rows = t.node_rows(), cols = t.node_cols(), K = int(t.sigmas.size()), L = t.lobes;
  Image img(cols * L, rows * K, 1);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j)
      for (int k = 0; k < K; ++k)
        for (int l = 0; l < L; ++l) img.px(j * L + l, i * K + k)[0] = float(t.scale_at(k, i, j, l));
  return img;
}

Image asg_residual_image(const AsgTable& t) {
  const int M = int(t.theta_i.size()), N = int(t.h.size()), K = int(t.sigmas.size());
  if (t.residual.size() != size_t(M) * size_t(N) * size_t(K) * 2)
    throw std::logic_error("asg_residual_image: the table has no residual");
  Image img(2 * N, M * K, 1);
  for (int m = 0; m < M; ++m)
    for (int n = 0; n < N; ++n)
      for (int k = 0; k < K; ++k)
        for (int side = 0; side < 2; ++side)
          img.px(side * N + n, m * K + k)[0] =
              float(t.residual[size_t(((m * N + n) * K + k) * 2 + side)]);
  return img;
}

namespace {
json grid_json(const std::vector<double>& g) {
  return {{"min", g.front()}, {"max", g.back()}, {"count", g.size()}};
}
json table_json(const AsgTable& t) {
  // Mean residual energy per side at sigma = 0 (asg_residual.h), over the slices.
  double rb = 0, rf = 0;
  const size_t K = t.sigmas.size(), S = t.theta_i.size() * t.h.size();
  for (size_t s = 0; s < S && t.residual.size() == S * K * 2; ++s) {
    rb += t.residual[s * K * 2] / double(S);
    rf += t.residual[s * K * 2 + 1] / double(S);
  }
  return {{"lobes", t.lobes},
          {"residual_mean_sigma0", {{"backward", rb}, {"forward", rf}}},
          {"theta_i", grid_json(t.theta_i)},
          {"h", grid_json(t.h)},
          {"sigma_per_mm", t.sigmas},
          {"nrmse", t.nrmse},
          {"nrmse_per_sigma", t.nrmse_per_sigma},
          {"block_nrmse", t.block_nrmse}};
}
std::vector<double> grid_from(const json& g, const std::string& what) {
  if (!g.is_object() || !g.contains("min") || !g.contains("max") || !g.contains("count") ||
      !g["min"].is_number() || !g["max"].is_number() || !g["count"].is_number_integer() || g["count"].get<long long>() < 0)
    throw std::runtime_error(what + ": expected {min, max, count}");
  const double lo = g["min"], hi = g["max"];
  const size_t n = g["count"];
  if (n < 3 || n % 2 == 0 || n > 4097 || !(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi))
    throw std::runtime_error(what + ": count must be odd and in [3, 4097], min < max");
  std::vector<double> v;
  for (size_t i = 0; i < n; ++i) v.push_back(lo + (hi - lo) * double(i) / double(n - 1));
  return v;
}
}  // namespace

json ply_tables_manifest(const PlyTables& t, const std::string& yarn) {
  return {{"yarn", yarn},
          {"node_layout", kAsgNodeLayout},
          {"high", table_json(t.high)},
          {"refl", table_json(t.refl)},
          {"files",
           {{"high", "ply_high_" + yarn},
            {"high_scale", "ply_high_scale_" + yarn},
            {"refl", "ply_refl_" + yarn},
            {"high_residual", "ply_high_residual_" + yarn},
            {"refl_residual", "ply_refl_residual_" + yarn}}},
          {"simulation",
           {{"rays", t.rays},
            {"rays_per_slice", t.sim.rays_per_slice},
            {"theta_o_bins", t.sim.theta_o_count},
            {"phi_o_bins", t.sim.phi_o_count},
            {"seed", t.sim.seed},
            {"seconds", t.sim_seconds},  // simulation, and multi-ply for yarns of several plies
            {"includes_multi_ply", bool(t.multi)}}},
          {"fit_seconds", t.fit_seconds},
          {"multi_ply", t.multi ? json{{"plies", t.multi->plies},
                                       {"centre_distance", t.multi->centre_distance},
                                       {"twist_rad", t.multi->twist},
                                       {"residual_width_rad", kResidualWidth}}
                                : json(false)}};
}

AbsorptionCurve absorption_curve_from_manifest(const json& entry, const std::string& yarn) {
  AbsorptionCurve c;
  if (!entry.is_object() || !entry.contains("absorption")) return c;
  const std::string where = "raywave.yarns." + yarn + ".absorption.curve";
  const json& j = entry["absorption"].value("curve", json());
  if (!j.is_object() || !j.contains("sigma_per_mm") || !j.contains("energy") ||
      !j["sigma_per_mm"].is_array() || !j["energy"].is_array() ||
      j["sigma_per_mm"].size() != j["energy"].size() || j["energy"].size() < 2)
    throw std::runtime_error(where + ": expected arrays sigma_per_mm and energy of one length >= 2");
  for (size_t k = 0; k < j["energy"].size(); ++k) {
    const json &s = j["sigma_per_mm"][k], &e = j["energy"][k];
    if (!s.is_number() || !e.is_number() || !std::isfinite(s.get<double>()) ||
        !std::isfinite(e.get<double>()) || s.get<double>() < 0 || e.get<double>() < 0 ||
        e.get<double>() > 1 + 1e-6)
      throw std::runtime_error(where + ": expected sigma >= 0 and energy in [0, 1], finite");
    if (k > 0 && !(s.get<double>() > c.sigma_per_mm.back()))
      throw std::runtime_error(where + ".sigma_per_mm: must increase");
    c.sigma_per_mm.push_back(s.get<double>());
    c.energy.push_back(e.get<double>());
  }
  c.rays = j.value("rays", uint64_t(0));
  return c;
}

AbsorptionCurve layer_absorption_curve(const json& raywave) {
  const json& y = raywave.value("yarns", json());
  return mean_curve(absorption_curve_from_manifest(y.value("warp", json()), "warp"),
                    absorption_curve_from_manifest(y.value("weft", json()), "weft"));
}

AsgTable asg_table_from_images(const json& entry, const std::string& which, const Image& nodes,
                               const Image* scale, const Image* residual) {
  if (!entry.is_object() || !entry.contains(which) || !entry[which].is_object())
    throw std::runtime_error(fmt::format("raywave table entry has no \"{}\"", which));
  if (entry.value("node_layout", "") != kAsgNodeLayout)
    throw std::runtime_error(fmt::format("raywave tables: node layout \"{}\" is not this baker's "
                                         "\"{}\" (re-bake the atlas)",
                                         entry.value("node_layout", "none"), kAsgNodeLayout));
  const json& j = entry[which];
  AsgTable t;
  if (!j.contains("lobes") || !j["lobes"].is_number_integer() || j["lobes"] < 1 || j["lobes"] > 64)
    throw std::runtime_error(which + ".lobes: expected an integer in [1, 64]");
  t.lobes = j["lobes"];
  t.theta_i = grid_from(j.value("theta_i", json()), which + ".theta_i");
  t.h = grid_from(j.value("h", json()), which + ".h");
  if (!j.contains("sigma_per_mm") || !j["sigma_per_mm"].is_array() || j["sigma_per_mm"].empty())
    throw std::runtime_error(which + ".sigma_per_mm: expected a non-empty array");
  for (auto& s : j["sigma_per_mm"]) {
    if (!s.is_number() || !std::isfinite(s.get<double>()) || s.get<double>() < 0)
      throw std::runtime_error(which + ".sigma_per_mm: expected finite numbers >= 0");
    t.sigmas.push_back(s.get<double>());
  }
  for (size_t k = 1; k < t.sigmas.size(); ++k)
    if (!(t.sigmas[k] > t.sigmas[k - 1]))
      throw std::runtime_error(which + ".sigma_per_mm: must increase");
  t.nrmse = j.value("nrmse", 0.0);
  t.absorption = absorption_curve_from_manifest(entry, entry.value("yarn", std::string("?")));
  const int rows = t.node_rows(), cols = t.node_cols(), L = t.lobes;
  if (nodes.width != cols * L * 2 || nodes.height != rows || nodes.channels != 4)
    throw std::runtime_error(fmt::format("{} nodes: image is {}x{}x{}, the grids say {}x{}x4",
                                         which, nodes.width, nodes.height, nodes.channels,
                                         cols * L * 2, rows));
  for (int i = 0; i < rows; ++i)
    for (int jj = 0; jj < cols; ++jj)
      for (int l = 0; l < L; ++l) {
        const float* a = nodes.px(shading::asg_node_column(0, l, jj, cols, L), i);
        const float* b = nodes.px(shading::asg_node_column(1, l, jj, cols, L), i);
        t.nodes.push_back(AsgLobe{a[0], a[1], a[2], a[3], b[0], b[1]});
      }
  const int K = int(t.sigmas.size());
  t.scale.assign(size_t(rows * cols * K * L), 1.0);
  if (scale) {
    if (scale->width != cols * L || scale->height != rows * K || scale->channels != 1)
      throw std::runtime_error(fmt::format("{} scale-downs: image is {}x{}x{}, expected {}x{}x1",
                                           which, scale->width, scale->height, scale->channels,
                                           cols * L, rows * K));
    for (int i = 0; i < rows; ++i)
      for (int jj = 0; jj < cols; ++jj)
        for (int k = 0; k < K; ++k)
          for (int l = 0; l < L; ++l)
            t.scale_at(k, i, jj, l) = scale->px(jj * L + l, i * K + k)[0];
  } else if (K != 1) {
    throw std::runtime_error(which + ": several absorption levels but no scale-downs");
  }
  for (const AsgLobe& q : t.nodes)
    for (double v : {q.theta_z, q.phi_z, q.phi_xy, q.mu1, q.mu2, q.c})
      if (!std::isfinite(v)) throw std::runtime_error(which + " nodes: non-finite lobe parameter");
  if (residual) {
    const int M = int(t.theta_i.size()), N = int(t.h.size());
    if (residual->width != 2 * N || residual->height != M * K || residual->channels != 1)
      throw std::runtime_error(fmt::format("{} residual: image is {}x{}x{}, expected {}x{}x1",
                                           which, residual->width, residual->height,
                                           residual->channels, 2 * N, M * K));
    t.residual.resize(size_t(M) * size_t(N) * size_t(K) * 2);
    for (int m = 0; m < M; ++m)
      for (int n = 0; n < N; ++n)
        for (int k = 0; k < K; ++k)
          for (int side = 0; side < 2; ++side) {
            const float v = residual->px(side * N + n, m * K + k)[0];
            if (!std::isfinite(v) || v < 0)
              throw std::runtime_error(which + " residual: expected finite values >= 0");
            t.residual[size_t(((m * N + n) * K + k) * 2 + side)] = v;
          }
  }
  return t;
}

LoadedPlyTables load_ply_tables(const Atlas& a, const std::string& yarn) {
  const json& m = a.manifest;
  if (m.value("tier", "") != "raywave" || !m.contains("raywave"))
    throw std::runtime_error(fmt::format("the atlas is a \"{}\" atlas and has no ray-wave tables "
                                         "(bake the spec with \"model\": {{\"tier\": \"raywave\"}})",
                                         m.value("tier", "?")));
  LoadedPlyTables out;
  out.entry = m["raywave"]["yarns"].value(yarn, json());
  if (!out.entry.is_object())
    throw std::runtime_error(fmt::format("raywave.yarns.{}: missing", yarn));
  const json& f = out.entry["files"];
  for (const char* k : {"high", "high_scale", "refl", "high_residual", "refl_residual"})
    if (!f.is_object() || !f.contains(k) || !f[k].is_string())
      throw std::runtime_error(fmt::format("raywave.yarns.{}.files.{}: missing (an atlas from an "
                                           "older loom-bake: re-bake it)", yarn, k));
  const Image& scale = a.map(f["high_scale"].get<std::string>());
  out.high = asg_table_from_images(out.entry, "high", a.map(f["high"].get<std::string>()), &scale,
                                   &a.map(f["high_residual"].get<std::string>()));
  out.refl = asg_table_from_images(out.entry, "refl", a.map(f["refl"].get<std::string>()), nullptr,
                                   &a.map(f["refl_residual"].get<std::string>()));
  return out;
}

}  // namespace loom
