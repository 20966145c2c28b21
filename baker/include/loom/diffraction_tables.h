// Diffraction tables of the ray-wave atlas: the spectral intensity of Eq. S.35 through the
// apertures a woven fabric has, integrated into scene-linear RGB for the shaders
// (osl/include/loom/diffraction_table.h holds the coordinates and the left-out factor).
//
// Two aperture classes (section 4):
//  * gap: the open rectangle between two neighbouring warp and two neighbouring weft yarns,
//    g_x x g_y um (g_x = weft spacing - weft diameter, g_y = warp spacing - warp diameter). The
//    beam centre lands anywhere in it; section 4.2 shows the position changes mainly the colour
//    saturation, so the table holds a few offsets (c_x, c_y) of the beam centre from the hole's
//    centre, c = (1 - (1 - j / (offsets - 1))^2) g / 2 (from the centre to the edge, denser
//    towards the edge: osl/include/loom/diffraction_sampling.h, diffraction_tile_coord), and
//    the shader blends between them. Absent when the yarns touch (g_x <= 0 or g_y <= 0).
//  * ply edge: a beam centred on a ply within d_cut of its edge is clipped to
//    [x_w, d_cut] x [-d_cut, d_cut] (section 4.3). The table depends only on x_w / d_cut and w_0,
//    so one serves every yarn: tile j holds x_w / d_cut = j / (tiles - 1), the last tile (a
//    closed aperture) is zero.
//
// Layout of both: RGB float, tiles of size x size texels; in a tile, column u holds
// t_x = u / (size - 1) and row r (counted from the bottom, v = 0, as every Loom image) holds
// t_y = r / (size - 1), with |s| = 2 t^2 (diffraction_table_s). Gap tiles: column block i = offset index along x, row block j along y.
// Edge tiles: one row of tiles, column block j. Values D_c(s) of diffraction_table.h: per unit
// incident power and unit solid angle, without the obliquity factor.
#pragma once

#include <string>
#include <vector>

#include "loom/spec.h"
#include "loom/spectrum.h"

namespace loom {

struct DiffractionSettings {
  int size = 64;         ///< texels per tile side
  double step_nm = 5;    ///< wavelength step of the spectral integration
  int gap_offsets = 4;   ///< beam-centre offsets per axis in the gap table
  int edge_tiles = 8;    ///< x_w / d_cut steps in the ply-edge table
};
DiffractionSettings diffraction_settings(Quality q);

struct DiffractionTable {
  int size = 0, tiles_x = 0, tiles_y = 0;
  std::vector<float> rgb;  ///< (tiles_y size) rows of (tiles_x size) texels, 3 floats each
  int width() const { return tiles_x * size; }
  int height() const { return tiles_y * size; }
  const float* px(int x, int y) const { return &rgb[(size_t(y) * width() + x) * 3]; }
  /// Channel c of tile (tile_x, tile_y) at table coordinates (t_x, t_y) in [0, 1], bilinear
  /// between the texels (texel k at t = k / (size - 1)).
  double at(int tile_x, int tile_y, double t_x, double t_y, int c) const;
};

/// The gap widths (um) of a fabric: {g_x, g_y}; <= 0 when the yarns touch or overlap.
std::array<double, 2> gap_widths(const FabricSpec& spec);

/// The gap table for a g_x x g_y hole (um), beam waist w0 (um).
DiffractionTable diffraction_gap_table(double gx, double gy, double w0, const SpectralRgb& rgb,
                                       const DiffractionSettings& s);
/// The ply-edge table for beam waist w0 (um); d_cut = LOOM_DIFFRACTION_DCUT_WAISTS w0.
DiffractionTable diffraction_edge_table(double w0, const SpectralRgb& rgb,
                                        const DiffractionSettings& s);

// ---- Sampling the gap table at render time (osl/include/loom/diffraction_sampling.h) ----

/// Radius s_spot, in the direction sum s, of the central spot that stays delta transmission:
/// three standard deviations lambda / (2 pi w0) of a free Gaussian beam's pattern at 700 nm,
/// at most 0.05 (3 degrees; beams narrower than 6.7 um then keep part of their spot sampled).
double diffraction_spot_radius(double w0_um);

/// The distribution the shaders sample for one tile and channel (diffraction_sampling.h), in
/// table coordinates t over one quadrant. Choice: piecewise uniform on a sub-grid `sub` times
/// finer than the table (the table read bilinearly at sub-cell centres, times the Jacobian
/// (2 S_MAX t_x)(2 S_MAX t_y) of s = S_MAX t^2), as a product of the marginal in t_y (per
/// sub-row) and the conditional in t_x given the table row (one per row of table cells: the
/// sampling image holds one conditional row per table row). Sub-cells whose centre lies inside
/// the spot (|s| < spot_s) are left out of both and counted in `spot`.
struct DiffractionSampler {
  int cells = 0, sub = 0;  ///< table cells per axis (size - 1), sub-cells per table cell
  std::vector<double> marginal;     ///< per sub-row (cells sub), masses
  std::vector<double> conditional;  ///< per table row j, per sub-column: [j (cells sub) + i]
  std::vector<double> row_total;    ///< per table row j, the sum of its conditional
  double outside = 0, spot = 0;     ///< masses outside and inside the spot (one quadrant)
  double p_out() const { return outside + spot > 0 ? outside / (outside + spot) : 0.0; }
  /// The sampled density per unit area of direction sum s over the whole plane (the four
  /// quadrants equally likely), normalised to 1; 0 outside the table. (Uniform in t within a
  /// sub-cell, it is integrably infinite on the axes s_x = 0, s_y = 0: integrate with
  /// probability().)
  double density(double s_x, double s_y) const;
  /// The probability of the rectangle [sx0, sx1] x [sy0, sy1] of direction sums (any signs).
  double probability(double sx0, double sx1, double sy0, double sy1) const;
};
inline constexpr int kDiffractionSub = 8;
DiffractionSampler diffraction_sampler(const DiffractionTable& t, int tile_x, int tile_y,
                                       int channel, double spot_s, int sub = kDiffractionSub);

/// The gap table's sampling image (layout: diffraction_sampling.h), RGB.
struct DiffractionSampling {
  int width = 0, height = 0;
  std::vector<float> rgb;  ///< rows from the bottom
  std::vector<std::array<float, 3>> p_out;  ///< per tile (ty tiles_x + tx), per channel
};
DiffractionSampling diffraction_sampling_table(const DiffractionTable& gap, double spot_s);

/// A table image (tiles as diffraction_gap_table lays them out) back as a DiffractionTable:
/// `size` texels per tile side; throws std::runtime_error when the image does not tile.
DiffractionTable diffraction_table_from_rgb(int width, int height, const float* rgb, int size);

}  // namespace loom
