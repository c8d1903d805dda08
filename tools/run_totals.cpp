#include "tools/run_totals.h"

#include <algorithm>

namespace cellphys::cli {

namespace {

using ppe::StepStats;

enum class Over { sum, max, last };

// One figure of the totals and the StepStats field it is gathered from.
struct Rule {
  uint64_t RunTotals::*total;
  Over over;
  uint64_t (*field)(const StepStats&);
};

template <auto Field>
uint64_t field(const StepStats& s) {
  return static_cast<uint64_t>(s.*Field);
}

const Rule kRules[] = {
    {&RunTotals::solver_iterations, Over::sum, field<&StepStats::solver_iterations>},
    {&RunTotals::solves, Over::sum, field<&StepStats::solves>},
    {&RunTotals::step_halvings, Over::sum, field<&StepStats::step_halvings>},
    {&RunTotals::failed_islands, Over::sum, field<&StepStats::failed_islands>},
    {&RunTotals::decoupled_islands, Over::sum, field<&StepStats::decoupled_islands>},
    {&RunTotals::pushed_bodies, Over::sum, field<&StepStats::pushed_bodies>},
    {&RunTotals::bytes_to_nodes, Over::sum, field<&StepStats::bytes_to_nodes>},
    {&RunTotals::bytes_from_nodes, Over::sum, field<&StepStats::bytes_from_nodes>},
    {&RunTotals::messages, Over::sum, field<&StepStats::messages>},
    {&RunTotals::bad_messages, Over::sum, field<&StepStats::bad_messages>},
    {&RunTotals::recomputed_islands, Over::sum, field<&StepStats::recomputed_islands>},
    {&RunTotals::reassigned_islands, Over::sum, field<&StepStats::reassigned_islands>},
    {&RunTotals::dropped_nodes, Over::sum, field<&StepStats::dropped_nodes>},
    {&RunTotals::island_bodies, Over::sum, field<&StepStats::island_bodies>},
    {&RunTotals::island_bytes_shared, Over::sum, field<&StepStats::island_bytes_shared>},
    {&RunTotals::wire_table_to_nodes, Over::sum, field<&StepStats::wire_table_to_nodes>},
    {&RunTotals::wire_table_to_nodes_compressed, Over::sum, field<&StepStats::wire_table_to_nodes_compressed>},
    {&RunTotals::wire_table_from_nodes, Over::sum, field<&StepStats::wire_table_from_nodes>},
    {&RunTotals::image_bytes, Over::sum, field<&StepStats::image_bytes>},
    {&RunTotals::result_bytes, Over::sum, field<&StepStats::result_bytes>},
    {&RunTotals::contacts_max, Over::max, field<&StepStats::contacts>},
    {&RunTotals::local_store_peak_bytes, Over::max, field<&StepStats::local_store_peak_bytes>},
    {&RunTotals::active_bodies, Over::last, field<&StepStats::active_bodies>},
    {&RunTotals::sleeping_bodies, Over::last, field<&StepStats::sleeping_bodies>},
    {&RunTotals::islands, Over::last, field<&StepStats::islands>},
    {&RunTotals::contacts, Over::last, field<&StepStats::contacts>},
};

}  // namespace

RunTotals::RunTotals(long long steps) {
  step_ms.reserve(static_cast<size_t>(std::clamp<long long>(steps, 0, 10000000)));
}

void RunTotals::add(const StepStats& s, double ms) {
  for (const Rule& r : kRules) {
    uint64_t& t = this->*r.total;
    const uint64_t v = r.field(s);
    switch (r.over) {
      case Over::sum: t += v; break;
      case Over::max: t = std::max(t, v); break;
      case Over::last: t = v; break;
    }
  }
  for (const ppe::StageTimeField& f : ppe::kStageTimeFields) stage_ms.*f.ms += s.times.*f.ms;
  step_ms.push_back(ms);
}

double RunTotals::median_step_ms() const {
  if (step_ms.empty()) return 0.0;
  std::vector<double> sorted = step_ms;
  std::sort(sorted.begin(), sorted.end());
  const size_t mid = sorted.size() / 2;
  return sorted.size() % 2 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
}

double RunTotals::max_step_ms() const {
  return step_ms.empty() ? 0.0 : *std::max_element(step_ms.begin(), step_ms.end());
}

}  // namespace cellphys::cli
