#include "runtime/spu/kernel.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "runtime/spu/integrators.h"
#include "runtime/spu/krylov.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

constexpr unsigned kTagIn = 1, kTagOut = 3;  // inputs on tags 1-2, outputs on 3 (single) and 5-6 (slots)

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

ComputeWorker::ComputeWorker(size_t local_store_bytes) : ls_(local_store_bytes), dma_(ls_) {
  // a batch of this many islands plans without allocating from the first: a world's threads
  // take runs of up to 32, so which thread gets the longest run does not decide who allocates
  plans_.reserve(kBatchReserve);
  ok_.reserve(kBatchReserve);
}

namespace {

// A refused island's result: a header and, when there is room, its bodies unchanged.
void write_refusal(const IslandJob& job, IslandReport& r, IslandStatus s, std::string why) {
  r.status = s;
  r.error = std::move(why);
  Island_Result res{};
  res.magic = kResultMagic;
  res.status = static_cast<uint32_t>(s);
  Island_Header h{};
  if (job.bytes >= sizeof h) std::memcpy(&h, job.image, sizeof h);
  res.island_id = h.island_id;
  res.num_bodies = h.num_bodies;
  res.local_store_bytes = static_cast<uint32_t>(std::min<size_t>(r.footprint.total, 0xFFFFFFFFu));
  res.total_bytes = sizeof res;
  if (job.result_capacity >= sizeof res) std::memcpy(job.result, &res, sizeof res);
  const IslandLayout l = island_layout(h.num_bodies, h.num_sections);
  const size_t body_bytes = size_t{h.num_bodies} * sizeof(Rigid_Body);
  if (s == IslandStatus::does_not_fit && job.result_capacity >= result_bytes(h.num_bodies) && l.instances <= job.bytes) {
    std::memset(job.result + sizeof res, 0, size_t{h.num_bodies} * sizeof(Rigid_Body_Step));
    std::memcpy(job.result + result_bytes(h.num_bodies) - body_bytes, job.image + l.bodies, body_bytes);
  }
}

// The header and the counts its section table gives, read the way the control side's
// scheduler would: enough to account for every byte before the island is fetched.
enum class Unreadable { none, header, bodies, sections };
Unreadable read_counts(const IslandJob& job, Island_Header& h, IslandCounts& c) {
  std::memcpy(&h, job.image, sizeof h);
  if (h.magic != kIslandMagic || h.version != kIslandVersion || h.total_bytes != job.bytes || h.num_bodies == 0 ||
      h.num_sections > static_cast<uint32_t>(kNumForceTypes) || h.integrator >= static_cast<uint32_t>(kNumIntegrators) ||
      h.solver >= static_cast<uint32_t>(kNumSolvers))
    return Unreadable::header;
  const IslandLayout layout = island_layout(h.num_bodies, h.num_sections);
  if (layout.instances > job.bytes) return Unreadable::bodies;
  c.num_bodies = h.num_bodies;
  c.num_blocks = h.num_blocks;
  c.image_bytes = h.total_bytes;
  c.integrator = static_cast<Integrator>(h.integrator);
  c.solver = static_cast<Solver>(h.solver);
  c.force_types = 0;
  for (uint32_t k = 0; k < h.num_sections; ++k) {
    Island_Section s;
    std::memcpy(&s, job.image + layout.sections + k * sizeof s, sizeof s);
    if (s.force_type >= static_cast<uint32_t>(kNumForceTypes) || s.world_count > s.count) return Unreadable::sections;
    if (kForceTable[s.force_type].offset_body_b >= 0) c.pair_instances += s.count - s.world_count;
    c.force_types |= 1u << s.force_type;
  }
  return Unreadable::none;
}

// Whether the section table (read from main memory, as read_counts reads it) lists the force
// types in increasing order, as IslandBuilder writes them.
bool sections_ascending_in(const IslandJob& job, uint32_t num_bodies, uint32_t num_sections) {
  const IslandLayout layout = island_layout(num_bodies, num_sections);
  uint32_t last = 0;
  for (uint32_t k = 0; k < num_sections; ++k) {
    Island_Section s;
    std::memcpy(&s, job.image + layout.sections + k * sizeof s, sizeof s);
    if (k > 0 && s.force_type <= last) return false;
    last = s.force_type;
  }
  return true;
}

}  // namespace

