#include "tools/snapshot_file.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "runtime/ppe/world.h"
#include "tools/atomic_file.h"

namespace cellphys::cli {

namespace fs = std::filesystem;

std::vector<unsigned char> read_snapshot_file(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw SnapshotError{path + ": no such snapshot"};
  if (fs::is_directory(path, ec)) throw SnapshotError{path + ": is a directory, not a snapshot"};
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw SnapshotError{path + ": cannot open: " + std::strerror(errno)};
  std::vector<unsigned char> bytes;
  unsigned char buf[1 << 16];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) bytes.insert(bytes.end(), buf, buf + n);
  const bool bad = std::ferror(f) != 0;
  std::fclose(f);
  if (bad) throw SnapshotError{path + ": read error"};
  return bytes;
}

void save_snapshot(const ppe::World& world, const std::string& path) {
  const std::vector<unsigned char> bytes = world.snapshot();
  AtomicFile f;
  f.open(path);
  std::fwrite(bytes.data(), 1, bytes.size(), f.get());
  f.commit();
}

}  // namespace cellphys::cli
