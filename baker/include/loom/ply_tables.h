// The ray-wave ply tables of an atlas: per yarn (warp, weft), the fitted ASG lobes of f_high and
// f_refl (asg_fit.h) and the absorption scale-downs, as float images plus manifest metadata.
//
// Layout (rows counted from the bottom, as every Loom image in memory; files have row 0 on top):
//   ply_high_<yarn>   corner nodes of the f_high fit (Eq. S.5-S.7): one row per theta_i node
//                     i = 0 .. M', two RGBA texels per (h node j, lobe l), lobe-major: part 0
//                     (theta_z, phi_z, phi_xy, mu1) at column l (N' + 1) + j, part 1
//                     (mu2, c, 0, 0) at column (L + l) (N' + 1) + j (asg_node_column in
//                     osl/include/loom/raywave_lobes.h), so that a bilinear look-up between
//                     nodes is Eq. S.7. Angles in radians, phi unwrapped (interpolate as stored).
//   ply_high_scale_<yarn>  scale-downs s_{l,k} (Eq. S.9): one channel, column j L + l, row
//                     i K + k, per corner node (i, j) and absorption level k (asg_fit.h: Loom
//                     keeps them at the nodes, not per block, so they interpolate continuously).
//   ply_refl_<yarn>   corner nodes of the f_refl fit, the ply_high layout with its own L.
//   ply_high_residual_<yarn>, ply_refl_residual_<yarn>  the energy residual (asg_residual.h):
//                     one channel, column side N + n (side 0 backward, 1 forward), row m K + k,
//                     per slice (theta_i^m, h^n) and absorption level k (K = 1 for f_refl).
// Grids (theta_i and h uniform, sigma levels in 1/mm), lobe counts and fit errors are in the
// manifest under "raywave". Identical warp and weft yarns share one set of files.
#pragma once
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "loom/asg_fit.h"
#include "loom/atlas.h"
#include "loom/multi_ply.h"
#include "loom/ply_maps.h"
#include "loom/spec.h"

namespace loom {

/// The manifest's raywave.yarns.<yarn>.node_layout of the layout above.
inline constexpr const char* kAsgNodeLayout = "lobe-major/node-scales";

struct PlyTables {
  AsgTable high, refl;
  /// What the tables were fitted to: the ply simulation, turned into the yarn's multi-ply
  /// scattering (Eq. S.13) for yarns of several plies. The double-layer factors use it too.
  PlySimResult raw;
  std::optional<MultiPlyGeometry> multi;  ///< set for multi-ply yarns
  PlySimSettings sim;
  uint64_t rays = 0;
  double sim_seconds = 0, fit_seconds = 0;
};

/// Simulate the yarn's ply and fit its tables at the given quality; `multi_ply` false skips
/// Eq. S.13-S.19 for yarns of several plies (components.multi_ply).
PlyTables bake_ply_tables(const YarnSpec& y, Quality q, const ProgressFn& progress = {},
                          const std::string& stage = "plysim", bool multi_ply = true);

/// Node and scale images of a table (layout above).
Image asg_nodes_image(const AsgTable& t);
Image asg_scale_image(const AsgTable& t);
Image asg_residual_image(const AsgTable& t);
/// The manifest entry of a yarn's tables (grids, lobe counts, errors, simulation settings).
nlohmann::json ply_tables_manifest(const PlyTables& t, const std::string& yarn);
/// The ply's sigma -> energy curve in a yarn's manifest entry (raywave.yarns.<yarn>.absorption.
/// curve); empty when the entry has none; throws std::runtime_error naming what is malformed.
AbsorptionCurve absorption_curve_from_manifest(const nlohmann::json& entry,
                                               const std::string& yarn);
/// The curve of the double layer (warp and weft): the mean of the two yarns' curves in the
/// manifest's "raywave" object.
AbsorptionCurve layer_absorption_curve(const nlohmann::json& raywave);
/// Rebuild a table from its images and manifest entry ("high" or "refl"); throws
/// std::runtime_error naming what is inconsistent. Without a residual image the table has none.
/// The entry's absorption curve, if any, becomes the table's interpolation variable.
AsgTable asg_table_from_images(const nlohmann::json& entry, const std::string& which,
                               const Image& nodes, const Image* scale,
                               const Image* residual = nullptr);

/// The f_high and f_refl tables of `yarn` ("warp" or "weft") of a loaded ray-wave atlas; throws
/// std::runtime_error if the atlas has none.
struct LoadedPlyTables {
  AsgTable high, refl;
  nlohmann::json entry;  ///< the manifest's raywave.yarns.<yarn>
};
LoadedPlyTables load_ply_tables(const Atlas& a, const std::string& yarn);

}  // namespace loom
