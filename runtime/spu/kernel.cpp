#include "runtime/spu/kernel.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "runtime/spu/integrators.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

constexpr unsigned kTagIn = 1, kTagOut = 2;

// Fixed-size substeps: a failed step is retried as two halves, down to max_halvings.
bool substep(StepContext& c, Integrator integ, float h, uint32_t depth, uint32_t max_depth, IslandReport& r) {
  bool ok = false;
  switch (integ) {
    case Integrator::implicit_split: ok = step_implicit(c, h, true); break;
    case Integrator::implicit_euler: ok = step_implicit(c, h, false); break;
    case Integrator::symplectic_euler: ok = step_explicit(c, h, true); break;
    case Integrator::explicit_euler: ok = step_explicit(c, h, false); break;
    case Integrator::rk4: ok = step_rk4(c, h); break;
    case Integrator::rosenbrock: break;  // adaptive, below
  }
  if (ok) {
    r.substeps += 1;
    return true;
  }
  if (depth >= max_depth) return false;
  r.halvings = std::max(r.halvings, depth + 1);
  return substep(c, integ, 0.5f * h, depth + 1, max_depth, r) && substep(c, integ, 0.5f * h, depth + 1, max_depth, r);
}

// Adaptive ROS2: the step follows the requested error; a failed or rejected step shrinks.
bool adaptive(StepContext& c, float H, uint32_t max_halvings, IslandReport& r) {
  const float min_h = H / float(1u << max_halvings);
  float t = 0.0f, h = H;
  while (H - t > 1e-7f * H) {
    h = std::min(h, H - t);
    float err = 0.0f;
    if (step_rosenbrock(c, h, &err)) {
      t += h;
      r.substeps += 1;
      h *= std::clamp(0.9f / std::sqrt(std::max(err, 1e-10f)), 0.2f, 2.0f);
    } else {
      h *= (err > 1.0f && std::isfinite(err)) ? std::clamp(0.9f / std::sqrt(err), 0.2f, 0.5f) : 0.5f;
      const auto depth = static_cast<uint32_t>(std::ceil(std::log2(H / h) - 1e-6));
      r.halvings = std::max(r.halvings, depth);
      if (h < min_h * 0.999f) return false;
    }
  }
  return true;
}

}  // namespace

ComputeWorker::ComputeWorker(size_t local_store_bytes) : ls_(local_store_bytes), dma_(ls_) {}

