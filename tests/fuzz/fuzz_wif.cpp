// libFuzzer target: the WIF draft reader (baker/src/wif.cpp) and the spec a draft makes, on
// arbitrary bytes.
//
// Properties checked beyond "no crash, no sanitizer report": a draft that does not read says
// why (non-empty messages, each naming the draft); one that does has an interlacing of its
// thread counts whose smallest repeat tiles back to it, and its spec, when it validates, has a
// canonical form that parses back to itself.
//
//   build-fuzz/fuzz_wif tests/fuzz/corpus/wif -max_total_time=60   (scripts/fuzz.sh)
#include <cstdint>
#include <cstdlib>
#include <string>

#include "loom/spec.h"
#include "loom/wif.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const loom::WifResult r = loom::parse_wif(text, "fuzz.wif");
  if (!r.ok()) {
    for (const std::string& e : r.errors)
      if (e.rfind("fuzz.wif", 0) != 0) std::abort();
    return 0;
  }
  const auto m = loom::wif_interlacing(r.draft);
  if (int(m.size()) != r.draft.warp_threads || int(m[0].size()) != r.draft.weft_threads)
    std::abort();
  const auto rep = loom::smallest_repeat(m);
  for (size_t i = 0; i < m.size(); ++i)
    for (size_t j = 0; j < m[i].size(); ++j)
      if (m[i][j] != rep[i % rep.size()][j % rep[0].size()]) std::abort();
  const loom::SpecResult s = loom::spec_with_draft(nlohmann::json::object(), text, "fuzz.wif");
  if (!s.ok()) {
    if (s.errors.empty()) std::abort();
    return 0;
  }
  const nlohmann::json c = loom::canonical_spec(s.spec);
  const loom::SpecResult again = loom::parse_spec(c);
  if (!again.ok() || loom::canonical_spec(again.spec) != c) std::abort();
  return 0;
}
