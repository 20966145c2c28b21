// Colour differences as people see them: the CIEDE2000 difference of two CIELAB colours
// (SpectralUpsampler::lab gives a scene-linear colour's, in the colour config's working space) (Sharma, Wu and Dalal 2005, "The CIEDE2000 color-difference formula:
// implementation notes, supplementary test data, and mathematical observations"), with which
// the issue states "the colour you pick is the colour you see": Delta E 2000 <= 3.
#pragma once
#include <array>

namespace loom {

using Lab = std::array<double, 3>;  ///< L*, a*, b*

/// CIEDE2000 with k_L = k_C = k_H = 1.
double delta_e_2000(const Lab& a, const Lab& b);

}  // namespace loom
