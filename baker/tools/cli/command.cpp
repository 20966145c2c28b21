#include "command.h"

#include <fmt/format.h>

#include <iostream>

#include "loom/cli_values.h"
#include "loom/spec.h"

namespace loom::cli {

CLI::Validator finite_range(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& s) -> std::string {
        try {
          s = fmt::format("{}", loom::parse_cli_number_in("", s, lo, hi));
        } catch (const loom::CliValueError& e) {
          return e.what();
        }
        return "";
      },
      fmt::format("in [{}, {}]", lo, hi));
}

int& verbosity() {
  static int level = 1;
  return level;
}

std::string spec_help() {
  std::string names;
  for (const std::string& n : loom::preset_names()) names += (names.empty() ? "" : ", ") + n;
  return "spec file (JSON, or a WIF weaving draft: .wif) or preset name (" + names + ")";
}

void refuse_thread_sequences(loom::SpecResult& res, const std::string& what) {
  if (res.ok())
    if (auto e = loom::thread_sequences_not_yet(res.spec, what); !e.empty())
      res.errors.push_back(e);
}

int report_spec_errors(const std::string& what, const std::vector<std::string>& errors) {
  for (auto& e : errors) std::cerr << "error: " << e << "\n";
  std::cerr << fmt::format("loom-bake: {} has {} problem{}; nothing was written\n", what,
                           errors.size(), errors.size() == 1 ? "" : "s");
  return 2;
}

}  // namespace loom::cli
