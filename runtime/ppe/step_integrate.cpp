#include "runtime/ppe/step_integrate.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "runtime/base/radix_sort.h"
#include "runtime/ppe/result_check.h"
#include "runtime/ppe/wire_accounting.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

void add_transport(const TransportCounters& tc, StepStats& st) {
  st.bytes_to_nodes += tc.bytes_to_nodes;
  st.bytes_from_nodes += tc.bytes_from_nodes;
  st.messages += tc.messages_to_nodes + tc.messages_from_nodes;
  st.bad_messages += tc.bad_messages;
  st.reassigned_islands += tc.reassigned_islands;
  st.dropped_nodes += tc.dropped_nodes;
}

void add_report(const spu::IslandReport& r, StepStats& st) {
  st.solver_iterations += r.solver_iterations;
  st.solves += r.solves;
  st.step_halvings = std::max(st.step_halvings, r.halvings);
  st.substeps += r.substeps;
  st.local_store_peak_bytes = std::max(st.local_store_peak_bytes, r.footprint.total);
}

// Parts of at most this many bodies, contacts and forces go to a thread a run at a time.
constexpr size_t kSmallPart = 32, kPartsPerRun = 32;

size_t part_size(const IslandContent& part) { return part.bodies.size() + part.contacts.size() + part.forces.size(); }

// The job order: largest first, so the long islands start early on the workers, then in part
// order. Keys of (largest - size, index), all distinct, in as few bits as they need (the sort's
// passes follow them).
template <class Size>
void largest_first(size_t used, Size size_of, IntegrateScratch& sc) {
  size_t largest = 0;
  for (size_t i = 0; i < used; ++i) largest = std::max(largest, size_of(i));
  const int index_bits = bits_used(used);
  sc.order_keys.resize(used);
  for (size_t i = 0; i < used; ++i) sc.order_keys[i] = uint64_t(largest - size_of(i)) << index_bits | i;
  radix_sort_keys(sc.order_keys, sc.sort_buffer);
  sc.order.resize(used);
  const uint64_t index = (uint64_t{1} << index_bits) - 1;
  for (size_t j = 0; j < used; ++j) sc.order[j] = size_t(sc.order_keys[j] & index);
}

void pack_one(const PackContext& pc, const IslandContent& part, PackScratch& scratch, PackedIsland& p, bool seal = true) {
  pack_island(pc, part, scratch, p, seal);
  p.result.assign(spu::result_bytes(static_cast<uint32_t>(p.bodies.size())), 0);
}

spu::IslandJob job_of(PackedIsland& p) { return {p.image.data(), p.image.size(), p.result.data(), p.result.size(), !p.sealed}; }

// The wave on another runner (compute nodes): every part packed (on the world's threads when
// it has them: each image depends on its part alone), then all run at once.
void pack_and_run(const PackContext& pc, const ShapeDictionary& shapes, IslandRunner& runner, WorkerPool* threads,
                  IntegrateScratch& sc, StepStats& st) {
  const size_t used = sc.todo.size();
  {
    StageTimer t(st, &StageTimes::pack_ms);
    if (threads && threads->size() > 1 && used > 1) {
      sc.thread_pack.resize(size_t(threads->size()));
      // A few dozen ranges: small islands pack in a few hundred nanoseconds each.
      const size_t grain = std::clamp<size_t>(used / (8 * size_t(threads->size())), 1, 32);
      threads->for_ranges(used, grain, [&](size_t begin, size_t end, int thread) {
        for (size_t i = begin; i < end; ++i) pack_one(pc, *sc.todo[i], sc.thread_pack[size_t(thread)], sc.packed[i]);
      });
      match_capacities(sc.thread_pack);
    } else {
      for (size_t i = 0; i < used; ++i) pack_one(pc, *sc.todo[i], sc.pack, sc.packed[i]);
    }
    largest_first(used, [&](size_t i) { return sc.packed[i].image.size(); }, sc);
    for (size_t k : sc.order) {
      sc.jobs.push_back(job_of(sc.packed[k]));
      count_wire_tables(sc.packed[k], shapes, st);
    }
  }
  StageTimer t(st, &StageTimes::integrate_ms);
  runner.run(sc.jobs, sc.reports);
  add_transport(runner.last_transport(), st);
}

