// What a parsed spec says: its canonical form (the bake's identity) and each thread's colour
// under the per-thread yarn sequences (spec.h).
#include "loom/spec.h"

namespace loom {

using nlohmann::json;

int sequence_length(const std::vector<ThreadRun>& runs) {
  int n = 0;
  for (const auto& r : runs) n += r.count;
  return n;
}

std::array<double, 3> thread_colour_linear(const FabricSpec& s, int system, int index) {
  const auto& runs = system == 2 ? s.weft_sequence : s.warp_sequence;
  const int n = sequence_length(runs);
  if (n == 0) return (system == 2 ? s.weft : s.warp).color_linear;
  int k = ((index % n) + n) % n;
  for (const auto& r : runs) {
    if (k < r.count) {
      for (const auto& t : s.yarn_types)
        if (t.name == r.type) return t.color_linear;
      break;
    }
    k -= r.count;
  }
  return (system == 2 ? s.weft : s.warp).color_linear;
}

bool has_thread_sequences(const FabricSpec& s) {
  return !s.warp_sequence.empty() || !s.weft_sequence.empty();
}

std::string thread_sequences_not_yet(const FabricSpec& s, const std::string& what) {
  if (!has_thread_sequences(s)) return "";
  return "$." + std::string(s.warp_sequence.empty() ? "weft" : "warp") + ".sequence: " + what +
         " does not yet take per-thread yarn sequences (issue 33: it knows one colour per "
         "system); bake the surface tier, or give each system one colour";
}

json canonical_spec(const FabricSpec& s) {
  auto yarn = [](const YarnSpec& y) {
    json c;
    c[y.color_space] = y.color_input;
    return json{{"plies", y.plies},
                {"fibers_per_ply", y.fibers_per_ply},
                {"yarn_diameter_um", y.yarn_diameter_um},
                {"ply_diameter_um", y.ply_diameter_um},
                {"fiber_diameter_um", y.fiber_diameter_um},
                {"fiber_twist_pitch_um", y.fiber_twist_pitch_um},
                {"ply_twist_deg", y.ply_twist_deg},
                {"twist", y.twist},
                {"ior", y.ior},
                {"color", c},
                {"roughness", y.roughness},
                {"specular", y.specular},
                {"transmission", y.transmission},
                {"migration_min", y.migration_min},
                {"migration_max", y.migration_max},
                {"migration_period", y.migration_period},
                {"density_epsilon", y.density_epsilon},
                {"density_beta", y.density_beta},
                {"loop_flyaways_per_mm", y.loop_flyaways_per_mm},
                {"hair_flyaways_per_mm", y.hair_flyaways_per_mm}};
  };
  auto runs = [](const std::vector<ThreadRun>& rs) {
    json a = json::array();
    for (const auto& r : rs) a.push_back({r.type, r.count});
    return a;
  };
  json weave = {{"pattern", s.weave.pattern}};
  if (s.weave.pattern == "twill") {
    weave["up"] = s.weave.up;
    weave["down"] = s.weave.down;
    weave["direction"] = s.weave.direction;
  } else if (s.weave.pattern == "satin") {
    weave["harness"] = s.weave.harness;
    weave["shift"] = s.weave.shift;
  } else if (s.weave.pattern == "basket") {
    weave["group"] = s.weave.group;
  } else if (s.weave.pattern == "custom") {
    weave["matrix"] = s.weave.matrix;
  }
  json c = json{{"schema", kSpecSchema},
              {"name", s.name},
              {"weave", weave},
              {"warp", yarn(s.warp)},
              {"weft", yarn(s.weft)},
              {"density", {{"warp_per_cm", s.warp_per_cm}, {"weft_per_cm", s.weft_per_cm}}},
              {"model",
               {{"tier", to_string(s.tier)},
                {"quality", to_string(s.quality)},
                {"colour_reading", to_string(s.colour_reading)},
                {"optical_thickness", s.optical_thickness},
                {"diffuse_blend", s.diffuse_blend},
                {"double_layer_blend", s.double_layer_blend}}},
              {"components",
               {{"transmission", s.components.transmission},
                {"gaps", s.components.gaps},
                {"shadowing", s.components.shadowing},
                {"multi_ply", s.components.multi_ply},
                {"double_layer", s.components.double_layer},
                {"perlin", s.perlin.enabled}}},
              {"perlin",
               {{"seed", s.perlin.seed},
                {"amplitude", s.perlin.amplitude},
                {"cells_per_repeat", s.perlin.cells_per_repeat}}},
              {"wave",
               {{"diffraction", s.wave.diffraction},
                {"beam_waist_um", s.wave.beam_waist_um},
                {"noise", s.wave.noise},
                {"speckle_width_um", s.wave.speckle_width_um}}}};
  // The surface tier's choice is always written: its default is "fitted", so a canonical spec
  // without it would read back as fitted. The other tiers map only, and leave it out.
  if (s.tier == Tier::Surface)
    c["model"]["closures"] = s.closures == ClosureSource::Fitted ? "fitted" : "mapped";
  if (!s.yarn_types.empty()) {
    json& t = c["yarn_types"] = json::object();
    for (const auto& y : s.yarn_types) t[y.name] = {{"color", {{y.color_space, y.color_input}}}};
  }
  if (!s.warp_sequence.empty()) c["warp"]["sequence"] = runs(s.warp_sequence);
  if (!s.weft_sequence.empty()) c["weft"]["sequence"] = runs(s.weft_sequence);
  return c;
}

}  // namespace loom
