// Ray-wave shading checks that need a baked ray-wave atlas (test_raywave_bsdf.cpp); called from
// PlyTables.RaywaveAtlas, which bakes the atlas once per test process.
#pragma once
#include <filesystem>

namespace loom::test {
void raywave_bsdf_atlas_checks(const std::filesystem::path& dir);
}