size_t ComputeWorker::bytes_needed(const IslandJob& job) {
  Island_Header h;
  IslandCounts c;
  if (job.bytes < sizeof h || read_counts(job, h, c) != Unreadable::none) return 0;
  return footprint(c).total;
}

bool ComputeWorker::plan(const IslandJob& job, Plan& p, IslandReport& r) {
  if (job.bytes < sizeof(Island_Header) || reinterpret_cast<uintptr_t>(job.image) % 16 ||
      reinterpret_cast<uintptr_t>(job.result) % 16) {
    write_refusal(job, r, IslandStatus::malformed, "image shorter than a header or not 16-byte aligned");
    return false;
  }
  const Island_Header& h = p.header;
  IslandCounts& c = p.counts;
  switch (read_counts(job, p.header, c)) {
    case Unreadable::none: break;
    case Unreadable::header:
      write_refusal(job, r, IslandStatus::malformed, "bad header: " + validate_island(job.image, job.bytes, !job.trusted));
      return false;
    case Unreadable::bodies: write_refusal(job, r, IslandStatus::malformed, "too short for its bodies"); return false;
    case Unreadable::sections: write_refusal(job, r, IslandStatus::malformed, validate_island(job.image, job.bytes, !job.trusted));
      return false;
  }
  p.ascending = sections_ascending_in(job, h.num_bodies, h.num_sections);
  p.footprint = footprint(c);
  r.footprint = p.footprint;
  if (r.footprint.total > ls_.capacity()) {
    write_refusal(job, r, IslandStatus::does_not_fit,
                  "island needs " + std::to_string(r.footprint.total) + " bytes of local store, capacity " +
                      std::to_string(ls_.capacity()));
    return false;
  }
  if (job.result_capacity < result_bytes(h.num_bodies)) {
    write_refusal(job, r, IslandStatus::malformed, "result buffer too small");
    return false;
  }
  return true;
}

bool ComputeWorker::begin(const IslandJob& job, const Plan& p, unsigned char* in, unsigned char* out, IslandReport& r,
                          Active& a) {
  const Island_Header& h = p.header;
  // A trusted image is this process's packer's, read by nothing else: plan() has read its
  // header and section table; debug builds check the rest all the same.
#ifdef NDEBUG
  const bool check = !job.trusted;
#else
  const bool check = true;
#endif
  const std::string why = check ? validate_island(in, job.bytes, !job.trusted) : std::string();
  if (!why.empty()) {
    write_refusal(job, r, IslandStatus::malformed, why);
    return false;
  }
  a.mark = ls_.used();
  if (!allocate_workspace(ls_, p.counts, p.footprint, a.ws)) {
    write_refusal(job, r, IslandStatus::does_not_fit, "local store exhausted (accounting bug)");
    return false;
  }
  StepContext& c = a.c;
  c = StepContext{};
  c.island = view_island(in);
  c.ws = &a.ws;
  c.solver = p.counts.solver;
  c.solve.rel_tol = h.tolerance;
  c.solve.abs_tol = h.tolerance * 1e-3f;
  c.solve.zero_rhs = 0.0f;
  c.solve.sharer = sharer_;
  c.error_tolerance = h.tolerance;
  const int n = static_cast<int>(h.num_bodies);
  auto* steps = reinterpret_cast<Rigid_Body_Step*>(out + align16(sizeof(Island_Result)));
  for (int i = 0; i < n; ++i) {  // the start velocities, so the output can be their change
    std::memset(&steps[i], 0, sizeof steps[i]);
    std::memcpy(steps[i].delta_velocity, c.island.bodies[i].velocity, 12);
    std::memcpy(steps[i].delta_angular_velocity, c.island.bodies[i].angular_velocity, 12);
  }
  if (!prepare(c)) {
    ls_.release(a.mark);
    write_refusal(job, r, IslandStatus::malformed, "num_blocks does not match the pair forces");
    return false;
  }
  return true;
}

