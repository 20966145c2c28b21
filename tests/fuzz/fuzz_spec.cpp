// libFuzzer target: the fabric spec parser (baker/src/spec.cpp) on arbitrary bytes.
//
// Properties checked beyond "no crash, no sanitizer report": a spec that does not validate says
// why (at least one error message); one that does has a canonical form that parses back to
// itself (the canonical form is what identifies a bake, so it must be a fixed point).
//
//   build-fuzz/fuzz_spec tests/fuzz/corpus/spec -max_total_time=60   (scripts/fuzz.sh)
#include <cstdint>
#include <cstdlib>
#include <string>

#include "loom/spec.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const loom::SpecResult r = loom::parse_spec_text(text);
  if (!r.ok()) {
    if (r.errors.empty()) std::abort();
    for (const std::string& e : r.errors)
      if (e.empty()) std::abort();
    return 0;
  }
  const nlohmann::json c = loom::canonical_spec(r.spec);
  const loom::SpecResult again = loom::parse_spec(c);
  if (!again.ok() || loom::canonical_spec(again.spec) != c) std::abort();
  return 0;
}
