// A runner that ships a world's islands through the wire codec (runtime/ppe/wire.h) to a node
// in this process, and the built-in scenes the wire fuzzers step: what make_seeds records as
// seeds and what fuzz_dispatcher replays with a fuzzed answer in place of the node's.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "runtime/ppe/island_runner.h"
#include "runtime/ppe/wire.h"
#include "runtime/ppe/world.h"

namespace cellphys::fuzz {

/// Scenes with several islands, contacts, joints and springs; a fuzz input's first byte picks one.
inline constexpr const char* kWireScenes[] = {"incline", "newton_cradle", "stack10", "chain_ratio", "pile65"};
inline constexpr size_t kNumWireScenes = sizeof kWireScenes / sizeof kWireScenes[0];

/// A built-in scene's world at its start, as snapshot bytes (restoring them is cheaper than
/// building the scene).
std::vector<unsigned char> scene_snapshot(const std::string& name);

/// Every wave is one jobs batch (sequence 1, 2, ...) and one answer; the dispatcher's side is
/// wire::read_results, as over MPI. A job without a sound result is left for the world to
/// recompute.
class WireLoopback : public ppe::IslandRunner {
 public:
  /// What the node answers to a jobs batch; by default a wire::NodeKernel's answer.
  using Node = std::function<void(const std::vector<unsigned char>& jobs, std::vector<unsigned char>& answer)>;
  explicit WireLoopback(Node node = {});
  void run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) override;
  void set_local_store(size_t bytes) override { local_store_ = bytes; }
  const char* name() const override { return "wire loopback"; }
  /// The last wave's messages.
  const std::vector<unsigned char>& jobs_message() const { return jobs_; }
  const std::vector<unsigned char>& answer_message() const { return answer_; }

 private:
  Node node_;
  ppe::wire::NodeKernel kernel_;
  size_t local_store_ = 256 * 1024;
  uint32_t sequence_ = 0;
  std::vector<unsigned char> jobs_, answer_;
};

}  // namespace cellphys::fuzz
