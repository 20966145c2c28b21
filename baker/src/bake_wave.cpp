// The wave-optics stages of a ray-wave bake (bake_stages.h): aperture diffraction (section 4)
// and speckle noise (section 5). Neither depends on the yarn colours.
#include <chrono>
#include <fmt/format.h>

#include "bake_stages.h"
#include "loom/diffraction_tables.h"
#include "loom/shading.h"
#include "loom/spectrum.h"
#include "loom/speckle_noise.h"

using nlohmann::json;

namespace loom {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

Image to_image(const DiffractionTable& t) {
  Image img(t.width(), t.height(), 3);
  std::copy(t.rgb.begin(), t.rgb.end(), img.data.begin());
  return img;
}

}  // namespace

json bake_diffraction_stage(const BakeContext& ctx) {
  const FabricSpec& spec = ctx.spec;
  if (!spec.wave.diffraction)
    return {{"mode", "delta"},
            {"reason", "wave.diffraction is off: delta transmission (the non-wave variant)"}};
  ctx.progress("diffraction", 0.0);
  const auto dt0 = std::chrono::steady_clock::now();
  const DiffractionSettings ds = diffraction_settings(spec.quality);
  const SpectralRgb srgb = spectral_rgb(ctx.cc, ds.step_nm);
  const double w0 = spec.wave.beam_waist_um;
  const auto gap = gap_widths(spec);
  json dif = {
      {"mode", "tables"},
      {"beam_waist_um", w0},
      {"d_cut_um", LOOM_DIFFRACTION_DCUT_WAISTS * w0},
      {"s_max", LOOM_DIFFRACTION_S_MAX},
      {"tile_size", ds.size},
      {"lambda_nm", {kLambdaMinNm, kLambdaMaxNm, ds.step_nm}},
      {"gap_um", {gap[0], gap[1]}},
      {"files", {{"edge", "diffraction_edge"}}},
      {"edge_tiles", ds.edge_tiles},
      {"layout",
       "RGB D_c(s) per unit incident power and solid angle (Eq. S.35 without the "
       "obliquity factor), tiles of tile_size^2 texels: texel (u, r) of a tile at "
       "|s_x| = s_max (u / (tile_size - 1))^2, |s_y| likewise with row r counted "
       "from the bottom (v = 0) (osl/include/loom/diffraction_table.h); gap tiles: column block i, row block "
       "j hold the beam centre offset (1 - (1 - (i, j) / (gap_offsets - 1))^2) gap_um "
       "/ 2 from the hole's centre; edge tiles: column block j holds x_w / d_cut = j / "
       "(edge_tiles - 1) (baker/include/loom/diffraction_tables.h)"}};
  ctx.out.write_table(to_image(diffraction_edge_table(w0, srgb, ds)), "diffraction_edge",
                      {"r", "g", "b"},
                      "ply-edge aperture diffraction (section 4.3; layout: manifest "
                      "raywave.diffraction.layout)");
  if (spec.components.gaps && gap[0] > 0 && gap[1] > 0) {
    const DiffractionTable gap_table = diffraction_gap_table(gap[0], gap[1], w0, srgb, ds);
    ctx.out.write_table(to_image(gap_table), "diffraction_gap", {"r", "g", "b"},
                        "gap aperture diffraction (section 4.1-4.2; layout: manifest "
                        "raywave.diffraction.layout)");
    dif["files"]["gap"] = "diffraction_gap";
    dif["gap_offsets"] = ds.gap_offsets;
    // What the shaders sample at render time (osl/include/loom/diffraction_sampling.h).
    const double spot = diffraction_spot_radius(w0);
    const DiffractionSampling samp = diffraction_sampling_table(gap_table, spot);
    Image simg(samp.width, samp.height, 3);
    std::copy(samp.rgb.begin(), samp.rgb.end(), simg.data.begin());
    ctx.out.write_table(simg, "diffraction_gap_sampling", {"r", "g", "b"},
                        "inverse CDFs of the gap diffraction outside the central spot, and the "
                        "power there (layout: osl/include/loom/diffraction_sampling.h)");
    dif["files"]["gap_sampling"] = "diffraction_gap_sampling";
    dif["spot_s"] = spot;
    dif["gap_p_out"] = samp.p_out;  // per tile (row-major from offset (0, 0)), RGB
    dif["gap_fraction"] = {gap[0] * spec.weft_per_cm * 1e-4, gap[1] * spec.warp_per_cm * 1e-4};
  } else {
    dif["gap_absent"] = spec.components.gaps ? "the yarns touch: no open gaps"
                                             : "components.gaps is off";
  }
  dif["seconds"] = seconds_since(dt0);
  ctx.progress("diffraction", 1.0);
  return dif;
}

json bake_noise_stage(const BakeContext& ctx) {
  const FabricSpec& spec = ctx.spec;
  if (!spec.wave.noise)
    return {{"files", json::object()},
            {"reason", "wave.noise is off: the mean scattering, unmodulated"}};
  ctx.progress("noise", 0.0);
  const auto nt0 = std::chrono::steady_clock::now();
  const NoiseSettings ns = noise_settings(spec.quality);
  json blur = json::array();
  for (int l = 0; l < LOOM_NOISE_LEVELS; ++l) blur.push_back(shading::noise_level_blur(l));
  json noise = {{"theta_count", ns.theta_count},
                {"instances", ns.instances},
                {"band_nm", kNoiseBandsNm},
                {"width_um", spec.wave.speckle_width_um},
                {"segments_per_repeat", LOOM_NOISE_SEGMENTS_PER_REPEAT},
                {"levels", LOOM_NOISE_LEVELS},
                {"level_blur_rad", blur},
                {"psd", "P_1D(lambda; f) = exp(-2 (lambda f / width_um)^2), f in cycles "
                        "per radian (baker/include/loom/speckle_noise.h)"},
                {"files", {{"refl", "noise_refl"}, {"high", "noise_high"}}},
                {"layout",
                 "RGB = N_2D (Eq. S.38) at band_nm; u = (phi_o + pi) / 2 pi, periodic; "
                 "level l, instance j's rows (from the bottom) (l instances + j) "
                 "theta_count ... (l instances + j + 1) theta_count - 1 span theta_o "
                 "from -pi/2 to pi/2, ply space; level 0 the tile, level l blurred by "
                 "level_blur_rad[l] (osl/include/loom/speckle_noise.h)"}};
  int k = 0;
  for (const char* which : {"refl", "high"}) {
    const Image tile = speckle_noise_levels(
        speckle_noise_tile(ns, spec.wave.speckle_width_um, kNoiseSeed + uint64_t(k)), ns);
    // Half floats: the noise needs no more than 3 significant digits, and it is the largest
    // table of the atlas.
    ctx.out.write_table(tile, std::string("noise_") + which, {"n_r", "n_g", "n_b"},
                        std::string("speckle noise tile for ") +
                            (k == 0 ? "surface reflection (looked up at the memory-effect "
                                      "direction, Eq. S.40)"
                                    : "higher-order scattering (looked up at w_o)") +
                            "; layout: manifest raywave.noise.layout",
                        true, "periodic");
    ++k;
    ctx.progress("noise", 0.5 * k);
  }
  noise["seconds"] = seconds_since(nt0);
  return noise;
}

}  // namespace loom
