// loom-bake eval diffraction, noise, colour: the ray-wave tier's wave optics and colour, probed
// (Gaussian-beam aperture diffraction, Eq. S.34-S.35; the speckle noise tiles, Eq. S.37-S.38;
// a colour through the absorption data, Eq. S.42).
#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/absorption.h"
#include "loom/aperture_diffraction.h"
#include "loom/atlas.h"
#include "loom/cli_values.h"
#include "loom/colour.h"

using nlohmann::json;

namespace loom::cli {

namespace {

struct DiffractionArgs {
  std::string aperture, wi, wo;
  double waist = 10, lambda = 550;
};

int eval_diffraction(const DiffractionArgs& a) {
  const auto A = loom::parse_cli_aperture("--aperture", a.aperture);
  const auto wi = loom::parse_cli_direction("--wi", a.wi);
  const auto wo = loom::parse_cli_direction("--wo", a.wo);
  const loom::Aperture ap{A[0], A[1], A[2], A[3]};
  const double lambda_um = a.lambda * 1e-3;
  const std::array<double, 3> xi{wi[0], wi[1], wi[2]}, xo{wo[0], wo[1], wo[2]};
  const auto K = loom::aperture_K(ap, (wi[0] + wo[0]) / lambda_um, (wi[1] + wo[1]) / lambda_um,
                                  a.waist);
  const double I = loom::aperture_intensity(ap, a.waist, lambda_um, xi, xo);
  std::cout << json{{"intensity", I},
                    {"K", {K.real(), K.imag()}},
                    {"f", {(wi[0] + wo[0]) / lambda_um, (wi[1] + wo[1]) / lambda_um}},
                    {"beam_power", loom::beam_power(a.waist)},
                    {"aperture_power", loom::aperture_power(ap, a.waist)},
                    {"units", "lengths um, f 1/um, K um^2, intensity um^2 (Eq. S.35)"}}
                   .dump()
            << std::endl;
  return 0;
}

/// Per tile, instance and band of the atlas's speckle noise: mean, variance, min, max.
int eval_noise(const std::string& dir) {
  auto atlas = loom::load_atlas(dir);
  const json& m = atlas.manifest;
  const json* nj = m.contains("raywave") ? &m["raywave"] : nullptr;
  if (!nj || !nj->contains("noise") || (*nj)["noise"]["files"].empty()) {
    std::cerr << "error: " << dir
              << ": no speckle noise tiles (bake a ray-wave spec with wave.noise on)\n";
    return 2;
  }
  const json& n = (*nj)["noise"];
  const int H = n["theta_count"], inst = n["instances"];
  json out = json::object();
  for (auto& [which, file] : n["files"].items()) {
    const auto& img = atlas.map(file.get<std::string>());
    json per = json::array();
    for (int j = 0; j < inst; ++j) {
      json bands = json::array();
      for (int c = 0; c < img.channels; ++c) {
        double sum = 0, sum2 = 0, lo = INFINITY, hi = -INFINITY;
        for (int y = j * H; y < (j + 1) * H; ++y)
          for (int x = 0; x < img.width; ++x) {
            const double v = img.px(x, y)[c];
            sum += v, sum2 += v * v, lo = std::min(lo, v), hi = std::max(hi, v);
          }
        const double cnt = double(H) * img.width, mean = sum / cnt;
        bands.push_back({{"band_nm", n["band_nm"][size_t(c)]},
                         {"mean", mean},
                         {"variance", sum2 / cnt - mean * mean},
                         {"min", lo},
                         {"max", hi}});
      }
      per.push_back({{"instance", j}, {"bands", bands}});
    }
    out[which] = per;
  }
  std::cout << out.dump() << std::endl;
  return 0;
}

int eval_colour(const std::string& rgb_s, const std::string& dir, const std::string& yarn) {
  const auto rgb = loom::parse_cli_rgb01("--rgb", rgb_s);
  auto atlas = loom::load_atlas(dir);
  const json& m = atlas.manifest;
  const json y = m.contains("raywave") ? m["raywave"]["yarns"].value(yarn, json()) : json();
  if (!y.is_object() || !y.contains("absorption")) {
    std::cerr << "error: " << dir
              << ": no absorption data (bake a ray-wave spec; this atlas has tier "
              << m.value("tier", "?") << ")\n";
    return 2;
  }
  const json& a = y["absorption"];
  loom::AbsorptionCurve curve;
  curve.sigma_per_mm = a["curve"]["sigma_per_mm"].get<std::vector<double>>();
  curve.energy = a["curve"]["energy"].get<std::vector<double>>();
  loom::AbsorptionFit fit;
  fit.a = a["s42"]["a_mm"], fit.b = a["s42"]["b"];
  const double sigma_max = y["high"]["sigma_per_mm"].back();
  // The atlas's own colour configuration (a config file, or the built-in one).
  std::string cfg = m.contains("colour") ? m["colour"].value("config", "") : "";
  if (cfg.rfind("loom-builtin", 0) == 0) cfg.clear();
  const loom::ColourConverter cc(cfg);
  const loom::SpectralUpsampler up(cc, 5.0);
  const auto ya = loom::yarn_absorption({rgb[0], rgb[1], rgb[2]}, up, fit, curve, sigma_max);
  json samples = json::array();
  for (size_t k = 0; k < ya.lambda_nm.size(); k += 4)  // every 20 nm
    samples.push_back({{"lambda_nm", ya.lambda_nm[k]},
                       {"reflectance", ya.spectrum(ya.lambda_nm[k])},
                       {"sigma_per_mm", ya.sigma_per_mm[k]},
                       {"sigma_s42_per_mm", ya.sigma_s42_per_mm[k]}});
  std::cout << json{{"rgb", rgb},
                    {"sigma", samples},
                    {"sigma_rgb_per_mm", ya.sigma_rgb},
                    {"rgb_spectrum", ya.rgb_spectrum},
                    {"rgb_reconstructed", ya.rgb_ply},
                    {"rgb_reconstructed_s42", ya.rgb_s42},
                    {"s42", {{"a_mm", fit.a}, {"b", fit.b}}}}
                   .dump()
            << std::endl;
  return 0;
}

}  // namespace

void add_eval_diffraction(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<DiffractionArgs>();
  auto* c = eval.add_subcommand(
      "diffraction",
      "Gaussian-beam aperture diffraction (Eq. S.34, S.35) for one wavelength and direction pair");
  c->add_option("--aperture", a->aperture,
                "XW,XE,YS,YN: the rectangle [XW, XE] x [YS, YN] in um, relative to the beam "
                "centre (inf and -inf allowed)")
      ->required();
  c->add_option("--waist", a->waist, "beam waist w_0 in um (Eq. S.25)")
      ->check(finite_range(1e-3, 1e6));
  c->add_option("--lambda", a->lambda, "wavelength in nm")->check(finite_range(1.0, 1e5));
  c->add_option("--wi", a->wi, "X,Y,Z towards the light, aperture frame (z normal)")->required();
  c->add_option("--wo", a->wo, "X,Y,Z towards the receiver on the far side")->required();
  out.push_back({c, [a] { return eval_diffraction(*a); }});
}

void add_eval_noise(CLI::App& eval, Commands& out) {
  struct Args {
    std::string atlas;
    bool stats = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = eval.add_subcommand(
      "noise", "statistics of a ray-wave atlas's speckle noise tiles (Eq. S.37, S.38)");
  c->add_option("--atlas", a->atlas, "ray-wave atlas")->required();
  c->add_flag("--stats", a->stats,
              "per tile, instance and band: mean (1 by construction), variance, min, max")
      ->required();
  out.push_back({c, [a] { return eval_noise(a->atlas); }});
}

void add_eval_colour(CLI::App& eval, Commands& out) {
  struct Args {
    std::string rgb, atlas, yarn = "warp";
  };
  auto a = std::make_shared<Args>();
  auto* c = eval.add_subcommand(
      "colour", "a colour through a ray-wave atlas's absorption data: sigma(lambda) (Eq. S.42) "
                "and the RGB the ply reflects with it");
  c->add_option("--rgb", a->rgb, "R,G,B scene-linear, each in [0, 1]")->required();
  c->add_option("--atlas", a->atlas, "ray-wave atlas")->required();
  c->add_option("--yarn", a->yarn, "warp | weft (whose ply model)")
      ->check(CLI::IsMember({"warp", "weft"}));
  out.push_back({c, [a] { return eval_colour(a->rgb, a->atlas, a->yarn); }});
}

}  // namespace loom::cli
