// Snapshot files for `cellphys run --resume` and `--save-snapshot` (the bytes are
// ppe::World::snapshot's, docs/distributed.md): read whole, or written atomically.
#pragma once
#include <string>
#include <vector>

namespace cellphys::ppe {
class World;
}

namespace cellphys::cli {

// A snapshot that cannot be resumed (missing, unreadable, damaged): exit code 2.
struct SnapshotError {
  std::string message;
};

// The file's bytes; throws SnapshotError naming the file when it is missing, a directory or
// unreadable.
std::vector<unsigned char> read_snapshot_file(const std::string& path);

// Writes the world's snapshot to `path` under a temporary name, then renames it into place;
// throws std::runtime_error naming the file.
void save_snapshot(const ppe::World& world, const std::string& path);

}  // namespace cellphys::cli
