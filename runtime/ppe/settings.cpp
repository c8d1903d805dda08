#include "runtime/ppe/settings.h"

#include <cmath>
#include <cstdio>

namespace cellphys::ppe {

float* global_lanes(gen::Force_Globals& globals, const gen::GlobalInfo& g) {
  return reinterpret_cast<float*>(reinterpret_cast<unsigned char*>(&globals) + g.field_offset);
}
const float* global_lanes(const gen::Force_Globals& globals, const gen::GlobalInfo& g) {
  return reinterpret_cast<const float*>(reinterpret_cast<const unsigned char*>(&globals) + g.field_offset);
}

std::string global_problem(const gen::GlobalInfo& g, float v) {
  if (!std::isfinite(v)) return "must be finite";
  if (g.param.admits(v)) return "";
  if (g.param.min_exclusive && g.param.min == 0.0f) return "must be positive";
  char bound[32];
  std::snprintf(bound, sizeof bound, "%g", double(g.param.min));
  return std::string("must be ") + g.param.min_relation() + " " + bound;
}

void validate_settings(const WorldSettings& s) {
  if (!(s.dt > 0.0f) || !std::isfinite(s.dt)) throw WorldError("settings.dt must be positive and finite");
  if (!(s.tolerance > 0.0f) || !std::isfinite(s.tolerance)) throw WorldError("settings.tolerance must be positive");
  if (s.workers < 1 || s.workers > 256) throw WorldError("settings.workers must be between 1 and 256");
  if (s.local_store_bytes < 16 * 1024) throw WorldError("settings.local_store_bytes must be at least 16 KiB");
  if (s.max_halvings > 16) throw WorldError("settings.max_halvings must be at most 16");
  if (s.decouple_sweeps < 1 || s.decouple_sweeps > 64) throw WorldError("settings.decouple_sweeps must be between 1 and 64");
  if (!(s.decouple_tolerance >= 0.0f) || !std::isfinite(s.decouple_tolerance))
    throw WorldError("settings.decouple_tolerance must be finite and >= 0");
  for (int i = 0; i < gen::kNumGlobals; ++i) {
    const gen::GlobalInfo& g = gen::kGlobalTable[i];
    const float* v = global_lanes(s.globals, g);
    for (uint32_t l = 0; l < g.param.lanes; ++l) {
      const std::string why = global_problem(g, v[l]);
      if (!why.empty()) throw WorldError(std::string("settings.globals.") + g.param.name + ": " + why);
    }
  }
}

}  // namespace cellphys::ppe
