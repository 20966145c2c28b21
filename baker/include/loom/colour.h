// Colour conversion of the spec's yarn colours to the scene-linear working space, with
// OpenColorIO.
#pragma once
#include <array>
#include <nlohmann/json.hpp>
#include <string>

namespace loom {

struct FabricSpec;

/// Converts sRGB-encoded colours to scene linear. With a config path (e.g. Blender's
/// `datafiles/colormanagement/config.ocio`), the source is its "sRGB" colour space (or
/// "sRGB - Texture") and the destination its `scene_linear` role. Without one, Loom builds an
/// in-memory OCIO config (Debian's OCIO 2.1 has no built-in configs) whose "sRGB" space is the
/// IEC 61966-2-1 curve (ExponentWithLinearTransform, gamma 2.4, offset 0.055) over linear
/// Rec.709 primaries, the same as Blender's "sRGB" to "Linear Rec.709".
class ColourConverter {
 public:
  explicit ColourConverter(const std::string& config_path = "");
  std::array<double, 3> srgb_to_linear(const std::array<double, 3>& c) const;
  /// The linear map from CIE XYZ (D65) to scene linear: the config's `cie_xyz_d65_interchange`
  /// role (Blender's configs define it) to its `scene_linear` role; the built-in config's XYZ
  /// space is the IEC 61966-2-1 XYZ to linear Rec.709 matrix. Rows are output channels.
  std::array<std::array<double, 3>, 3> xyz_to_linear_matrix() const;
  /// What the manifest records: config, source space, destination space, OCIO version.
  nlohmann::json describe() const;

 private:
  struct Impl;
  std::shared_ptr<Impl> impl_;
};

/// Each yarn's colour_linear from its input colour: converted from sRGB by cc, or taken as given
/// when the spec says it is linear. The baker does this first; so must anything else that
/// reads colour_linear from a spec it loaded (eval truth).
void resolve_yarn_colours(FabricSpec& spec, const ColourConverter& cc);

}  // namespace loom