IslandReport ComputeWorker::step(const unsigned char* image, size_t bytes, unsigned char* result, size_t result_capacity) {
  IslandReport r;
  ls_.reset();
  ls_.reset_peak();
  auto refuse = [&](IslandStatus s, std::string why) {
    r.status = s;
    r.error = std::move(why);
    // a refused island's result: a header and, when there is room, its bodies unchanged
    Island_Result res{};
    res.magic = kResultMagic;
    res.status = static_cast<uint32_t>(s);
    Island_Header h{};
    if (bytes >= sizeof h) std::memcpy(&h, image, sizeof h);
    res.island_id = h.island_id;
    res.local_store_bytes = static_cast<uint32_t>(std::min<size_t>(r.footprint.total, 0xFFFFFFFFu));
    if (result_capacity >= sizeof res) std::memcpy(result, &res, sizeof res);
    return r;
  };
  // 1. Header and section table first: enough to account for the island's bytes.
  if (bytes < sizeof(Island_Header) || reinterpret_cast<uintptr_t>(image) % 16 || reinterpret_cast<uintptr_t>(result) % 16)
    return refuse(IslandStatus::malformed, "image shorter than a header or not 16-byte aligned");
  auto* head = static_cast<unsigned char*>(ls_.allocate(sizeof(Island_Header), 16, Region::input));
  dma_.get(head, image, sizeof(Island_Header), kTagIn);
  dma_.wait(1u << kTagIn);
  Island_Header h;
  std::memcpy(&h, head, sizeof h);
  if (h.magic != kIslandMagic || h.version != kIslandVersion || h.total_bytes != bytes || h.num_bodies == 0 ||
      h.num_sections > static_cast<uint32_t>(kNumForceTypes) || h.integrator >= static_cast<uint32_t>(kNumIntegrators) ||
      h.solver > 2)
    return refuse(IslandStatus::malformed, "bad header: " + validate_island(image, bytes));
  const IslandLayout layout = island_layout(h.num_bodies, h.num_sections);
  if (layout.instances > bytes) return refuse(IslandStatus::malformed, "too short for its bodies");
  IslandCounts counts;
  counts.num_bodies = h.num_bodies;
  counts.num_blocks = h.num_blocks;
  counts.image_bytes = h.total_bytes;
  counts.integrator = static_cast<Integrator>(h.integrator);
  counts.solver = static_cast<Solver>(h.solver);
  {
    std::vector<Island_Section> sections(h.num_sections);
    std::memcpy(sections.data(), image + layout.sections, h.num_sections * sizeof(Island_Section));
    for (const Island_Section& s : sections) {
      if (s.force_type >= static_cast<uint32_t>(kNumForceTypes) || s.world_count > s.count)
        return refuse(IslandStatus::malformed, validate_island(image, bytes));
      if (kForceTable[s.force_type].offset_body_b >= 0) counts.pair_instances += s.count - s.world_count;
    }
  }
  r.footprint = footprint(counts);
  if (r.footprint.total > ls_.capacity())
    return refuse(IslandStatus::does_not_fit, "island needs " + std::to_string(r.footprint.total) +
                                                  " bytes of local store, capacity " + std::to_string(ls_.capacity()));
  if (result_capacity < result_bytes(h.num_bodies)) return refuse(IslandStatus::malformed, "result buffer too small");
  ls_.reset();
  // 2. The island into the local store, with room reserved for the next one and the last result.
  auto* in = static_cast<unsigned char*>(ls_.allocate(bytes, 32, Region::input));
  auto* out = static_cast<unsigned char*>(ls_.allocate(r.footprint.bytes[int(Region::output)], 32, Region::output));
  const bool reserved = ls_.allocate(r.footprint.bytes[int(Region::double_buffer)], 32, Region::double_buffer) != nullptr;
  dma_.get(in, image, bytes, kTagIn);
  dma_.wait(1u << kTagIn);
  const std::string why = validate_island(in, bytes);
  if (!why.empty()) return refuse(IslandStatus::malformed, why);
  Workspace ws;
  if (!in || !out || !reserved || !allocate_workspace(ls_, counts, ws))
    return refuse(IslandStatus::does_not_fit, "local store exhausted (accounting bug)");

  // 3. Integrate, halving on failure.
  StepContext c;
  c.island = view_island(in);
  c.ws = &ws;
  c.solver = counts.solver;
  c.solve.rel_tol = h.tolerance;
  c.solve.abs_tol = h.tolerance * 1e-3f;
  c.error_tolerance = h.tolerance;
  const int n = static_cast<int>(h.num_bodies);
  auto* res = reinterpret_cast<Island_Result*>(out);
  auto* steps = reinterpret_cast<Rigid_Body_Step*>(out + align16(sizeof(Island_Result)));
  for (int i = 0; i < n; ++i) {  // the start velocities, so the output can be their change
    std::memset(&steps[i], 0, sizeof steps[i]);
    std::memcpy(steps[i].delta_velocity, c.island.bodies[i].velocity, 12);
    std::memcpy(steps[i].delta_angular_velocity, c.island.bodies[i].angular_velocity, 12);
  }
  bool ok = prepare(c);
  if (!ok) return refuse(IslandStatus::malformed, "block structure does not match num_blocks");
  if (counts.integrator == Integrator::rosenbrock)
    ok = adaptive(c, h.step, h.max_halvings, r);
  else
    ok = substep(c, counts.integrator, h.step, 0, h.max_halvings, r);
  r.solver_iterations = static_cast<uint32_t>(c.stats.solver_iterations);
  r.solves = static_cast<uint32_t>(c.stats.solves);
  r.solver_code = static_cast<uint32_t>(c.stats.last_solver_code);
  r.rejected = static_cast<uint32_t>(c.stats.rejected);
  r.status = ok ? IslandStatus::ok : IslandStatus::failed;
  r.local_store_peak = ls_.peak();

  // 4. The result: header, the seed's Rigid_Body_Step per body, and the advanced bodies
  // (the original bodies when the step failed: nothing half-stepped leaves the kernel).
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      steps[i].delta_velocity[k] = ok ? c.island.bodies[i].velocity[k] - steps[i].delta_velocity[k] : 0.0f;
      steps[i].delta_angular_velocity[k] =
          ok ? c.island.bodies[i].angular_velocity[k] - steps[i].delta_angular_velocity[k] : 0.0f;
    }
  }
  const size_t steps_bytes = size_t(n) * sizeof(Rigid_Body_Step);
  const unsigned char* bodies_src = ok ? reinterpret_cast<unsigned char*>(c.island.bodies) : image + layout.bodies;
  const size_t bodies_bytes = size_t(n) * sizeof(Rigid_Body);
  std::memset(res, 0, sizeof *res);
  res->magic = kResultMagic;
  res->status = static_cast<uint32_t>(r.status);
  res->island_id = h.island_id;
  res->num_bodies = h.num_bodies;
  res->solver_iterations = r.solver_iterations;
  res->solves = r.solves;
  res->halvings = r.halvings;
  res->substeps = r.substeps;
  res->solver_code = r.solver_code;
  res->local_store_bytes = static_cast<uint32_t>(r.footprint.total);
  res->total_bytes = static_cast<uint32_t>(result_bytes(h.num_bodies));
  res->checksum = checksum(bodies_src, bodies_bytes, checksum(reinterpret_cast<unsigned char*>(steps), steps_bytes));
  const size_t head_bytes = align16(sizeof(Island_Result));
  dma_.put(result, out, head_bytes + steps_bytes, kTagOut);
  if (ok)
    dma_.put(result + head_bytes + steps_bytes, bodies_src, bodies_bytes, kTagOut);
  else
    std::memcpy(result + head_bytes + steps_bytes, bodies_src, bodies_bytes);  // main to main: unchanged state
  dma_.wait(1u << kTagOut);
  return r;
}

}  // namespace cellphys::spu
