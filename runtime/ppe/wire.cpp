#include "runtime/ppe/wire.h"

#include <algorithm>
#include <cstring>

#include "runtime/ppe/body_records.h"

namespace cellphys::ppe::wire {

using namespace cellphys::gen;

namespace {

constexpr size_t kOutBody = sizeof(Wire_Body_To_Node_Compressed);
constexpr size_t kBackBody = sizeof(Wire_Node_To_Dispatcher);

// Checksum of a message: its header with the checksum field zero, then the rest.
template <class Header>
uint32_t message_checksum(const Header& h, const unsigned char* rest, size_t n) {
  Header z = h;
  z.checksum = 0;
  return spu::checksum(rest, n, spu::checksum(reinterpret_cast<const unsigned char*>(&z), sizeof z));
}

Wire_Body_To_Node_Compressed to_wire(const Rigid_Body& b) {
  Wire_Body_To_Node_Compressed w{};
  std::copy(b.position, b.position + 3, w.position);
  std::copy(b.orientation, b.orientation + 4, w.orientation);
  std::copy(b.velocity, b.velocity + 3, w.velocity);
  std::copy(b.angular_velocity, b.angular_velocity + 3, w.angular_velocity);
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
  std::copy(w.position, w.position + 3, f.position);
  std::copy(w.orientation, w.orientation + 4, f.orientation);
  std::copy(w.velocity, w.velocity + 3, f.velocity);
  std::copy(w.angular_velocity, w.angular_velocity + 3, f.angular_velocity);
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

}  // namespace

size_t job_bytes(size_t image_bytes, size_t n) { return sizeof(JobHeader) + image_bytes - n * sizeof(Rigid_Body) + n * kOutBody; }
size_t result_message_bytes(size_t n) { return sizeof(ResultHeader) + n * kBackBody; }

void encode_job(const unsigned char* image, size_t bytes, uint32_t sequence, uint32_t job, uint64_t local_store_bytes,
                std::vector<unsigned char>& out) {
  Island_Header ih;
  std::memcpy(&ih, image, sizeof ih);
  const spu::IslandLayout l = spu::island_layout(ih.num_bodies, ih.num_sections);
  JobHeader h;
  h.sequence = sequence;
  h.job = job;
  h.image_bytes = static_cast<uint32_t>(bytes);
  h.num_bodies = ih.num_bodies;
  h.prefix_bytes = static_cast<uint32_t>(l.bodies);
  h.local_store_bytes = local_store_bytes;
  out.resize(job_bytes(bytes, ih.num_bodies));
  unsigned char* p = out.data() + sizeof h;
  std::memcpy(p, image, l.bodies);
  p += l.bodies;
  for (uint32_t i = 0; i < ih.num_bodies; ++i, p += kOutBody) {
    Rigid_Body b;
    std::memcpy(&b, image + l.bodies + i * sizeof b, sizeof b);
    const Wire_Body_To_Node_Compressed w = to_wire(b);
    std::memcpy(p, &w, kOutBody);
  }
  std::memcpy(p, image + l.instances, bytes - l.instances);
  h.checksum = message_checksum(h, out.data() + sizeof h, out.size() - sizeof h);
  std::memcpy(out.data(), &h, sizeof h);
}

std::string decode_job(const unsigned char* msg, size_t n, JobHeader& h, std::vector<unsigned char>& image) {
  if (n < sizeof h) return "job shorter than its header";
  std::memcpy(&h, msg, sizeof h);
  if (h.magic != kJobMagic || h.version != kVersion) return "not a job message of this version";
  if (h.num_bodies == 0 || h.num_bodies > (1u << 20)) return "body count out of range";
  const size_t body_bytes = size_t{h.num_bodies} * sizeof(Rigid_Body);
  if (h.image_bytes < h.prefix_bytes + body_bytes || h.prefix_bytes < sizeof(Island_Header)) return "sizes inconsistent";
  if (n != job_bytes(h.image_bytes, h.num_bodies)) return "job of " + std::to_string(n) + " bytes, header implies " +
                                                          std::to_string(job_bytes(h.image_bytes, h.num_bodies));
  if (message_checksum(h, msg + sizeof h, n - sizeof h) != h.checksum) return "job checksum mismatch";
  image.assign(h.image_bytes, 0);
  const unsigned char* p = msg + sizeof h;
  std::memcpy(image.data(), p, h.prefix_bytes);
  p += h.prefix_bytes;
  for (uint32_t i = 0; i < h.num_bodies; ++i, p += kOutBody) {
    Wire_Body_To_Node_Compressed w;
    std::memcpy(&w, p, kOutBody);
    Rigid_Body b;
    if (!from_wire(w, b)) return "body " + std::to_string(i) + ": inertia not invertible";
    std::memcpy(image.data() + h.prefix_bytes + i * sizeof b, &b, sizeof b);
  }
  const size_t inst = h.prefix_bytes + body_bytes;
  std::memcpy(image.data() + inst, p, h.image_bytes - inst);
  // the rebuilt bodies differ from the packer's in fields no kernel reads (damping): re-seal
  Island_Header ih;
  std::memcpy(&ih, image.data(), sizeof ih);
  ih.checksum = spu::checksum(image.data() + sizeof ih, image.size() - sizeof ih);
  std::memcpy(image.data(), &ih, sizeof ih);
  return "";
}

void encode_result(const JobHeader& job, const unsigned char* result, std::vector<unsigned char>& out) {
  ResultHeader h;
  h.sequence = job.sequence;
  h.job = job.job;
  std::memcpy(&h.result, result, sizeof h.result);
  const auto status = static_cast<spu::IslandStatus>(h.result.status);
  const bool bodies = status == spu::IslandStatus::ok || status == spu::IslandStatus::failed;
  h.num_bodies = bodies ? job.num_bodies : 0;
  out.resize(result_message_bytes(h.num_bodies));
  const unsigned char* src = result + spu::result_bytes(job.num_bodies) - size_t{job.num_bodies} * sizeof(Rigid_Body);
  unsigned char* p = out.data() + sizeof h;
  for (uint32_t i = 0; i < h.num_bodies; ++i, p += kBackBody) {
    Rigid_Body b;
    std::memcpy(&b, src + i * sizeof b, sizeof b);
    Wire_Node_To_Dispatcher w{};
    std::copy(b.position, b.position + 3, w.position);
    std::copy(b.orientation, b.orientation + 4, w.orientation);
    std::copy(b.velocity, b.velocity + 3, w.velocity);
    std::copy(b.angular_velocity, b.angular_velocity + 3, w.angular_velocity);
    std::memcpy(p, &w, kBackBody);
  }
  h.checksum = message_checksum(h, out.data() + sizeof h, out.size() - sizeof h);
  std::memcpy(out.data(), &h, sizeof h);
}

bool peek_result(const unsigned char* msg, size_t n, uint32_t& sequence, uint32_t& job) {
  ResultHeader h;
  if (n < sizeof h) return false;
  std::memcpy(&h, msg, sizeof h);
  if (h.magic != kResultMagic) return false;
  sequence = h.sequence;
  job = h.job;
  return true;
}

std::string decode_result(const unsigned char* msg, size_t n, uint32_t sequence, uint32_t job, const unsigned char* image,
                          unsigned char* result, size_t result_capacity, spu::IslandReport& report) {
  ResultHeader h;
  if (n < sizeof h) return "result shorter than its header";
  std::memcpy(&h, msg, sizeof h);
  if (h.magic != kResultMagic || h.version != kVersion) return "not a result message of this version";
  if (n != result_message_bytes(h.num_bodies)) return "result of " + std::to_string(n) + " bytes for " + std::to_string(h.num_bodies) + " bodies";
  if (message_checksum(h, msg + sizeof h, n - sizeof h) != h.checksum) return "result checksum mismatch";
  if (h.sequence != sequence || h.job != job) return "result for another island";
  Island_Header ih;
  std::memcpy(&ih, image, sizeof ih);
  const uint32_t nb = ih.num_bodies;
  const Island_Result& r = h.result;
  if (r.magic != spu::kResultMagic || r.num_bodies != nb || r.status > 3) return "kernel result header does not match the island";
  const auto status = static_cast<spu::IslandStatus>(r.status);
  const bool bodies = status == spu::IslandStatus::ok || status == spu::IslandStatus::failed;
  if (h.num_bodies != (bodies ? nb : 0)) return "result carries the wrong number of bodies";
  if (result_capacity < spu::result_bytes(nb)) return "result buffer too small";
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
  const spu::IslandLayout l = spu::island_layout(nb, ih.num_sections);
  const size_t head = spu::align16(sizeof(Island_Result));
  auto* steps = result + head;
  unsigned char* out_bodies = steps + size_t{nb} * sizeof(Rigid_Body_Step);
  const unsigned char* p = msg + sizeof h;
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
    std::copy(w.position, w.position + 3, b.position);
    std::copy(w.orientation, w.orientation + 4, b.orientation);
    std::copy(w.velocity, w.velocity + 3, b.velocity);
    std::copy(w.angular_velocity, w.angular_velocity + 3, b.angular_velocity);
    std::memcpy(steps + i * sizeof s, &s, sizeof s);
    std::memcpy(out_bodies + i * sizeof b, &b, sizeof b);
  }
  Island_Result rr = r;
  const size_t steps_bytes = size_t{nb} * sizeof(Rigid_Body_Step);
  rr.checksum = spu::checksum(out_bodies, size_t{nb} * sizeof(Rigid_Body), spu::checksum(steps, steps_bytes));
  std::memset(result, 0, head);
  std::memcpy(result, &rr, sizeof rr);
  return "";
}

void NodeKernel::serve(const unsigned char* msg, size_t n, std::vector<unsigned char>& out) {
  JobHeader h;
  const std::string why = decode_job(msg, n, h, image_);
  if (!why.empty()) {
    // answer what can be answered: a malformed result (if the header named an island)
    Island_Result r{};
    r.magic = spu::kResultMagic;
    r.status = static_cast<uint32_t>(spu::IslandStatus::malformed);
    r.num_bodies = h.num_bodies;
    r.total_bytes = sizeof r;
    result_.assign(spu::result_bytes(0), 0);
    std::memcpy(result_.data(), &r, sizeof r);
    JobHeader z = h;
    z.num_bodies = 0;
    encode_result(z, result_.data(), out);
    return;
  }
  if (!worker_ || worker_->local_store().capacity() != h.local_store_bytes)
    worker_ = std::make_unique<spu::ComputeWorker>(h.local_store_bytes);
  result_.assign(spu::result_bytes(h.num_bodies), 0);
  worker_->step(image_.data(), image_.size(), result_.data(), result_.size());
  encode_result(h, result_.data(), out);
  ++islands_;
}

}  // namespace cellphys::ppe::wire
