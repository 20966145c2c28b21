// Publishing a finished directory (an atlas, a fiber region) under its final name, so that a
// reader sees the old one or the new one, never half of either.
#pragma once

#include <filesystem>

namespace loom {

/// Renames the finished directory `tmp` to `dir`. True when done; false when `dir` exists (the
/// caller decides whether to replace it with exchange_directories); throws on any other failure.
bool publish_directory(const std::filesystem::path& tmp, const std::filesystem::path& dir);

/// Swaps the directories `tmp` and `dir`: afterwards `dir` holds what `tmp` held and `tmp` holds
/// the old `dir`, for the caller to remove. Atomic on Linux (renameat2 RENAME_EXCHANGE); elsewhere
/// three renames, so a reader may briefly find no `dir` (never a partial one). Throws on failure.
void exchange_directories(const std::filesystem::path& tmp, const std::filesystem::path& dir);

}  // namespace loom
