#include "runtime/spu/workspace.h"

#include <algorithm>

#include "runtime/spu/assembly.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

constexpr size_t kAlign = 32;
size_t up(size_t n) { return (n + kAlign - 1) / kAlign * kAlign; }

bool implicit(Integrator i) {
  return i == Integrator::implicit_split || i == Integrator::implicit_euler || i == Integrator::rosenbrock;
}

// Floats per body of each state vector an integrator keeps.
struct VectorPlan {
  int forces = 8, ref = 8, x = 0, u0 = 0, saved = 0, k1 = 0, jv = 0, acc = 0, p = 0;
};

VectorPlan plan(Integrator i) {
  VectorPlan v;
  switch (i) {
    case Integrator::implicit_split:
    case Integrator::implicit_euler: v.x = 8, v.u0 = 8; break;
    case Integrator::rosenbrock: v.x = 8, v.u0 = 8, v.saved = 16, v.k1 = 8, v.jv = 8, v.p = 48; break;
    case Integrator::symplectic_euler:
    case Integrator::explicit_euler: v.u0 = 8; break;
    case Integrator::rk4: v.saved = 16, v.k1 = 8, v.acc = 16; break;
  }
  return v;
}

}  // namespace

IslandCounts counts_of(const IslandView& v) {
  IslandCounts c;
  c.num_bodies = v.header->num_bodies;
  c.num_blocks = v.header->num_blocks;
  c.pair_instances = static_cast<uint32_t>(count_pair_instances(v));
  c.image_bytes = v.header->total_bytes;
  c.integrator = static_cast<Integrator>(v.header->integrator);
  c.solver = static_cast<Solver>(v.header->solver);
  c.force_types = 0;
  for (int s = 0; s < v.num_sections(); ++s) c.force_types |= 1u << v.sections[s].force_type;
  return c;
}

Footprint footprint(const IslandCounts& c) {
  Footprint f;
  auto& b = f.bytes;
  const size_t n = c.num_bodies;
  const size_t in = up(c.image_bytes), out = up(result_bytes(c.num_bodies) - n * sizeof(Rigid_Body));
  b[int(Region::input)] = in;
  b[int(Region::output)] = out;
  b[int(Region::double_buffer)] = in + out;  // the next island's input, the last one's output
  b[int(Region::w)] = up(n * sizeof(W_Element));
  const VectorPlan v = plan(c.integrator);
  size_t vec = 0;
  for (int floats : {v.forces, v.ref, v.x, v.u0, v.saved, v.k1, v.jv, v.acc}) vec += floats ? up(n * floats * 4) : 0;
  b[int(Region::vectors)] = vec;
  size_t scratch = up(force_scratch_bytes(c.force_types));
  if (implicit(c.integrator)) {
    b[int(Region::block_index)] = up((n + 1) * 4) + up(size_t{c.num_blocks} * 4);
    b[int(Region::blocks)] = up(size_t{c.num_blocks} * kBlockFloats * 4) + (v.p ? up(n * v.p * 4) : 0);
    const size_t assembly = up(n * kBlockFloats * 4) + scratch;
    const int work = c.solver == Solver::bicgstab ? kBicgstabWorkVectors : kCgsWorkVectors;
    const size_t solve = size_t{static_cast<size_t>(work)} * up(n * kVecFloats * 4);
    const size_t structure = up(size_t{c.pair_instances} * 2 * 8);
    scratch = std::max({assembly, solve, structure});
  }
  b[int(Region::scratch)] = scratch;
  for (size_t x : b) f.total += x;
  return f;
}

bool allocate_workspace(LocalStore& ls, const IslandCounts& c, Workspace& ws) {
  return allocate_workspace(ls, c, footprint(c), ws);
}

bool allocate_workspace(LocalStore& ls, const IslandCounts& c, const Footprint& f, Workspace& ws) {
  const int n = static_cast<int>(c.num_bodies);
  ws = Workspace{};
  ws.n = n;
  const VectorPlan v = plan(c.integrator);
  auto vec = [&](int floats) -> float* { return floats ? ls.allocate_array<float>(size_t(n) * floats, Region::vectors) : nullptr; };
  ws.w = ls.allocate_array<W_Element>(n, Region::w);
  ws.forces = vec(v.forces);
  ws.ref = vec(v.ref);
  ws.x = vec(v.x);
  ws.u0 = vec(v.u0);
  ws.saved = vec(v.saved);
  ws.k1 = vec(v.k1);
  ws.jv = vec(v.jv);
  ws.acc = vec(v.acc);
  if (implicit(c.integrator)) {
    ws.structure.n = n;
    ws.structure.row_start = ls.allocate_array<int32_t>(n + 1, Region::block_index);
    ws.structure.col = ls.allocate_array<int32_t>(std::max<uint32_t>(c.num_blocks, 1), Region::block_index);
    ws.blocks = ls.allocate_array<float>(std::max<size_t>(size_t{c.num_blocks} * kBlockFloats, 8), Region::blocks);
    if (v.p) ws.p = ls.allocate_array<float>(size_t(n) * v.p, Region::blocks);
  }
  auto* scratch = static_cast<unsigned char*>(ls.allocate(f.bytes[int(Region::scratch)], kAlign, Region::scratch));
  if (!scratch || !ws.w || !ws.forces) return false;
  if (implicit(c.integrator)) {
    ws.diag = reinterpret_cast<float*>(scratch);
    ws.force_scratch = ws.diag + size_t(n) * kBlockFloats;
    ws.solver_work = reinterpret_cast<float*>(scratch);
    ws.pair_scratch = reinterpret_cast<int32_t*>(scratch);
    ws.pair_capacity = static_cast<int>(c.pair_instances) * 2;
  } else {
    ws.force_scratch = reinterpret_cast<float*>(scratch);
  }
  return true;
}

}  // namespace cellphys::spu
