// The stages message (protocol::Stages): the wall time of each stage of a step, under the names
// ppe::kStageTimeFields gives them, so a stage added to the step reaches clients with no change
// here or in them.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/step_stats.h"

namespace cellphys::server {

std::vector<unsigned char> encode_stages(uint64_t step, uint32_t epoch, const ppe::StageTimes& times);

}  // namespace cellphys::server