bool ComputeWorker::integrate(const Plan& p, StepContext& c, IslandReport& r) {
  const Island_Header& h = p.header;
  if (p.counts.integrator == Integrator::rosenbrock) return adaptive(c, h.step, h.max_halvings, r);
  return substep(c, p.counts.integrator, h.step, 0, h.max_halvings, r);
}

void ComputeWorker::finish(const IslandJob& job, const Plan& p, unsigned char* out, const StepContext& c, bool ok,
                           IslandReport& r) {
  const Island_Header& h = p.header;
  r.solver_iterations = static_cast<uint32_t>(c.counters.solver_iterations);
  r.solves = static_cast<uint32_t>(c.counters.solves);
  r.solver_code = static_cast<uint32_t>(c.counters.last_solver_code);
  r.rejected = static_cast<uint32_t>(c.counters.rejected);
  r.status = ok ? IslandStatus::ok : IslandStatus::failed;
  const int n = static_cast<int>(h.num_bodies);
  auto* res = reinterpret_cast<Island_Result*>(out);
  auto* steps = reinterpret_cast<Rigid_Body_Step*>(out + align16(sizeof(Island_Result)));

  // The result: header, the reference design's Rigid_Body_Step per body, and the advanced bodies (the
  // original bodies when the step failed: nothing half-stepped leaves the kernel).
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      steps[i].delta_velocity[k] = ok ? c.island.bodies[i].velocity[k] - steps[i].delta_velocity[k] : 0.0f;
      steps[i].delta_angular_velocity[k] =
          ok ? c.island.bodies[i].angular_velocity[k] - steps[i].delta_angular_velocity[k] : 0.0f;
    }
  const IslandLayout layout = island_layout(h.num_bodies, h.num_sections);
  const size_t steps_bytes = size_t(n) * sizeof(Rigid_Body_Step);
  const unsigned char* bodies_src = ok ? reinterpret_cast<unsigned char*>(c.island.bodies) : job.image + layout.bodies;
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
  res->checksum = job.trusted ? 0u
                              : image_checksum(bodies_src, bodies_bytes,
                                               image_checksum(reinterpret_cast<unsigned char*>(steps), steps_bytes));
  const size_t head_bytes = align16(sizeof(Island_Result));
  dma_.put(job.result, out, head_bytes + steps_bytes, p.out_tag);
  if (ok)
    dma_.put(job.result + head_bytes + steps_bytes, bodies_src, bodies_bytes, p.out_tag);
  else
    std::memcpy(job.result + head_bytes + steps_bytes, bodies_src, bodies_bytes);  // main to main: unchanged
}

void ComputeWorker::compute(const IslandJob& job, const Plan& p, unsigned char* in, unsigned char* out, IslandReport& r) {
  Active& a = active_[0];
  if (!begin(job, p, in, out, r, a)) return;
  const bool ok = integrate(p, a.c, r);
  ls_.release(a.mark);
  finish(job, p, out, a.c, ok, r);
}

IslandReport ComputeWorker::step(const unsigned char* image, size_t bytes, unsigned char* result, size_t result_capacity) {
  return step(IslandJob{image, bytes, result, result_capacity});
}

IslandReport ComputeWorker::step(const IslandJob& job) {
  IslandReport r;
  step_batch(&job, 1, &r);
  return r;
}

void ComputeWorker::step_batch(const IslandJob* jobs, size_t count, IslandReport* reports) {
  // Every island is planned first; then runs of small islands that can go together are
  // integrated in lockstep (step_together) and the others one after another, double-buffered
  // (step_each).
  plans_.assign(count, Plan{});
  ok_.assign(count, 0);
  for (size_t k = 0; k < count; ++k) {
    reports[k] = IslandReport{};
    ok_[k] = plan(jobs[k], plans_[k], reports[k]);
  }
  size_t k = 0;
  while (k < count) {
    size_t e = together_end(k, count, reports);
    if (e - k >= 2) {
      step_together(jobs, k, e, reports);
      k = e;
      continue;
    }
    e = k + 1;
    while (e < count && together_end(e, count, reports) - e < 2) ++e;
    step_each(jobs, k, e, reports);
    k = e;
  }
}

