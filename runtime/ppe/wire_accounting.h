// What the islands of a step would cost in the reference design's wire tables
// (docs/distributed.md), whatever runner computes them: the figures StepStats reports.
#pragma once
#include "runtime/ppe/island_packer.h"
#include "runtime/ppe/shapes.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

/// Adds one packed island: per body 22 floats and its shape's geometry, or 25 floats with a
/// dictionary reference, out; 13 floats back. The island's header, force and contact records
/// go out in both forms.
void count_wire_tables(const PackedIsland& p, const ShapeDictionary& shapes, StepStats& st);

/// Adds the wire-table figures counted into `part` (a thread's share) to `st`.
void add_wire_tables(const StepStats& part, StepStats& st);

}  // namespace cellphys::ppe
