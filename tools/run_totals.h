// A run's statistics, gathered from each step's ppe::StepStats: each figure is the sum, the
// maximum or the last value of one StepStats field over the steps (the table in run_totals.cpp
// says which), and the time each step took.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/step_stats.h"

namespace cellphys::cli {

struct RunTotals {
  // summed over the steps
  uint64_t solver_iterations = 0, solves = 0, step_halvings = 0, failed_islands = 0, decoupled_islands = 0,
           pushed_bodies = 0;
  // transport and the reference design's wire tables (runtime/ppe/step_stats.h), summed over the steps
  uint64_t bytes_to_nodes = 0, bytes_from_nodes = 0, messages = 0, bad_messages = 0, recomputed_islands = 0,
           reassigned_islands = 0, dropped_nodes = 0, island_bodies = 0, island_bytes_shared = 0,
           wire_table_to_nodes = 0, wire_table_to_nodes_compressed = 0, wire_table_from_nodes = 0, image_bytes = 0,
           result_bytes = 0;
  // the largest of any step
  uint64_t contacts_max = 0, local_store_peak_bytes = 0;
  // after the last step (0 before any)
  uint64_t active_bodies = 0, sleeping_bodies = 0, islands = 0, contacts = 0;
  ppe::StageTimes stage_ms;     // each stage's time, summed over the steps
  std::vector<double> step_ms;  // wall time of each step

  explicit RunTotals(long long steps);  // reserves for that many steps
  void add(const ppe::StepStats& s, double ms);

  double median_step_ms() const;  // 0 before any step
  double max_step_ms() const;
};

}  // namespace cellphys::cli