// A part that is one body touching only the world (static geometry, forces anchored to the
// world). Up to kLoneShare of them share one image, as long as it surely fits a quarter of the
// local store (so that such images are still stepped several together): the kernel solves a
// system with no off-diagonal block a body at a time, so each body gets the bits it gets packed
// alone, and the image's fixed costs (header, workspace, solve set-up, fetch and result) are
// paid once. Only for the implicit Euler steps: an adaptive step's error estimate, and so its
// step sizes, would be the whole image's. (World1000's first step on one worker: 986 us with
// an image per part, 760 us shared; docs/bench.md, "Per-island cost".)
constexpr size_t kLoneShare = 32;

bool lone(const PackContext& pc, const IslandContent& part) {
  if (part.bodies.size() != 1) return false;
  const uint32_t id = part.bodies[0];
  const auto only = [id](uint32_t a, uint32_t b) { return (a == id || a == kWorldBody) && (b == id || b == kWorldBody); };
  for (uint32_t c : part.contacts)
    if (!only(pc.contacts[c].a, pc.contacts[c].b)) return false;
  for (uint32_t f : part.forces)
    if (!only(pc.forces[f].a, pc.forces[f].b)) return false;
  return true;
}

bool shares_images(const WorldSettings& s) {
  return s.integrator == spu::Integrator::implicit_split || s.integrator == spu::Integrator::implicit_euler;
}

// Jobs [b, e) of a thread's run as the images it steps: runs of lone parts merged into one
// image each (one of the thread's shared images), every other part alone in its own slot.
void pack_shares(const PackContext& pc, const PackContext& shared_pc, const ShapeDictionary& shapes, IntegrateScratch& sc,
                 size_t b, size_t e, PackScratch& pack, ThreadShares& t, StepStats& st) {
  t.groups.clear();
  t.jobs.clear();
  size_t shared = 0;
  const bool share = shares_images(pc.settings);
  const size_t fit = pc.settings.local_store_bytes / 4;
  for (size_t j = b; j < e;) {
    size_t g = j + 1;
    const IslandContent& first = *sc.todo[sc.order[j]];
    if (share && lone(pc, first)) {
      while (g < e && g - j < kLoneShare && lone(pc, *sc.todo[sc.order[g]])) ++g;
      // the bound checked once for the whole run of lone parts, halved while it does not fit
      while (g - j > 1) {
        size_t contacts = 0, force_bytes = 0;
        for (size_t m = j; m < g; ++m) {
          const IslandContent& c = *sc.todo[sc.order[m]];
          contacts += c.contacts.size();
          for (uint32_t f : c.forces) force_bytes += pc.forces[f].instance.size();
        }
        if (spu::footprint(counts_at_least(pc.settings, g - j, contacts, force_bytes, 0)).total <= fit) break;
        g = j + (g - j) / 2;
      }
    }
    const IslandContent* part = &first;
    const PackContext* with = &pc;
    PackedIsland* p = &sc.packed[sc.order[j]];
    if (g - j > 1) {
      if (shared == t.images.size()) t.images.emplace_back();
      p = &t.images[shared++];
      t.merged.bodies.clear(), t.merged.contacts.clear(), t.merged.forces.clear();
      for (size_t m = j; m < g; ++m) {
        const IslandContent& c = *sc.todo[sc.order[m]];
        t.merged.bodies.push_back(c.bodies[0]);
        t.merged.contacts.insert(t.merged.contacts.end(), c.contacts.begin(), c.contacts.end());
        t.merged.forces.insert(t.merged.forces.end(), c.forces.begin(), c.forces.end());
      }
      std::sort(t.merged.bodies.begin(), t.merged.bodies.end());
      part = &t.merged;
      with = &shared_pc;
    }
    pack_one(*with, *part, pack, *p, /*seal=*/false);
    t.groups.push_back({j, g, g - j > 1 ? shared - 1 : 0});
    t.jobs.push_back(job_of(*p));
    count_wire_tables(*p, shapes, st);
    j = g;
  }
  t.reports.resize(t.jobs.size());
}

