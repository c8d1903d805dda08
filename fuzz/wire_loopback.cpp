#include "fuzz/wire_loopback.h"

#include <cstring>

#include "runtime/scene/scene.h"

namespace cellphys::fuzz {

std::vector<unsigned char> scene_snapshot(const std::string& name) {
  return scene::build_world(scene::load_scene(std::string(CELLPHYS_SCENES_DIR) + "/" + name + ".json")).world->snapshot();
}

WireLoopback::WireLoopback(Node node) : node_(std::move(node)) {}

void WireLoopback::run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) {
  reports.assign(jobs.size(), spu::IslandReport{});
  ppe::wire::begin_batch(ppe::wire::kJobsMagic, ++sequence_, local_store_, jobs_);
  for (uint32_t k = 0; k < jobs.size(); ++k) ppe::wire::append_job(jobs[k].image, jobs[k].bytes, k, jobs_);
  ppe::wire::seal_batch(jobs_);
  if (node_) node_(jobs_, answer_);
  else kernel_.serve(jobs_.data(), jobs_.size(), answer_);
  std::vector<char> done(jobs.size(), 0);
  ppe::wire::read_results(
      answer_.data(), answer_.size(), sequence_, jobs, reports, [&](uint32_t k) { return !done[k]; },
      [&](uint32_t k, const std::string& why) { done[k] = why.empty() ? 1 : 2; });
  for (uint32_t k = 0; k < jobs.size(); ++k)
    if (done[k] != 1) {  // the IslandRunner contract: header zeroed, marked malformed
      std::memset(jobs[k].result, 0, std::min(jobs[k].result_capacity, sizeof(gen::Island_Result)));
      reports[k] = spu::IslandReport{};
      reports[k].status = spu::IslandStatus::malformed;
    }
}

}  // namespace cellphys::fuzz
