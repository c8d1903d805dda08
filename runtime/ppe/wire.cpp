#include "runtime/ppe/wire.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/body_state.h"
#include "runtime/spu/local_store.h"

namespace cellphys::ppe::wire {

using namespace cellphys::gen;

namespace {

constexpr size_t kOutBody = sizeof(Wire_Body_To_Node_Compressed);
constexpr size_t kBackBody = sizeof(Wire_Node_To_Dispatcher);

// Checksum of a record: its header with the checksum field zero, then the bytes after it.
template <class Header>
uint32_t record_checksum(const Header& h, const unsigned char* rest, size_t n) {
  Header z = h;
  z.checksum = 0;
  return spu::checksum(rest, n, spu::checksum(reinterpret_cast<const unsigned char*>(&z), sizeof z));
}

// Appends n zero bytes and returns where they start.
unsigned char* grow(std::vector<unsigned char>& out, size_t n) {
  const size_t at = out.size();
  out.resize(at + n);
  return out.data() + at;
}

void bump_count(std::vector<unsigned char>& out) {
  BatchHeader h;
  std::memcpy(&h, out.data(), sizeof h);
  ++h.count;
  std::memcpy(out.data(), &h, sizeof h);
}

constexpr uint32_t kMaxBodies = 1u << 20;

Wire_Body_To_Node_Compressed to_wire(const Rigid_Body& b) {
  Wire_Body_To_Node_Compressed w{};
  copy_state(b, w);
  w.mass = b.mass;
  std::copy(b.inertia_body, b.inertia_body + 6, w.inertia);
  w.friction = b.friction;
  w.collision_flags = b.flags;
  w.body_flags = b.inverse_mass == 0.0f ? kGhostFlag : 0u;  // a kinematic ghost of another part
  w.scale = b.scale;
  w.shape_index = b.shape_index;
  return w;
}

// The packer's Rigid_Body for a wire record: inverse mass 1/m and the inverse of the inertia
// (the same functions on the same bits), zero for a ghost. Damping travels as force records.
bool from_wire(const Wire_Body_To_Node_Compressed& w, Rigid_Body& out) {
  Rigid_Body_Fields f;
  copy_state(w, f);
  std::copy(w.inertia, w.inertia + 6, f.inertia_body);
  f.mass = w.mass;
  f.friction = w.friction;
  f.flags = w.collision_flags;
  f.shape_index = w.shape_index;
  f.scale = w.scale;
  if (w.body_flags & kGhostFlag) {
    f.inverse_mass = 0.0f;
    std::fill(f.inverse_inertia_body, f.inverse_inertia_body + 6, 0.0f);
  } else {
    f.inverse_mass = 1.0f / w.mass;
    if (!invert_inertia(w.inertia, f.inverse_inertia_body)) return false;
  }
  pack(f, out);
  return true;
}

// What a node's body record must hold for the world to take it: a finite state with a unit
// quaternion (the kernel normalises it every step). The checksum only proves the bytes came
// as sent; a node that computed garbage, or was built wrong, is caught here.
std::string returned_body_problem(const Wire_Node_To_Dispatcher& w) {
  const std::pair<const char*, std::pair<const float*, int>> fields[] = {
      {"position", {w.position, 3}}, {"orientation", {w.orientation, 4}}, {"velocity", {w.velocity, 3}},
      {"angular velocity", {w.angular_velocity, 3}}};
  for (const auto& [name, f] : fields)
    for (int k = 0; k < f.second; ++k)
      if (!std::isfinite(f.first[k])) return std::string(name) + "[" + std::to_string(k) + "] is not finite";
  double n = 0;
  for (int k = 0; k < 4; ++k) n += double(w.orientation[k]) * w.orientation[k];
  if (!(std::fabs(std::sqrt(n) - 1.0) <= 1e-4)) return "orientation is not a unit quaternion";
  return "";
}

}  // namespace

size_t job_record_bytes(size_t image_bytes, size_t n) {
  return sizeof(JobRecord) + image_bytes - n * sizeof(Rigid_Body) + n * kOutBody;
}
size_t result_record_bytes(size_t n) { return sizeof(ResultRecord) + n * kBackBody; }

void begin_batch(uint32_t magic, uint32_t sequence, uint64_t local_store_bytes, std::vector<unsigned char>& out) {
  BatchHeader h;
  h.magic = magic;
  h.sequence = sequence;
  h.local_store_bytes = local_store_bytes;
  out.resize(sizeof h);
  std::memcpy(out.data(), &h, sizeof h);
}

void seal_batch(std::vector<unsigned char>& out) {
  BatchHeader h;
  std::memcpy(&h, out.data(), sizeof h);
  h.checksum = record_checksum(h, nullptr, 0);
  std::memcpy(out.data(), &h, sizeof h);
}

std::string decode_batch_header(const unsigned char* msg, size_t n, uint32_t magic, BatchHeader& h) {
  if (n < sizeof h) return "message of " + std::to_string(n) + " bytes, shorter than a batch header";
  std::memcpy(&h, msg, sizeof h);
  if (h.magic != magic || h.version != kVersion) return "not a batch of this kind and version";
  if (record_checksum(h, nullptr, 0) != h.checksum) return "batch header checksum mismatch";
  return "";
}

void append_job(const unsigned char* image, size_t bytes, uint32_t job, std::vector<unsigned char>& out) {
  Island_Header ih;
  std::memcpy(&ih, image, sizeof ih);
  const spu::IslandLayout l = spu::island_layout(ih.num_bodies, ih.num_sections);
  JobRecord r;
  r.job = job;
  r.image_bytes = static_cast<uint32_t>(bytes);
  r.num_bodies = ih.num_bodies;
  const size_t at = out.size();
  grow(out, job_record_bytes(bytes, ih.num_bodies));
  unsigned char* const rec = out.data() + at;
  unsigned char* p = rec + sizeof r;
  std::memcpy(p, image, l.bodies);
  p += l.bodies;
  for (uint32_t i = 0; i < ih.num_bodies; ++i, p += kOutBody) {
    Rigid_Body b;
    std::memcpy(&b, image + l.bodies + i * sizeof b, sizeof b);
    const Wire_Body_To_Node_Compressed w = to_wire(b);
    std::memcpy(p, &w, kOutBody);
  }
  std::memcpy(p, image + l.instances, bytes - l.instances);
  r.checksum = record_checksum(r, rec + sizeof r, out.size() - at - sizeof r);
  std::memcpy(rec, &r, sizeof r);
  bump_count(out);
}

std::string next_job(const unsigned char* msg, size_t n, size_t& offset, JobRecord& r, std::vector<unsigned char>& image,
                     bool& framed) {
  framed = false;
  if (offset + sizeof r > n) return "job record runs past the message";
  std::memcpy(&r, msg + offset, sizeof r);
  if (r.num_bodies == 0 || r.num_bodies > kMaxBodies) return "body count out of range";
  const size_t body_bytes = size_t{r.num_bodies} * sizeof(Rigid_Body);
  if (r.image_bytes < sizeof(Island_Header) + body_bytes) return "sizes inconsistent";
  const size_t len = job_record_bytes(r.image_bytes, r.num_bodies);
  if (len > n - offset) return "job record of " + std::to_string(len) + " bytes runs past the message";
  const unsigned char* rec = msg + offset;
  offset += len;
  framed = true;
  if (record_checksum(r, rec + sizeof r, len - sizeof r) != r.checksum) return "job checksum mismatch";
  Island_Header ih;
  std::memcpy(&ih, rec + sizeof r, sizeof ih);
  if (ih.num_bodies != r.num_bodies) return "island header does not match the record";
  const spu::IslandLayout l = spu::island_layout(ih.num_bodies, ih.num_sections);
  if (l.bodies < sizeof ih || l.bodies + body_bytes > r.image_bytes || l.instances != l.bodies + body_bytes)
    return "island layout does not fit the record";
  const size_t prefix = l.bodies;
  image.assign(r.image_bytes, 0);
  const unsigned char* p = rec + sizeof r;
  std::memcpy(image.data(), p, prefix);
  p += prefix;
  for (uint32_t i = 0; i < r.num_bodies; ++i, p += kOutBody) {
    Wire_Body_To_Node_Compressed w;
    std::memcpy(&w, p, kOutBody);
    Rigid_Body b;
    if (!from_wire(w, b)) return "body " + std::to_string(i) + ": inertia not invertible";
    std::memcpy(image.data() + prefix + i * sizeof b, &b, sizeof b);
  }
  const size_t inst = prefix + body_bytes;
  std::memcpy(image.data() + inst, p, r.image_bytes - inst);
  // the rebuilt bodies differ from the packer's in fields no kernel reads (damping): re-seal
  ih.checksum = spu::image_checksum(image.data() + sizeof ih, image.size() - sizeof ih);
  std::memcpy(image.data(), &ih, sizeof ih);
  return "";
}

void append_result(uint32_t job, uint32_t num_bodies, const unsigned char* result, std::vector<unsigned char>& out) {
  Island_Result ir;
  std::memcpy(&ir, result, sizeof ir);
  ResultRecord r;
  r.job = job;
  r.status = ir.status;
  r.island_id = ir.island_id;
  r.solver_iterations = ir.solver_iterations;
  r.solves = ir.solves;
  r.halvings = ir.halvings;
  r.substeps = ir.substeps;
  r.solver_code = ir.solver_code;
  r.local_store_bytes = ir.local_store_bytes;
  r.total_bytes = ir.total_bytes;
  const auto status = static_cast<spu::IslandStatus>(ir.status);
  const bool bodies = status == spu::IslandStatus::ok || status == spu::IslandStatus::failed;
  r.num_bodies = bodies ? num_bodies : 0;
  const size_t at = out.size();
  grow(out, result_record_bytes(r.num_bodies));
  unsigned char* const rec = out.data() + at;
  const unsigned char* src = result + spu::result_bytes(num_bodies) - size_t{num_bodies} * sizeof(Rigid_Body);
  unsigned char* p = rec + sizeof r;
  for (uint32_t i = 0; i < r.num_bodies; ++i, p += kBackBody) {
    Rigid_Body b;
    std::memcpy(&b, src + i * sizeof b, sizeof b);
    Wire_Node_To_Dispatcher w{};
    copy_state(b, w);
    std::memcpy(p, &w, kBackBody);
  }
  r.checksum = record_checksum(r, rec + sizeof r, out.size() - at - sizeof r);
  std::memcpy(rec, &r, sizeof r);
  bump_count(out);
}

bool next_result(const unsigned char* msg, size_t n, size_t& offset, ResultRecord& rec, const unsigned char*& bodies) {
  if (offset > n || n - offset < sizeof rec) return false;
  std::memcpy(&rec, msg + offset, sizeof rec);
  if (rec.num_bodies > kMaxBodies) return false;
  const size_t len = result_record_bytes(rec.num_bodies);
  if (len > n - offset) return false;
  bodies = msg + offset + sizeof rec;
  offset += len;
  return true;
}

std::string decode_result(const ResultRecord& h, const unsigned char* msg_bodies, const unsigned char* image,
                          unsigned char* result, size_t result_capacity, spu::IslandReport& report) {
  if (record_checksum(h, msg_bodies, size_t{h.num_bodies} * kBackBody) != h.checksum) return "result checksum mismatch";
  Island_Header ih;
  std::memcpy(&ih, image, sizeof ih);
  const uint32_t nb = ih.num_bodies;
  if (h.status > 3) return "kernel status out of range";
  const auto status = static_cast<spu::IslandStatus>(h.status);
  const bool bodies = status == spu::IslandStatus::ok || status == spu::IslandStatus::failed;
  if (h.num_bodies != (bodies ? nb : 0)) return "result carries the wrong number of bodies";
  if (result_capacity < spu::result_bytes(nb)) return "result buffer too small";
  Island_Result r{};
  r.magic = spu::kResultMagic;
  r.status = h.status;
  r.island_id = h.island_id;
  r.num_bodies = nb;
  r.solver_iterations = h.solver_iterations;
  r.solves = h.solves;
  r.halvings = h.halvings;
  r.substeps = h.substeps;
  r.solver_code = h.solver_code;
  r.local_store_bytes = h.local_store_bytes;
  r.total_bytes = h.total_bytes;
  report = spu::IslandReport{};
  report.status = status;
  report.solver_iterations = r.solver_iterations;
  report.solves = r.solves;
  report.halvings = r.halvings;
  report.substeps = r.substeps;
  report.solver_code = r.solver_code;
  report.footprint.total = r.local_store_bytes;
  report.local_store_peak = r.local_store_bytes;
  if (!bodies) {  // a refusal: the header alone, as the kernel writes it
    std::memcpy(result, &r, sizeof r);
    report.error = std::string("refused by the node: ") + spu::status_name(status);
    return "";
  }
  // The kernel's result: header, each body's change of velocity, the advanced bodies (the
  // image's bodies with the returned state; the kernel changes nothing else).
  for (uint32_t i = 0; i < nb; ++i) {  // all checked before the result is written
    Wire_Node_To_Dispatcher w;
    std::memcpy(&w, msg_bodies + i * kBackBody, kBackBody);
    const std::string why = returned_body_problem(w);
    if (!why.empty()) return "body " + std::to_string(i) + ": " + why;
  }
  const spu::IslandLayout l = spu::island_layout(nb, ih.num_sections);
  const size_t head = spu::align16(sizeof(Island_Result));
  auto* steps = result + head;
  unsigned char* out_bodies = steps + size_t{nb} * sizeof(Rigid_Body_Step);
  const unsigned char* p = msg_bodies;
  for (uint32_t i = 0; i < nb; ++i, p += kBackBody) {
    Wire_Node_To_Dispatcher w;
    std::memcpy(&w, p, kBackBody);
    Rigid_Body b;
    std::memcpy(&b, image + l.bodies + i * sizeof b, sizeof b);
    Rigid_Body_Step s{};
    for (int k = 0; k < 3; ++k) {
      s.delta_velocity[k] = status == spu::IslandStatus::ok ? w.velocity[k] - b.velocity[k] : 0.0f;
      s.delta_angular_velocity[k] = status == spu::IslandStatus::ok ? w.angular_velocity[k] - b.angular_velocity[k] : 0.0f;
    }
    copy_state(w, b);
    std::memcpy(steps + i * sizeof s, &s, sizeof s);
    std::memcpy(out_bodies + i * sizeof b, &b, sizeof b);
  }
  const size_t steps_bytes = size_t{nb} * sizeof(Rigid_Body_Step);
  r.checksum = spu::image_checksum(out_bodies, size_t{nb} * sizeof(Rigid_Body), spu::image_checksum(steps, steps_bytes));
  std::memset(result, 0, head);
  std::memcpy(result, &r, sizeof r);
  return "";
}

std::string read_results(const unsigned char* msg, size_t n, uint32_t sequence, const std::vector<spu::IslandJob>& jobs,
                         std::vector<spu::IslandReport>& reports, const std::function<bool(uint32_t)>& expects,
                         const std::function<void(uint32_t, const std::string&)>& answered) {
  BatchHeader h;
  const std::string bad_header = decode_batch_header(msg, n, kResultsMagic, h);
  if (!bad_header.empty()) return bad_header;
  if (h.sequence != sequence) return "answer to another wave";
  size_t offset = sizeof h;
  for (uint32_t r = 0; r < h.count; ++r) {
    ResultRecord rec;
    const unsigned char* bodies = nullptr;
    if (!next_result(msg, n, offset, rec, bodies)) break;  // the rest is lost
    // a record whose job field was damaged names no island of this batch: skipped (its
    // island is among those without a result)
    if (rec.job >= jobs.size() || !expects(rec.job)) continue;
    const spu::IslandJob& j = jobs[rec.job];
    answered(rec.job, decode_result(rec, bodies, j.image, j.result, j.result_capacity, reports[rec.job]));
  }
  return "no sound result in the node's answer";
}

void NodeKernel::serve(const unsigned char* msg, size_t n, std::vector<unsigned char>& out) {
  offsets_.clear();
  BatchHeader bh;
  std::string bad_header = decode_batch_header(msg, n, kJobsMagic, bh);
  // a local store no kernel can have is a damaged header, not an exception in the node
  if (bad_header.empty() &&
      (bh.local_store_bytes < spu::LocalStore::kMinCapacity || bh.local_store_bytes > spu::LocalStore::kMaxCapacity))
    bad_header = "local store of " + std::to_string(bh.local_store_bytes) + " bytes out of range";
  begin_batch(kResultsMagic, bad_header.empty() ? bh.sequence : 0, 0, out);
  if (bad_header.empty()) {
    size_t offset = sizeof bh;
    for (uint32_t k = 0; k < bh.count; ++k) {
      JobRecord rec;
      bool framed = false;
      const std::string why = next_job(msg, n, offset, rec, image_, framed);
      if (!framed) break;  // the rest cannot be found: the dispatcher recomputes them
      offsets_.push_back(out.size());
      if (!why.empty()) {
        // a malformed result for the island the record names
        Island_Result r{};
        r.magic = spu::kResultMagic;
        r.status = static_cast<uint32_t>(spu::IslandStatus::malformed);
        r.total_bytes = sizeof r;
        append_result(rec.job, 0, reinterpret_cast<const unsigned char*>(&r), out);
        continue;
      }
      if (!worker_ || worker_->local_store().capacity() != bh.local_store_bytes)
        worker_ = std::make_unique<spu::ComputeWorker>(bh.local_store_bytes);
      result_.assign(spu::result_bytes(rec.num_bodies), 0);
      worker_->step(image_.data(), image_.size(), result_.data(), result_.size());
      append_result(rec.job, rec.num_bodies, result_.data(), out);
      ++islands_;
    }
  }
  seal_batch(out);
}

}  // namespace cellphys::ppe::wire
