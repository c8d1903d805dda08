// Writes the seed corpora of the snapshot and wire fuzzers from the built-in scenes (run by
// scripts/fuzz at build time, so no seed bytes are checked in):   make_seeds OUT
//   OUT/snapshot/    each scene but world1000 at its start and after 45 steps (sleepers,
//                    contact memory)
//   OUT/node/        the jobs batch of a wave of each wire scene, first step and step 30
//   OUT/dispatcher/  the scene's index byte, then the node's answer to its first step's wave
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "fuzz/wire_loopback.h"
#include "runtime/scene/scene.h"

namespace {

namespace fs = std::filesystem;
using cellphys::ppe::World;

void write(const fs::path& path, const std::vector<unsigned char>& bytes) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size() || std::fclose(f) != 0)
    throw std::runtime_error(path.string() + ": cannot write");
}

std::unique_ptr<World> world(const std::string& name) {
  const std::vector<unsigned char> b = cellphys::fuzz::scene_snapshot(name);
  return World::restore(b.data(), b.size());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds OUT\n");
    return 2;
  }
  const fs::path out = argv[1];
  for (const char* d : {"snapshot", "node", "dispatcher"}) fs::create_directories(out / d);
  size_t files = 0;
  for (const char* name : {"stack10", "chain_ratio", "incline", "newton_cradle", "pendulum", "spin", "stiff_spring", "pile65"}) {
    auto w = world(name);
    write(out / "snapshot" / (std::string(name) + "_0"), w->snapshot());
    for (int s = 0; s < 45; ++s) w->step();
    write(out / "snapshot" / (std::string(name) + "_45"), w->snapshot());
    files += 2;
  }
  for (size_t k = 0; k < cellphys::fuzz::kNumWireScenes; ++k) {
    const std::string name = cellphys::fuzz::kWireScenes[k];
    auto w = world(name);
    auto loop = std::make_shared<cellphys::fuzz::WireLoopback>();
    w->set_runner(loop);
    for (int s = 1; s <= 30; ++s) {
      w->step();
      if (s != 1 && s != 30) continue;
      write(out / "node" / (name + "_" + std::to_string(s)), loop->jobs_message());
      ++files;
      if (s != 1) continue;
      std::vector<unsigned char> seed(1, static_cast<unsigned char>(k));
      seed.insert(seed.end(), loop->answer_message().begin(), loop->answer_message().end());
      write(out / "dispatcher" / name, seed);
      ++files;
    }
  }
  std::printf("make_seeds: %zu seeds in %s\n", files, out.c_str());
  return 0;
}