// Every thread's merge lists and shared images as large as the largest any thread has used:
// which thread takes which run varies from step to step, and a warm step allocates nothing.
void match_shared_capacities(std::vector<ThreadShares>& threads) {
  size_t contacts = 0, forces = 0, images = 0, image = 0, result = 0, bodies = 0;
  for (const ThreadShares& t : threads) {
    contacts = std::max(contacts, t.merged.contacts.capacity());
    forces = std::max(forces, t.merged.forces.capacity());
    images = std::max(images, t.images.size());
    for (const PackedIsland& p : t.images) {
      image = std::max(image, p.image.capacity());
      result = std::max(result, p.result.capacity());
      bodies = std::max(bodies, p.bodies.capacity());
    }
  }
  for (ThreadShares& t : threads) {
    t.merged.contacts.reserve(contacts), t.merged.forces.reserve(forces);
    t.images.resize(images);
    for (PackedIsland& p : t.images) p.image.reserve(image), p.result.reserve(result), p.bodies.reserve(bodies), p.ghost.reserve(bodies);
  }
}

// The wave on the world's own threads: a thread packs, steps and unpacks each run of parts it
// takes, so their images, results and bodies stay in its core's cache (on 2 workers the
// 1,000-body world steps 7% faster than packed on one core and stepped on the other). Their
// images are unsealed (IslandJob::trusted): no bytes leave the process, so the three checksums
// of each (packed, stepped, checked) and the kernel's full validation bought nothing (4% of
// a step of one-body islands). A result is unpacked there only when sound; the rest are left
// to the checks after. A shared image that fails (a body of it halved, say) is stepped again
// a part at a time, so each part's result is what it gets alone.
void pack_run_unpack(const PackContext& pc, const ShapeDictionary& shapes, WorkerPool& pool, std::vector<WorldBody>& bodies,
                     IntegrateScratch& sc, StepStats& st) {
  const size_t used = sc.todo.size();
  {
    StageTimer t(st, &StageTimes::pack_ms);
    largest_first(used, [&](size_t i) { return part_size(*sc.todo[i]); }, sc);
    sc.runs.clear();
    for (size_t k = 0; k < used;) {
      size_t e = k + 1;
      if (part_size(*sc.todo[sc.order[k]]) <= kSmallPart)
        while (e < used && e - k < kPartsPerRun && part_size(*sc.todo[sc.order[e]]) <= kSmallPart) ++e;
      sc.runs.push_back({k, e});
      k = e;
    }
    sc.thread_pack.resize(size_t(pool.size()));
    sc.threads.resize(size_t(pool.size()));
    for (ThreadShares& ts : sc.threads) ts.reserve(kPartsPerRun);
    sc.jobs.resize(used);
    sc.reports.resize(used);
    sc.thread_stats.assign(size_t(pool.size()), StepStats{});
  }
  // A shared image is never halved: a step that fails fails the image, whose parts are then
  // stepped alone, each halving as it would.
  WorldSettings once = pc.settings;
  once.max_halvings = 0;
  const PackContext shared_pc{pc.bodies, pc.forces, pc.contacts, once, pc.start};
  StageTimer t(st, &StageTimes::integrate_ms);
  pool.for_each(sc.runs.size(), [&](size_t r, int thread) {
    ThreadShares& ts = sc.threads[size_t(thread)];
    PackScratch& pack = sc.thread_pack[size_t(thread)];
    StepStats& tst = sc.thread_stats[size_t(thread)];
    pack_shares(pc, shared_pc, shapes, sc, sc.runs[r].first, sc.runs[r].second, pack, ts, tst);
    pool.step_on(thread, ts.jobs.data(), ts.jobs.size(), ts.reports.data());
    const auto sound = [](const PackedIsland& p, const spu::IslandReport& r) {
      return r.status == spu::IslandStatus::ok && sound_result(p, r);
    };
    for (size_t i = 0; i < ts.groups.size(); ++i) {
      const size_t j = ts.groups[i].first, g = ts.groups[i].end;
      PackedIsland& p = g - j > 1 ? ts.images[ts.groups[i].shared] : sc.packed[sc.order[j]];
      const spu::IslandReport& rep = ts.reports[i];
      if (g - j == 1) {
        sc.jobs[j] = ts.jobs[i];
        sc.reports[j] = rep;
        if (sound(p, rep)) unpack_island(p, bodies), sc.unpacked[j] = 1;
        continue;
      }
      if (sound(p, rep)) {
        // the shared image's work counted once, on its first part; each part took its substeps
        unpack_island(p, bodies);
        tst.shared_islands += uint32_t(g - j);
        for (size_t m = j; m < g; ++m) {
          sc.reports[m] = m == j ? rep : spu::IslandReport{};
          sc.reports[m].substeps = rep.substeps;
          sc.unpacked[m] = 1;
        }
        continue;
      }
      for (size_t m = j; m < g; ++m) {
        PackedIsland& q = sc.packed[sc.order[m]];
        pack_one(pc, *sc.todo[sc.order[m]], pack, q, /*seal=*/false);
        sc.jobs[m] = job_of(q);
        pool.step_on(thread, &sc.jobs[m], 1, &sc.reports[m]);
        if (sound(q, sc.reports[m])) unpack_island(q, bodies), sc.unpacked[m] = 1;
      }
    }
  });
  for (const StepStats& part : sc.thread_stats) {
    add_wire_tables(part, st);
    st.shared_islands += part.shared_islands;
  }
  match_capacities(sc.thread_pack);
  match_shared_capacities(sc.threads);
}

