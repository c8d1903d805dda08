// Stage times: each stage timed from the end of the one before it in the step, so a stage is
// never counted twice nor from before the step (that a step's stages add up to at most the step
// is tests/test_cli.cpp's, through `cellphys run --stats`).
#include "runtime/ppe/step_stats.h"

#include <gtest/gtest.h>

#include <chrono>

namespace cellphys::ppe {
namespace {

using Clock = std::chrono::steady_clock;

TEST(StageTimer, StartsWhereTheStageBeforeItEnded) {
  StepStats st;
  const Clock::time_point start = Clock::now() - std::chrono::seconds(10);
  st.stage_end = start;
  { StageTimer t(st, &StageTimes::broad_ms); }
  EXPECT_GE(st.times.broad_ms, 10000.0);  // from the step's start, ten seconds back
  EXPECT_GT(st.stage_end, start);
  const Clock::time_point broad_end = st.stage_end;
  { StageTimer t(st, &StageTimes::mid_ms); }
  EXPECT_LT(st.times.mid_ms, 10000.0);  // from broad's end: its ten seconds are not counted again
  EXPECT_GE(st.stage_end, broad_end);
  const double both = std::chrono::duration<double, std::milli>(st.stage_end - start).count();
  EXPECT_NEAR(st.times.broad_ms + st.times.mid_ms, both, 1e-6);  // nothing between them lost
}

TEST(StageTimer, OutsideAStepTimesFromItsOwnStart) {
  StepStats st;  // stage_end unset: not since the clock's epoch
  { StageTimer t(st, &StageTimes::narrow_ms); }
  EXPECT_GE(st.times.narrow_ms, 0.0);
  EXPECT_LT(st.times.narrow_ms, 1000.0);
  EXPECT_NE(st.stage_end, Clock::time_point{});
}

}  // namespace
}  // namespace cellphys::ppe