bool ComputeWorker::can_go_together(size_t k, const IslandReport* reports) const {
  const Plan& p = plans_[k];
  const Integrator i = p.counts.integrator;
  return ok_[k] && p.ascending && (i == Integrator::implicit_split || i == Integrator::implicit_euler) &&
         reports[k].footprint.total <= ls_.capacity() / 4;
}

size_t ComputeWorker::together_bytes(size_t k, const IslandReport* reports) {
  // the island's own footprint without the double buffers, and alignment for its allocations
  return reports[k].footprint.total - reports[k].footprint.bytes[int(Region::double_buffer)] + 16 * 32;
}

size_t ComputeWorker::together_end(size_t k, size_t count, const IslandReport* reports) const {
  if (!can_go_together(k, reports)) return k;
  const Plan& first = plans_[k];
  uint32_t types = first.counts.force_types;
  size_t bytes = together_bytes(k, reports), e = k + 1;
  for (; e < count && e - k < kMaxTogether; ++e) {
    const Plan& p = plans_[e];
    if (!can_go_together(e, reports) || p.counts.integrator != first.counts.integrator || p.header.step != first.header.step)
      break;
    const uint32_t t = types | p.counts.force_types;
    const size_t b = bytes + together_bytes(e, reports);
    if (b + force_scratch_bytes(t) + 32 > ls_.capacity()) break;
    types = t, bytes = b;
  }
  return e;
}

void ComputeWorker::step_together(const IslandJob* jobs, size_t begin_k, size_t end_k, IslandReport* reports) {
  // Islands [begin_k, end_k) in the local store at once: each fetched, validated and given its
  // workspace; their first step's forces evaluated in one pass, SIMD lanes filled across
  // islands, and their diagonal blocks inverted likewise; each solved alone; their bodies'
  // rotations in shared lanes again; then each committed. An island whose first step fails is
  // stepped again alone, halving as step() would: every island's result is the bytes step()
  // gives it.
  const size_t m = end_k - begin_k;
  ls_.reset();
  ls_.reset_peak();
  uint32_t types = 0;
  for (size_t j = 0; j < m; ++j) {
    const size_t k = begin_k + j;
    const RegionBytes& b = reports[k].footprint.bytes;
    in_[j] = static_cast<unsigned char*>(ls_.allocate(b[int(Region::input)], 32, Region::input));
    out_[j] = static_cast<unsigned char*>(ls_.allocate(b[int(Region::output)], 32, Region::output));
    dma_.get(in_[j], jobs[k].image, jobs[k].bytes, kTagIn);
    plans_[k].out_tag = kTagOut;
    types |= plans_[k].counts.force_types;
  }
  auto* scratch = static_cast<float*>(ls_.allocate(force_scratch_bytes(types), 32, Region::scratch));
  dma_.wait(1u << kTagIn);
  const Integrator integ = plans_[begin_k].counts.integrator;
  const bool split = integ == Integrator::implicit_split;
  const float h = plans_[begin_k].header.step;
  size_t ready = 0;
  for (size_t j = 0; j < m; ++j) {
    const size_t k = begin_k + j;
    Active& a = active_[j];
    a.ready = begin(jobs[k], plans_[k], in_[j], out_[j], reports[k], a);
    if (!a.ready) continue;
    targets_[ready] = implicit_step_targets(a.c, h, split);
    force_jobs_[ready] = {&a.c.island, &targets_[ready]};
    ++ready;
  }
  evaluate_forces_together(force_jobs_.data(), static_cast<int>(ready), scratch);
  // every island's diagonal blocks inverted in one pass, eight to a group of SIMD lanes
  BlockInverter inverter;
  for (size_t j = 0; j < m; ++j) {
    Active& a = active_[j];
    a.singular = false;
    if (a.ready) add_implicit_diagonal(a.c, inverter, &a.singular);
  }
  inverter.flush();
  // every island solved, then all their bodies' rotations in one pass, eight to a group of SIMD lanes
  KickRotations rotations;
  for (size_t j = 0; j < m; ++j) {
    Active& a = active_[j];
    if (!a.ready) continue;
    a.failed = a.singular || !solve_inverted(a.c, h);
    if (!a.failed) add_kick_rotations(a.c, rotations, h, split, &a.failed);
  }
  rotations.flush();
  for (size_t j = 0; j < m; ++j) {
    const size_t k = begin_k + j;
    Active& a = active_[j];
    if (!a.ready) continue;
    bool ok = !a.failed;
    if (ok) {
      commit_step(a.c, h);
      reports[k].substeps += 1;
    } else {  // the same first step again, then its halves, as step() takes them
      a.c.counters = IntegrationCounters{};
      ok = integrate(plans_[k], a.c, reports[k]);
    }
    finish(jobs[k], plans_[k], out_[j], a.c, ok, reports[k]);
  }
  dma_.wait(1u << kTagOut);
  for (size_t j = 0; j < m; ++j) reports[begin_k + j].local_store_peak = ls_.peak();
}

