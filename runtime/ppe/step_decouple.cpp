#include "runtime/ppe/step_decouple.h"

#include <algorithm>

namespace cellphys::ppe {

DecoupledIslands decouple_islands(const PackContext& pc, const std::vector<IslandContent>& islands, StepStats& st) {
  StageTimer t(st.times.decouple_ms);
  DecoupledIslands d;
  d.parts.resize(islands.size());
  for (size_t k = 0; k < islands.size(); ++k) {
    d.parts[k] = decouple(pc, islands[k], st.cut_couplings);  // a copy: the sleep stage needs the island whole
    if (d.parts[k].size() > 1) ++st.decoupled_islands;
    d.waves = std::max(d.waves, d.parts[k].size());
  }
  return d;
}

}  // namespace cellphys::ppe