// One wave: part `wave` of every island (of the split ones only, after the first sweep).
// A failed part of a split island marks the island in part_failed (counted once, after the
// last sweep); a failed whole island is counted and marked in failed now and keeps its state.
void run_wave(const PackContext& pc, const ShapeDictionary& shapes, const DecoupledIslands& d, size_t wave,
              bool split_only, const IslandCompute& compute, std::vector<WorldBody>& bodies,
              IntegrateScratch& sc, std::vector<uint8_t>& failed, StepStats& st) {
  std::vector<PackedIsland>& packed = sc.packed;
  std::vector<size_t>& island_of_packed = sc.island_of_packed;
  const std::vector<size_t>& order = sc.order;  // job j is packed[order[j]]
  std::vector<spu::IslandReport>& reports = sc.reports;
  island_of_packed.clear();
  sc.jobs.clear();
  {
    StageTimer t(st, &StageTimes::pack_ms);
    sc.todo.clear();
    for (size_t k = 0; k < d.used.size(); ++k)
      if (wave < d.count(k) && (!split_only || d.is_split(k))) {
        sc.todo.push_back(&d.part(k, wave));
        island_of_packed.push_back(k);
      }
    while (packed.size() < sc.todo.size()) packed.emplace_back();
    sc.unpacked.assign(sc.todo.size(), 0);
  }
  IslandRunner& runner = compute.runner();
  runner.set_local_store(pc.settings.local_store_bytes);
  if (compute.threads && &runner == static_cast<IslandRunner*>(compute.threads))
    pack_run_unpack(pc, shapes, *compute.threads, bodies, sc, st);
  else
    pack_and_run(pc, shapes, runner, compute.threads, sc, st);
  {
    StageTimer t(st, &StageTimes::integrate_ms);
    // Every result is checked before it is unpacked; an unsound one (damaged on the way, or
    // refused by a node that was sent a sound image) is computed again here.
    for (size_t j = 0; j < order.size(); ++j) {
      PackedIsland& p = packed[order[j]];
      if (sc.unpacked[j] || sound_result(p, reports[j])) continue;
      reports[j] = compute.local().step(job_of(p));
      ++st.recomputed_islands;
    }
  }
  StageTimer t(st, &StageTimes::unpack_ms);
  for (size_t j = 0; j < order.size(); ++j) {
    const spu::IslandReport& r = reports[j];
    add_report(r, st);
    if (r.status != spu::IslandStatus::ok) {
      const size_t k = island_of_packed[order[j]];
      if (d.is_split(k)) sc.part_failed[k] = 1;
      else ++st.failed_islands, failed[k] = 1;
      continue;
    }
    if (!sc.unpacked[j]) unpack_island(packed[order[j]], bodies);
  }
}

