// The surface model's ply-level maps over one weave repeat (Zhu et al. 2023: the model's inputs
// are maps of the ply geometry; the paper bakes them from a weave pattern, so do we).
#pragma once
#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "loom/spec.h"
#include "loom/weave.h"

namespace loom {

/// A W x H image of C float channels, row iy = 0 at the *bottom* (v = 0, Blender's convention;
/// the atlas writer flips rows for OpenImageIO, whose row 0 is the top).
struct Image {
  int width = 0, height = 0, channels = 0;
  std::vector<float> data;
  Image() = default;
  Image(int w, int h, int c) : width(w), height(h), channels(c), data(size_t(w) * h * c, 0.0f) {}
  float* px(int ix, int iy) { return &data[(size_t(iy) * width + ix) * channels]; }
  const float* px(int ix, int iy) const { return &data[(size_t(iy) * width + ix) * channels]; }
};

/// One map: a semantic name, its channels and what they mean.
struct MapInfo {
  std::string name;
  std::vector<std::string> channels;
  std::vector<std::array<float, 2>> range;  ///< value range per channel
  std::vector<std::string> units;           ///< unit per channel ("" = unitless)
  std::string description;
};

/// All maps of the surface tier, in atlas order:
///   ply_frame        t.x t.y t.z height     ply tangent (unit, tangent frame), height (um)
///   ply_normal       n.x n.y n.z h          ply normal (unit, z > 0), position across ply [-1,1]
///   yarn_info        kind along ply_id gap  0 gap / 1 warp / 2 weft, position along the yarn
///                                           [0,1), per-ply ID hash [0,1), gap coverage [0,1]
///   albedo_reflect   k_rd.rgb k_rs          diffuse and specular reflection albedos (Eq. 1, 3)
///   albedo_transmit  k_td.rgb k_ts          diffuse and specular transmission albedos (Eq. 4, 6)
///   spec_params      a T w ior              SGGX roughness, optical thickness, Eq. 3 blend, IOR
///   horizon_0/1      sin(horizon) for azimuths 0..3 and 4..7 (visibility.h)
struct SurfaceMaps {
  std::vector<MapInfo> info;
  std::vector<Image> images;
  double repeat_um[2] = {0, 0};  ///< physical size of the repeat along x (u) and y (v)
  int warp_yarns = 0, weft_yarns = 0;
};

using ProgressFn = std::function<void(const std::string& stage, double fraction)>;

/// The continuous ply-level geometry of a spec at a point (x, y) in micrometres: which yarn is on
/// top and its ply frame. Periodic over the weave repeat by construction (the maps are texel
/// samples of it, which is why they tile).
struct GeometrySample {
  int kind = 0;  ///< 0 open gap, 1 warp, 2 weft
  double height = 0;
  float t[3] = {1, 0, 0}, n[3] = {0, 0, 1};
  float h = 0, along = 0, ply_id = 0;
  int yarn = 0;  ///< which warp yarn (row) or weft yarn (column) of the repeat
};

class SurfaceGeometry {
 public:
  explicit SurfaceGeometry(const FabricSpec& spec);
  ~SurfaceGeometry();
  /// `nearest_if_open`: where no yarn covers the point, return the nearest yarn's geometry at its
  /// edge (kind then says which) instead of kind 0.
  GeometrySample sample(double x_um, double y_um, bool nearest_if_open) const;
  double repeat_x() const;  ///< repeat length along x (um)
  double repeat_y() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Bakes the ply-level maps of a (validated) spec whose yarn colours are already scene-linear.
/// `horizons` false leaves the two horizon maps at zero (for a caller that copies them from an
/// atlas of the same geometry).
SurfaceMaps bake_surface_maps(const FabricSpec& spec, const ProgressFn& progress = {},
                              bool horizons = true);

/// Per-ply ID hash in [0, 1): a deterministic integer hash (PCG-style) of its arguments.
float ply_id_hash(int kind, int yarn, int stripe);

}  // namespace loom
