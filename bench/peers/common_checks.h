// Scene features every peer refuses the same way.
#pragma once
#include <string>

#include "bench/peers/peer.h"

namespace cellphys::bench {

/// Throws Unsupported for a force type the peers cannot map (e.g. a hand-placed contact).
inline void check_forces(const scene::SceneDesc& scene, const char* engine) {
  for (const scene::ForceSpec& f : scene.forces) {
    if (f.type == "spring" || f.type == "point_to_point" || f.type == "applied_wrench" ||
        f.type == "damping" || f.type == "gyroscopic")
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