// The linear velocities of the bodies of split islands, in island order, into v (replaced).
void split_velocities(const std::vector<IslandContent>& islands, const DecoupledIslands& d,
                      const std::vector<WorldBody>& bodies, std::vector<float>& v) {
  v.clear();
  for (size_t k = 0; k < d.used.size(); ++k)
    if (d.is_split(k))
      for (uint32_t i : islands[k].bodies) v.insert(v.end(), bodies[i].state.velocity, bodies[i].state.velocity + 3);
}

float largest_change(const std::vector<float>& before, const std::vector<float>& after) {
  float change = 0;
  for (size_t k = 0; k < before.size(); ++k) change = std::max(change, std::fabs(after[k] - before[k]));
  return change;
}

}  // namespace

void integrate_islands(const WorldSettings& s, const ShapeDictionary& shapes, const std::vector<IslandContent>& islands,
                       const DecoupledIslands& d, const std::vector<WorldForce>& forces,
                       const std::vector<WorldContact>& contacts, std::vector<WorldBody>& bodies, const IslandCompute& compute,
                       IntegrateScratch& sc, std::vector<uint8_t>& failed, StepStats& st) {
  // Every sweep packs from the start state; it is kept apart only when an island is split.
  std::vector<WorldBody>& start = sc.start;
  if (d.split()) {
    StageTimer t(st, &StageTimes::pack_ms);
    start = bodies;
  }
  const PackContext pc{bodies, forces, contacts, s, d.split() ? start : bodies};
  std::vector<uint8_t>& part_failed = sc.part_failed;  // split islands: a part failed this sweep
  part_failed.assign(islands.size(), 0);
  failed.assign(islands.size(), 0);
  const uint32_t sweeps = d.split() ? std::max(1u, s.decouple_sweeps) : 1;
  for (uint32_t sweep = 0; sweep < sweeps; ++sweep) {
    std::fill(part_failed.begin(), part_failed.end(), uint8_t{0});
    split_velocities(islands, d, bodies, sc.before);
    for (size_t wave = 0; wave < d.waves; ++wave)
      run_wave(pc, shapes, d, wave, sweep > 0, compute, bodies, sc, failed, st);
    if (!d.split()) break;
    st.decouple_sweeps = sweep + 1;
    split_velocities(islands, d, bodies, sc.after);
    st.decouple_change = largest_change(sc.before, sc.after);
    const bool any_failed = std::find(part_failed.begin(), part_failed.end(), uint8_t{1}) != part_failed.end();
    if (sweep > 0 && st.decouple_change <= s.decouple_tolerance && !any_failed) break;
  }
  // A split island with a part that failed in its last sweep goes back to its start state
  // whole, never half-stepped.
  for (size_t k = 0; k < islands.size(); ++k)
    if (part_failed[k]) {
      ++st.failed_islands;
      failed[k] = 1;
      for (uint32_t i : islands[k].bodies) bodies[i] = start[i];
    }
  // A failed island is stopped where it started: given back moving, it failed again from the
  // same state every step (a tangled ragdoll hung in the air at 6.7 m/s for 420 steps).
  for (size_t k = 0; k < islands.size(); ++k)
    if (failed[k])
      for (uint32_t i : islands[k].bodies) {
        BodyState& b = bodies[i].state;
        std::fill(std::begin(b.velocity), std::end(b.velocity), 0.0f);
        std::fill(std::begin(b.angular_velocity), std::end(b.angular_velocity), 0.0f);
      }
}

}  // namespace cellphys::ppe
