#include "loom/colour.h"

#include "loom/spec.h"

#include <OpenColorIO/OpenColorIO.h>

#include <stdexcept>

namespace OCIO = OCIO_NAMESPACE;

namespace loom {

struct ColourConverter::Impl {
  OCIO::ConstConfigRcPtr config;
  OCIO::ConstCPUProcessorRcPtr cpu;
  OCIO::ConstCPUProcessorRcPtr xyz;  // null when the config has no XYZ interchange role
  std::string config_name, src, dst;
};

ColourConverter::ColourConverter(const std::string& config_path) : impl_(std::make_shared<Impl>()) {
  try {
    if (!config_path.empty()) {
      impl_->config = OCIO::Config::CreateFromFile(config_path.c_str());
      impl_->config_name = config_path;
      for (const char* name : {"sRGB", "sRGB - Texture", "srgb_texture", "Utility - sRGB - Texture"}) {
        if (impl_->config->getColorSpace(name)) {
          impl_->src = name;
          break;
        }
      }
      if (impl_->src.empty())
        throw std::runtime_error("the config has no sRGB colour space (looked for \"sRGB\", "
                                 "\"sRGB - Texture\")");
      impl_->dst = OCIO::ROLE_SCENE_LINEAR;
    } else {
      auto cfg = OCIO::Config::CreateRaw()->createEditableCopy();
      auto lin = OCIO::ColorSpace::Create();
      lin->setName("Linear Rec.709");
      lin->setFamily("linear");
      cfg->addColorSpace(lin);
      auto srgb = OCIO::ColorSpace::Create();
      srgb->setName("sRGB");
      auto curve = OCIO::ExponentWithLinearTransform::Create();
      curve->setGamma({2.4, 2.4, 2.4, 1.0});
      curve->setOffset({0.055, 0.055, 0.055, 0.0});
      srgb->setTransform(curve, OCIO::COLORSPACE_DIR_TO_REFERENCE);
      cfg->addColorSpace(srgb);
      auto xyz = OCIO::ColorSpace::Create();
      xyz->setName("Linear CIE-XYZ D65");
      xyz->setFamily("linear");
      auto m = OCIO::MatrixTransform::Create();
      // IEC 61966-2-1 (sRGB) XYZ to linear Rec.709, D65.
      const double M[16] = {3.2404542, -1.5371385, -0.4985314, 0, -0.9692660, 1.8760108,
                            0.0415560, 0, 0.0556434, -0.2040259, 1.0572252, 0,
                            0, 0, 0, 1};
      m->setMatrix(M);
      xyz->setTransform(m, OCIO::COLORSPACE_DIR_TO_REFERENCE);
      cfg->addColorSpace(xyz);
      cfg->setRole("cie_xyz_d65_interchange", "Linear CIE-XYZ D65");
      cfg->setRole(OCIO::ROLE_SCENE_LINEAR, "Linear Rec.709");
      cfg->setRole(OCIO::ROLE_REFERENCE, "Linear Rec.709");
      impl_->config = cfg;
      impl_->config_name = "loom-builtin (in-memory OCIO config: sRGB = IEC 61966-2-1 over Rec.709)";
      impl_->src = "sRGB";
      impl_->dst = "Linear Rec.709";
    }
    auto proc = impl_->config->getProcessor(impl_->src.c_str(), impl_->dst.c_str());
    impl_->cpu = proc->getDefaultCPUProcessor();
    if (impl_->config->hasRole("cie_xyz_d65_interchange"))
      impl_->xyz = impl_->config->getProcessor("cie_xyz_d65_interchange", OCIO::ROLE_SCENE_LINEAR)
                       ->getDefaultCPUProcessor();
  } catch (const OCIO::Exception& e) {
    throw std::runtime_error(std::string("colour conversion (OpenColorIO): ") + e.what());
  }
}

std::array<double, 3> ColourConverter::srgb_to_linear(const std::array<double, 3>& c) const {
  float px[3] = {float(c[0]), float(c[1]), float(c[2])};
  impl_->cpu->applyRGB(px);
  return {px[0], px[1], px[2]};
}

std::array<std::array<double, 3>, 3> ColourConverter::xyz_to_linear_matrix() const {
  if (!impl_->xyz)
    throw std::runtime_error("colour conversion (OpenColorIO): the config " + impl_->config_name +
                             " has no cie_xyz_d65_interchange role (needed for spectra)");
  std::array<std::array<double, 3>, 3> M{};
  for (int j = 0; j < 3; ++j) {
    float px[3] = {0, 0, 0};
    px[j] = 1.0f;
    impl_->xyz->applyRGB(px);
    for (int i = 0; i < 3; ++i) M[i][j] = px[i];
  }
  return M;
}

nlohmann::json ColourConverter::describe() const {
  return {{"config", impl_->config_name},
          {"from", impl_->src},
          {"to", impl_->dst},
          {"ocio_version", OCIO::GetVersion()}};
}

void resolve_yarn_colours(FabricSpec& spec, const ColourConverter& cc) {
  for (YarnSpec* y : {&spec.warp, &spec.weft})
    y->color_linear = y->color_space == "srgb" ? cc.srgb_to_linear(y->color_input) : y->color_input;
  for (YarnType& t : spec.yarn_types)
    t.color_linear = t.color_space == "srgb" ? cc.srgb_to_linear(t.color_input) : t.color_input;
}

}  // namespace loom
