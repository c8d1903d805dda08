// The packed island: the bytes a compute kernel takes, identical for a worker thread and a
// remote node. Layout (every part 16-byte aligned):
//   Island_Header | Island_Section x num_sections | Island_Params | Rigid_Body x num_bodies |
//   each section's instances (pair instances first, then world-anchored ones)
// and the result a kernel returns:
//   Island_Result | Rigid_Body_Step x num_bodies | Rigid_Body x num_bodies (advanced)
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "cellphys/gen/force_table.h"
#include "cellphys/gen/layouts.h"

namespace cellphys::spu {

inline constexpr uint32_t kIslandMagic = 0x50494C43u;  // "CLIP"
inline constexpr uint32_t kResultMagic = 0x534C5352u;  // "RSLS"
inline constexpr uint32_t kIslandVersion = 2;  // 2: image_checksum

/// Integration methods (docs/integrators.md). implicit_split is the default.
enum class Integrator : uint32_t {
  implicit_split = 0,    // linearly implicit Euler for forces + conserving midpoint rotation
  implicit_euler = 1,    // the reference design's: linearly implicit Euler, gyroscopic torque in the solve
  rosenbrock = 2,        // ROS2, second order, L-stable, embedded error estimate, adaptive substeps
  symplectic_euler = 3,  // explicit, what most game engines use
  explicit_euler = 4,
  rk4 = 5,
};
inline constexpr int kNumIntegrators = 6;

/// Rigid_Body::flags bit: under implicit_split this body turns by its kick, q1 = exp(h w1) q0
/// with no gyroscopic torque (as Box2D and Jolt turn every body), instead of by the torque-free
/// drift. The packer sets it on the unequal-moment bodies a joint holds: there the drift moves the
/// joint's point off where the solve held it, and a stiff joint at 60 Hz then pumps energy in (a
/// 1 m rod 0.1 m thick swinging round on a ball joint gained a thousandfold in 5 s; docs/joints.md).
inline constexpr uint32_t kBodyTurnsByKick = 1u;
const char* integrator_name(Integrator i);
bool parse_integrator(const std::string& name, Integrator* out);
/// "implicit_split, implicit_euler, ...": for messages and help text.
std::string integrator_names();

/// A failed step is retried as two halves, down to 1/2^max_halvings of it; at most this many.
inline constexpr uint32_t kMaxHalvings = 16;

enum class IslandStatus : uint32_t { ok = 0, failed = 1, does_not_fit = 2, malformed = 3 };
const char* status_name(IslandStatus s);

inline constexpr size_t align16(size_t n) { return (n + 15) / 16 * 16; }

/// Checksum of a byte range, chainable through `seed`: four independent 64-bit FNV-style
/// multiply-xor lanes over 8-byte words (a byte-wise FNV-1a cost a third of a step), folded
/// to 32 bits. Catches corrupted or truncated transfers; it is not cryptographic. The files'
/// checksum (snapshots, recordings): its value never changes.
uint32_t checksum(const unsigned char* p, size_t n, uint32_t seed = 0x811C9DC5u);

/// The checksum of island images and results, which live only between this build's packer and
/// kernel: the same multiply-xor over sixteen lanes, and the tail in words. Each lane waits on
/// its own multiplies, so four lanes ran at 8 bytes a cycle however wide the machine, and the
/// last bytes went one at a time: `checksum` was 8% of a step of one-box islands.
uint32_t image_checksum(const unsigned char* p, size_t n, uint32_t seed = 0x811C9DC5u);

/// Offsets of the parts of an image, computed from its counts.
struct IslandLayout {
  size_t sections = 0, params = 0, bodies = 0, instances = 0, total = 0;
};
IslandLayout island_layout(uint32_t num_bodies, uint32_t num_sections);
size_t result_bytes(uint32_t num_bodies);

/// A parsed view into an image (in the local store or in main memory).
struct IslandView {
  gen::Island_Header* header = nullptr;
  gen::Island_Section* sections = nullptr;
  gen::Island_Params* params = nullptr;
  gen::Rigid_Body* bodies = nullptr;
  unsigned char* base = nullptr;
  int num_bodies() const { return static_cast<int>(header->num_bodies); }
  int num_sections() const { return static_cast<int>(header->num_sections); }
  template <class Instance>
  Instance* instances(const gen::Island_Section& s) const {
    return reinterpret_cast<Instance*>(base + s.offset);
  }
};

/// Checks an image (magic, version, sizes, offsets, force types, body indices, finite
/// numbers, and its checksum unless `sealed` is false). Returns "" when it is well-formed,
/// else the reason. The header's num_blocks is verified when the kernel builds the block
/// structure.
std::string validate_island(const unsigned char* image, size_t bytes, bool sealed = true);
IslandView view_island(unsigned char* image);

/// Builds an image from bodies and force instances (the control side's packer uses it too).
class IslandBuilder {
 public:
  IslandBuilder();
  void set_step(float h) { header_.step = h; }
  void set_integrator(Integrator i) { header_.integrator = static_cast<uint32_t>(i); }
  void set_solver(uint32_t s) { header_.solver = s; }
  void set_tolerance(float t) { header_.tolerance = t; }
  void set_max_halvings(uint32_t n) { header_.max_halvings = n; }
  void set_island_id(uint32_t id) { header_.island_id = id; }
  gen::Island_Params& params() { return params_; }
  int add_body(const gen::Rigid_Body_Fields& body);
  int num_bodies() const { return static_cast<int>(bodies_.size()); }
  /// Adds one instance of a force (its packed struct); body_b < 0 makes it world-anchored.
  void add_force(gen::ForceType type, const void* instance, size_t instance_bytes);
  /// Turns on a global force (gravity): it acts on every body and has no instances.
  void add_global(gen::ForceType type);
  template <class Instance>
  void add(gen::ForceType type, const Instance& f) {
    add_force(type, &f, sizeof f);
  }
  /// The finished image: 16-byte aligned storage, checksum set (`seal`); unsealed (checksum
  /// 0) only for an image this process steps itself at once (IslandJob::trusted).
  std::vector<unsigned char> finish() const;
  /// The same into `img` (replaced; its storage is reused).
  void finish(std::vector<unsigned char>& img, bool seal = true) const;
  /// Empty again, with the defaults of a new builder; keeps its storage, so a builder reused
  /// for island after island allocates nothing once warm.
  void reset();
  /// Storage at least as large as `other`'s, so this builder packs what that one has packed
  /// without allocating.
  void reserve_like(const IslandBuilder& other);

 private:
  gen::Island_Header header_{};
  gen::Island_Params params_{};
  std::vector<gen::Rigid_Body> bodies_;
  struct Bucket {
    std::vector<unsigned char> pair, world;
    uint32_t pair_count = 0, world_count = 0;
    bool global = false;
    bool present() const { return global || pair_count + world_count > 0; }
  };
  std::vector<Bucket> buckets_;  // per force type
  mutable std::vector<uint64_t> keys_;  // finish()'s scratch for counting blocks
};

/// Distinct off-diagonal blocks the island's pair forces create (2 per coupled body pair).
uint32_t count_offdiagonal_blocks(const IslandView& v);
/// The same with the caller's scratch (replaced).
uint32_t count_offdiagonal_blocks(const IslandView& v, std::vector<uint64_t>& keys);

}  // namespace cellphys::spu
