// loom-bake eval asg, plysim, raywave, tables, lobes: the ply scattering of the ray-wave tier,
// simulated (plysim) and as the atlas's fitted ASG lobes (Eq. S.1, S.8, S.12), for probes and
// plots.
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/asg_residual.h"
#include "loom/atlas.h"
#include "loom/cli_values.h"
#include "loom/ply_scattering.h"
#include "loom/ply_tables.h"
#include "loom/shading.h"
#include "loom/spec.h"

using nlohmann::json;

namespace loom::cli {

namespace {

/// Index of the grid value nearest to x (the first of equals).
size_t nearest_node(const std::vector<double>& g, double x) {
  size_t best = 0;
  for (size_t i = 1; i < g.size(); ++i)
    if (std::fabs(g[i] - x) < std::fabs(g[best] - x)) best = i;
  return best;
}

/// The ray simulation of the grid slice of an atlas's ply tables nearest to (theta_i, h),
/// identical to the bake's (same seed), at sigma = 0 and `sigma`: what eval raywave --raw and
/// eval lobes --raw compare the fit with. For a multi-ply yarn this is one ply's scattering
/// while the tables hold the yarn's (Eq. S.13).
struct NearestSlice {
  loom::PlySimSlice slice;
  loom::PlySimSettings settings;
  double theta_i = 0, h = 0;
  bool multi_ply = false;
  /// Simulated f_refl + f_high (at `sigma`) in the bin of direction w.
  double value(const loom::Vec3d& w, double* refl = nullptr, double* high = nullptr) const {
    int bt, bp;
    loom::ply_sim_bin_of(settings, w, bt, bp);
    const size_t bins = size_t(settings.theta_o_count) * size_t(settings.phi_o_count);
    const size_t b = size_t(bt) * size_t(settings.phi_o_count) + size_t(bp);
    const double r = slice.refl[b], hh = slice.high[(settings.sigmas.size() - 1) * bins + b];
    if (refl) *refl = r;
    if (high) *high = hh;
    return r + hh;
  }
};

NearestSlice simulate_nearest_slice(const loom::Atlas& atlas, const loom::AsgTable& high,
                                    const std::string& yarn, double theta_i, double h,
                                    double sigma) {
  auto res = loom::parse_spec(atlas.manifest.value("spec", json()));
  if (!res.ok()) throw std::runtime_error("the atlas's spec does not parse: " + res.errors[0]);
  const loom::YarnSpec& y = yarn == "weft" ? res.spec.weft : res.spec.warp;
  NearestSlice out;
  out.settings = loom::ply_sim_settings(res.spec.quality);
  const size_t m = nearest_node(high.theta_i, theta_i), hn = nearest_node(high.h, h);
  out.settings.sigmas = {0.0};
  if (sigma > 0) out.settings.sigmas.push_back(sigma);
  auto p = loom::ply_params_from_yarn(y);
  loom::PlyGeometry g(p, loom::make_ply_fibers(p, 0, 0));
  out.slice = loom::simulate_ply_slice(g, y.ior, out.settings, high.theta_i[m], high.h[hn],
                                       m * high.h.size() + hn);
  out.theta_i = high.theta_i[m], out.h = high.h[hn], out.multi_ply = y.plies > 1;
  return out;
}

const char* slice_model(const NearestSlice& sl) {
  return sl.multi_ply ? "single ply (the tables are multi-ply)" : "single ply";
}

/// Where in an atlas's ply tables a probe looks: --atlas, --theta-i, --h, --sigma, --yarn.
struct SliceArgs {
  std::string atlas, yarn = "warp";
  double theta = 0, h = 0, sigma = 0;
};

void add_slice_options(CLI::App* c, SliceArgs& s) {
  c->add_option("--atlas", s.atlas, "ray-wave atlas directory")->required();
  c->add_option("--theta-i", s.theta, "incident angle, degrees [-90, 90]")
      ->required()
      ->check(finite_range(-90.0, 90.0));
  c->add_option("--h", s.h, "offset across the ply, [-1, 1]")
      ->required()
      ->check(finite_range(-1.0, 1.0));
  c->add_option("--sigma", s.sigma, "fiber absorption, 1/mm, [0, 1e6]")
      ->check(finite_range(0.0, 1e6));
  c->add_option("--yarn", s.yarn, "warp | weft")->check(CLI::IsMember({"warp", "weft"}));
}

struct RaywaveArgs : SliceArgs {
  std::string wo;
  bool raw = false;
};

int eval_raywave(const RaywaveArgs& a) {
  const auto wo = loom::parse_cli_direction("--wo", a.wo);
  const loom::Vec3d w{wo[0], wo[1], wo[2]};
  auto atlas = loom::load_atlas(a.atlas);
  auto t = loom::load_ply_tables(atlas, a.yarn);
  const double th = a.theta * M_PI / 180;
  double high = loom::asg_table_eval(t.high, th, a.h, a.sigma, w);
  double refl = loom::asg_table_eval(t.refl, th, a.h, 0, w);
  json out = {{"value", refl + high}, {"refl", refl}, {"high", high}, {"yarn", a.yarn},
              {"lobes", {{"high", t.high.lobes}, {"refl", t.refl.lobes}}}};
  {  // The energy the lobes miss at this (theta_i, h, sigma) (asg_residual.h).
    double hb, hf, rb, rf;
    loom::asg_residual_at(t.high, th, a.h, a.sigma, hb, hf);
    loom::asg_residual_at(t.refl, th, a.h, 0, rb, rf);
    out["residual_energy"] = {{"backward", hb + rb}, {"forward", hf + rf}};
  }
  if (a.raw) {
    const NearestSlice sl = simulate_nearest_slice(atlas, t.high, a.yarn, th, a.h, a.sigma);
    double raw_refl, raw_high;
    const double raw = sl.value(w, &raw_refl, &raw_high);
    out["raw"] = {{"value", raw}, {"refl", raw_refl}, {"high", raw_high},
                  {"model", slice_model(sl)},
                  {"theta_i_deg", sl.theta_i * 180 / M_PI}, {"h", sl.h},
                  {"rays", sl.settings.rays_per_slice}};
  }
  std::cout << out.dump() << std::endl;
  return 0;
}

struct LobesArgs : SliceArgs {
  int res = 48;
  bool raw = false, snap = false;
};

int eval_lobes(const LobesArgs& a) {
  const auto atlas = loom::load_atlas(a.atlas);
  const auto t = loom::load_ply_tables(atlas, a.yarn);
  double th = a.theta * M_PI / 180, lh = a.h;
  if (a.snap)
    th = t.high.theta_i[nearest_node(t.high.theta_i, th)],
    lh = t.high.h[nearest_node(t.high.h, lh)];
  const auto high = loom::asg_table_lobes(t.high, th, lh, a.sigma);
  const auto refl = loom::asg_table_lobes(t.refl, th, lh, 0);
  // Ply space: z along the ply axis (the ASG frame of Eq. S.2); elevation from the ply's
  // normal plane, as in eval tables. Row r at elevation -90 + 180 (r + 0.5) / res.
  const int rows = a.res, cols = 2 * a.res;
  std::vector<loom::Vec3d> dirs;
  for (int r = 0; r < rows; ++r) {
    const double el = -M_PI / 2 + M_PI * (r + 0.5) / rows;
    for (int c = 0; c < cols; ++c) {
      const double az = -M_PI + 2 * M_PI * (c + 0.5) / cols;
      dirs.push_back({std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)});
    }
  }
  auto on_grid = [&](auto&& f) {
    json rowsj = json::array();
    for (int r = 0; r < rows; ++r) {
      json row = json::array();
      for (int c = 0; c < cols; ++c) row.push_back(f(dirs[size_t(r) * size_t(cols) + size_t(c)]));
      rowsj.push_back(row);
    }
    return rowsj;
  };
  auto grid = [&](const std::vector<loom::AsgLobe>& ls) {
    return on_grid([&](const loom::Vec3d& d) { return loom::asg_mixture_eval(ls, d); });
  };
  auto each = [&](const std::vector<loom::AsgLobe>& ls) {
    json out = json::array();
    for (const auto& l : ls)
      out.push_back({{"theta_z", l.theta_z}, {"phi_z", l.phi_z}, {"phi_xy", l.phi_xy},
                     {"mu1", l.mu1}, {"mu2", l.mu2}, {"c", l.c},
                     {"values", grid({l})}});
    return out;
  };
  std::vector<loom::AsgLobe> all = high;
  all.insert(all.end(), refl.begin(), refl.end());
  json out = {{"theta_i_deg", th * 180 / M_PI}, {"h", lh}, {"sigma_per_mm", a.sigma},
              {"yarn", a.yarn},
              {"grid", {{"rows", rows}, {"cols", cols},
                        {"elevation", "row r: -90 + 180 (r + 0.5) / rows degrees"},
                        {"azimuth", "column c: -180 + 360 (c + 0.5) / cols degrees"}}},
              {"high", each(high)}, {"refl", each(refl)}, {"total", grid(all)}};
  if (a.raw) {
    const NearestSlice sl = simulate_nearest_slice(atlas, t.high, a.yarn, th, lh, a.sigma);
    out["raw"] = {{"values", on_grid([&](const loom::Vec3d& d) { return sl.value(d); })},
                  {"theta_i_deg", sl.theta_i * 180 / M_PI},
                  {"h", sl.h},
                  {"model", slice_model(sl)}};
  }
  std::cout << out.dump() << std::endl;
  return 0;
}

/// f = f_refl + f_high of two atlases over 9 x 9 (theta_i, h) inside the grids, the
/// reference's absorption levels, and a 32 x 64 (theta_o, phi_o) midpoint grid weighted by
/// solid angle: the relative L1 per absorption level and over all.
int eval_tables(const std::string& atlas, const std::string& reference, const std::string& yarn) {
  auto a = loom::load_atlas(atlas), r = loom::load_atlas(reference);
  auto ta = loom::load_ply_tables(a, yarn), tr = loom::load_ply_tables(r, yarn);
  json per_sigma = json::array();
  double num_all = 0, den_all = 0;
  for (double sg : tr.high.sigmas) {
    double num = 0, den = 0;
    for (int i = 0; i < 9; ++i)
      for (int j = 0; j < 9; ++j) {
        const double th = tr.high.theta_i.front() +
                          (tr.high.theta_i.back() - tr.high.theta_i.front()) * (i + 0.5) / 9;
        const double h = -1 + 2 * (j + 0.5) / 9;
        auto la = loom::asg_table_lobes(ta.high, th, h, sg);
        auto lr = loom::asg_table_lobes(tr.high, th, h, sg);
        auto ra = loom::asg_table_lobes(ta.refl, th, h, 0);
        auto rr = loom::asg_table_lobes(tr.refl, th, h, 0);
        for (int t = 0; t < 32; ++t) {
          const double el = -M_PI / 2 + M_PI * (t + 0.5) / 32, w = std::cos(el);
          for (int q = 0; q < 64; ++q) {
            const double az = -M_PI + 2 * M_PI * (q + 0.5) / 64;
            loom::Vec3d v{std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
            const double fa = loom::asg_mixture_eval(la, v) + loom::asg_mixture_eval(ra, v);
            const double fr = loom::asg_mixture_eval(lr, v) + loom::asg_mixture_eval(rr, v);
            num += w * std::fabs(fa - fr);
            den += w * std::fabs(fr);
          }
        }
      }
    per_sigma.push_back({{"sigma_per_mm", sg}, {"relative_l1", den > 0 ? num / den : 0.0}});
    num_all += num, den_all += den;
  }
  std::cout << json{{"relative_l1", den_all > 0 ? num_all / den_all : 0.0},
                    {"per_sigma", per_sigma},
                    {"yarn", yarn},
                    {"lobes", {{"atlas", ta.high.lobes}, {"reference", tr.high.lobes}}}}
                   .dump()
            << std::endl;
  return 0;
}

struct PlysimArgs {
  std::string spec, yarn = "warp", quality;
  double theta = 0, h = 0, sigma = 0;
  int rays = 0;
  uint64_t seed = 1;
};

int eval_plysim(const PlysimArgs& a) {
  auto res = loom::load_spec(a.spec, a.quality);
  if (!res.ok()) return report_spec_errors(a.spec, res.errors);
  const loom::YarnSpec& y = a.yarn == "weft" ? res.spec.weft : res.spec.warp;
  auto p = loom::ply_params_from_yarn(y);
  auto st = loom::ply_sim_settings(res.spec.quality);
  if (a.rays > 0) st.rays_per_slice = a.rays;
  st.sigmas = {0.0};
  if (a.sigma > 0) st.sigmas.push_back(a.sigma);
  st.seed = a.seed;
  loom::PlyGeometry g(p, loom::make_ply_fibers(p, 0, 0));
  auto sl = loom::simulate_ply_slice(g, y.ior, st, a.theta * M_PI / 180, a.h, 0);
  const auto& e = sl.energy.back();
  std::cout << json{{"reflected", e.reflected},
                    {"higher_order", e.higher_order},
                    {"absorbed", e.absorbed},
                    {"unscattered", e.unscattered},
                    {"truncated", e.truncated},
                    {"rays", st.rays_per_slice},
                    {"sigma_per_mm", a.sigma},
                    {"yarn", a.yarn}}
                   .dump()
            << std::endl;
  return 0;
}

}  // namespace

void add_eval_asg(CLI::App& eval, Commands& out) {
  struct Args {
    std::string lobe, v;
  };
  auto a = std::make_shared<Args>();
  auto* c = eval.add_subcommand(
      "asg", "one ASG lobe (Eq. S.1, S.2) at a direction, and its integral over the sphere");
  c->add_option("--lobe", a->lobe, "THETA_Z,PHI_Z,PHI_XY,MU1,MU2,C (angles in radians)")
      ->required();
  c->add_option("--v", a->v, "X,Y,Z direction in ply space (normalised)")->required();
  out.push_back({c, [a] {
    const auto q = loom::parse_cli_asg_lobe("--lobe", a->lobe);
    const auto v = loom::parse_cli_direction("--v", a->v);
    namespace sh = loom::shading;
    sh::vec3 dir = sh::normalize(sh::vec3(float(v[0]), float(v[1]), float(v[2])));
    float val = sh::asg_eval(float(q[0]), float(q[1]), float(q[2]), float(q[3]), float(q[4]),
                             float(q[5]), dir);
    float integral = sh::asg_integral(float(q[3]), float(q[4]), float(q[5]));
    std::cout << json{{"value", val}, {"integral", integral}}.dump() << std::endl;
    return 0;
  }});
}

void add_eval_plysim(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<PlysimArgs>();
  auto* c = eval.add_subcommand(
      "plysim", "simulate one (theta_i, h) slice of ply scattering and print energy fractions");
  c->add_option("--spec", a->spec, spec_help())->required();
  c->add_option("--yarn", a->yarn, "warp | weft")->check(CLI::IsMember({"warp", "weft"}));
  c->add_option("--theta-i", a->theta, "incident angle from the ply's normal plane, "
                                       "degrees [-90, 90]")
      ->required()
      ->check(finite_range(-90.0, 90.0));
  c->add_option("--h", a->h, "beam offset across the ply, [-1, 1]")
      ->required()
      ->check(finite_range(-1.0, 1.0));
  c->add_option("--sigma", a->sigma, "fiber absorption, 1/mm, [0, 1e6]")
      ->check(finite_range(0.0, 1e6));
  c->add_option("--rays", a->rays, "rays (default: the quality preset's per slice)")
      ->check(CLI::Range(1, 100000000));
  c->add_option("--quality", a->quality, "draft | preview | final | reference");
  c->add_option("--seed", a->seed, "random seed");
  out.push_back({c, [a] { return eval_plysim(*a); }});
}

void add_eval_raywave(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<RaywaveArgs>();
  auto* c = eval.add_subcommand(
      "raywave", "the fitted ply scattering of a ray-wave atlas (Eq. S.8, S.12) at one direction");
  add_slice_options(c, *a);
  c->add_option("--wo", a->wo, "X,Y,Z outgoing direction in ply space")->required();
  c->add_flag("--raw", a->raw,
              "also re-run the simulation of the nearest grid slice (identical to the "
              "bake's: same seed) and print its value in the bin of --wo");
  out.push_back({c, [a] { return eval_raywave(*a); }});
}

void add_eval_tables(CLI::App& eval, Commands& out) {
  struct Args {
    std::string atlas, reference, yarn = "warp";
  };
  auto a = std::make_shared<Args>();
  auto* c = eval.add_subcommand(
      "tables", "error of a ray-wave atlas's fitted ply scattering against another (e.g. the "
                "reference preset's): relative L1 over the sphere");
  c->add_option("--atlas", a->atlas, "ray-wave atlas to measure")->required();
  c->add_option("--reference", a->reference, "ray-wave atlas to compare with")->required();
  c->add_option("--yarn", a->yarn, "warp | weft")->check(CLI::IsMember({"warp", "weft"}));
  out.push_back({c, [a] { return eval_tables(a->atlas, a->reference, a->yarn); }});
}

void add_eval_lobes(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<LobesArgs>();
  auto* c = eval.add_subcommand(
      "lobes", "each fitted lobe of a ray-wave atlas (Eq. S.1, S.7, S.11) at (theta_i, h, "
               "sigma) on an (elevation, azimuth) grid of ply-space directions, for plots");
  add_slice_options(c, *a);
  c->add_option("--res", a->res, "grid rows (elevation); columns (azimuth) 2x, [4, 512]")
      ->check(CLI::Range(4, 512));
  c->add_flag("--raw", a->raw,
              "also the simulated scattering of the nearest grid slice on the same grid");
  c->add_flag("--snap", a->snap,
              "evaluate the lobes at the tables' grid slice (theta_i, h) nearest to the one "
              "asked, where the simulation is (to compare the two)");
  out.push_back({c, [a] { return eval_lobes(*a); }});
}

}  // namespace loom::cli
