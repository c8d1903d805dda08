// Scene features every peer refuses the same way.
#pragma once
#include <string>

#include "bench/peers/peer.h"

namespace cellphys::bench {

/// Throws Unsupported for a force type no peer maps (e.g. a hand-placed contact). Each peer
/// refuses the joints, and the joints' features, it cannot map itself.
inline void check_forces(const scene::SceneDesc& scene, const char* engine) {
  for (const scene::ForceSpec& f : scene.forces) {
    if (f.type == "spring" || is_joint_type(f.type) || f.type == "applied_wrench" || f.type == "damping" ||
        f.type == "gyroscopic")
      continue;
    throw Unsupported(std::string(engine) + " has no equivalent of force '" + f.type + "'");
  }
}

inline double param_of(const ppe::ForceParams& p, const char* name, int k = 0) {
  for (const auto& [n, v] : p)
    if (n == name && static_cast<int>(v.size()) > k) return v[k];
  return 0.0;
}

}  // namespace cellphys::bench
