// Diffraction tables of the ray-wave atlas: the spectral intensity of Eq. S.35 through the
// apertures a woven fabric has, integrated into scene-linear RGB for the shaders
// (osl/include/loom/diffraction_table.h holds the coordinates and the left-out factor).
//
// Two aperture classes (section 4):
//  * gap: the open rectangle between two neighbouring warp and two neighbouring weft yarns,
//    g_x x g_y um (g_x = weft spacing - weft diameter, g_y = warp spacing - warp diameter). The
//    beam centre lands anywhere in it; section 4.2 shows the position changes mainly the colour
//    saturation, so the table holds a few offsets (c_x, c_y) of the beam centre from the hole's
//    centre, c = j / (offsets - 1) * g / 2 (from the centre to the edge), and the shader blends
//    between them. Absent when the yarns touch (g_x <= 0 or g_y <= 0).
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
};

/// The gap widths (um) of a fabric: {g_x, g_y}; <= 0 when the yarns touch or overlap.
std::array<double, 2> gap_widths(const FabricSpec& spec);

/// The gap table for a g_x x g_y hole (um), beam waist w0 (um).
DiffractionTable diffraction_gap_table(double gx, double gy, double w0, const SpectralRgb& rgb,
                                       const DiffractionSettings& s);
/// The ply-edge table for beam waist w0 (um); d_cut = LOOM_DIFFRACTION_DCUT_WAISTS w0.
DiffractionTable diffraction_edge_table(double w0, const SpectralRgb& rgb,
                                        const DiffractionSettings& s);

}  // namespace loom
