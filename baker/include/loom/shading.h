// The shared shading math (osl/include/loom/*.h) compiled as C++: the same lines the OSL shaders
// run, in namespace loom::shading. Include this, never a copy of a formula.
#pragma once

#define LOOM_CPP 1
namespace loom::shading {}
#include "../../../osl/include/loom/osl_compat.h"
namespace loom::shading {
#include "../../../osl/include/loom/texel_guard.h"
#include "../../../osl/include/loom/sggx.h"
#include "../../../osl/include/loom/spongecake.h"
#include "../../../osl/include/loom/visibility.h"
#include "../../../osl/include/loom/surface_bsdf.h"
#include "../../../osl/include/loom/closure_mapping.h"
#include "../../../osl/include/loom/fitted_closures.h"
#include "../../../osl/include/loom/asg.h"
#include "../../../osl/include/loom/diffraction_table.h"
#include "../../../osl/include/loom/speckle_noise.h"
#include "../../../osl/include/loom/raywave_lobes.h"
#include "../../../osl/include/loom/double_layer_factors.h"
#include "../../../osl/include/loom/diffraction_sampling.h"
#include "../../../osl/include/loom/average_closures.h"
}  // namespace loom::shading