void ComputeWorker::step_each(const IslandJob* jobs, size_t begin_k, size_t end_k, IslandReport* reports) {
  // Two input and two output slots, sized for the largest island of the run, below the
  // working set: island k computes from slot k % 2 while island k + 1 is fetched into the
  // other and island k - 1's result drains from the other output slot. An island whose
  // own footprint (with double buffering, as the reference design counts it) does not fit is refused.
  std::vector<Plan>& plans = plans_;
  std::vector<char>& ok = ok_;
  size_t in_slot = 0, out_slot = 0, work = 0;
  for (size_t k = begin_k; k < end_k; ++k) {
    if (!ok[k]) continue;
    const RegionBytes& b = reports[k].footprint.bytes;
    in_slot = std::max(in_slot, b[int(Region::input)]);
    out_slot = std::max(out_slot, b[int(Region::output)]);
    work = std::max(work, reports[k].footprint.total - 2 * (b[int(Region::input)] + b[int(Region::output)]));
  }
  ls_.reset();
  ls_.reset_peak();
  const bool overlap = 2 * (in_slot + out_slot) + work <= ls_.capacity();
  if (!overlap) {  // islands too different in size to share slots: one at a time
    for (size_t k = begin_k; k < end_k; ++k) {
      if (!ok[k]) continue;
      ls_.reset();
      const RegionBytes& b = reports[k].footprint.bytes;
      auto* in = static_cast<unsigned char*>(ls_.allocate(b[int(Region::input)], 32, Region::input));
      auto* out = static_cast<unsigned char*>(ls_.allocate(b[int(Region::output)], 32, Region::output));
      ls_.allocate(b[int(Region::double_buffer)], 32, Region::double_buffer);  // accounted as the reference design does
      plans[k].out_tag = kTagOut;
      dma_.get(in, jobs[k].image, jobs[k].bytes, kTagIn);
      dma_.wait(1u << kTagIn);
      compute(jobs[k], plans[k], in, out, reports[k]);
      dma_.wait(1u << kTagOut);
      reports[k].local_store_peak = ls_.peak();
    }
    return;
  }
  unsigned char* in[2];
  unsigned char* out[2];
  for (int s = 0; s < 2; ++s) {
    in[s] = static_cast<unsigned char*>(ls_.allocate(in_slot, 32, s ? Region::double_buffer : Region::input));
    out[s] = static_cast<unsigned char*>(ls_.allocate(out_slot, 32, s ? Region::double_buffer : Region::output));
  }
  auto fetch = [&](size_t k) {
    if (k < end_k && ok[k]) dma_.get(in[k % 2], jobs[k].image, jobs[k].bytes, kTagIn + unsigned(k % 2));
  };
  fetch(begin_k);
  for (size_t k = begin_k; k < end_k; ++k) {
    // island k - 1's result (its advanced bodies are put from its input slot) drains before
    // island k + 1 is fetched into that slot; then the next island loads while this one computes
    dma_.wait(1u << (kTagOut + 2 + unsigned((k + 1) % 2)));
    fetch(k + 1);
    if (!ok[k]) continue;
    const unsigned slot = unsigned(k % 2);
    dma_.wait(1u << (kTagIn + slot));
    plans[k].out_tag = kTagOut + 2 + slot;
    compute(jobs[k], plans[k], in[slot], out[slot], reports[k]);
    reports[k].local_store_peak = ls_.peak();
  }
  dma_.wait_all();
}

}  // namespace cellphys::spu
