// Publishing finished directories (publish_dir.h): one rename, or an exchange with the old one.
#include "loom/publish_dir.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <stdio.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace loom {

namespace fs = std::filesystem;

bool publish_directory(const fs::path& tmp, const fs::path& dir) {
  if (::rename(tmp.c_str(), dir.c_str()) == 0) return true;
  if (errno == EEXIST || errno == ENOTEMPTY) return false;
  throw std::runtime_error(
      fmt::format("cannot publish {}: {}", dir.string(), std::strerror(errno)));
}

void exchange_directories(const fs::path& tmp, const fs::path& dir) {
#if defined(__linux__) && defined(RENAME_EXCHANGE)
  if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, dir.c_str(), RENAME_EXCHANGE) == 0) return;
  if (errno != EINVAL && errno != ENOSYS)  // (a file system without exchange: the fallback)
    throw std::runtime_error(
        fmt::format("cannot replace {}: {}", dir.string(), std::strerror(errno)));
#endif
  // Portable fallback: the old directory aside, the new one in, the old one to tmp's name.
  fs::path aside = tmp;
  aside += ".old";
  std::error_code ec;
  fs::rename(dir, aside, ec);
  if (ec) throw std::runtime_error(fmt::format("cannot replace {}: {}", dir.string(), ec.message()));
  fs::rename(tmp, dir, ec);
  if (ec) {
    std::error_code back;
    fs::rename(aside, dir, back);
    throw std::runtime_error(fmt::format("cannot replace {}: {}", dir.string(), ec.message()));
  }
  fs::rename(aside, tmp, ec);
  if (ec) throw std::runtime_error(fmt::format("replaced {}, but cannot move the old one to {}: {}",
                                               dir.string(), tmp.string(), ec.message()));
}

}  // namespace loom
