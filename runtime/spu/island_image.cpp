#include "runtime/spu/island_image.h"

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "runtime/base/enum_names.h"
#include "runtime/spu/krylov.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {
constexpr const char* kIntegratorNames[kNumIntegrators] = {"implicit_split", "implicit_euler", "rosenbrock",
                                                            "symplectic_euler", "explicit_euler", "rk4"};

bool finite_floats(const float* p, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) return false;
  return true;
}

int32_t read_i32(const unsigned char* p) {
  int32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

// Per force type, a mask per 4-byte word of its instance: the exponent bits for a word that
// holds a parameter, 0 for the rest (body indices, padding). A parameter is not finite when
// its word & mask == mask.
struct ParamMask {
  std::vector<uint32_t> words;  // instance_size / 4
};
const ParamMask& param_mask(int force_type) {
  static const auto table = [] {
    std::array<ParamMask, kNumForceTypes> t{};
    for (int f = 0; f < kNumForceTypes; ++f) {
      t[f].words.assign(kForceTable[f].instance_size / 4, 0u);
      for (uint32_t p = 0; p < kForceTable[f].num_params; ++p)
        for (uint32_t l = 0; l < kForceTable[f].params[p].lanes; ++l)
          t[f].words[kForceTable[f].params[p].offset / 4 + l] = 0x7f800000u;
    }
    return t;
  }();
  return table[force_type];
}

// Whether every parameter of `count` consecutive instances is finite: one pass over their
// words, which the compiler vectorises (the section's instances are 16-byte aligned words).
bool params_finite(const unsigned char* first, uint32_t count, const ParamMask& m) {
  const uint32_t* mask = m.words.data();
  const size_t n = m.words.size();
  uint32_t bad = 0;
  for (uint32_t k = 0; k < count; ++k) {
    const unsigned char* inst = first + size_t{k} * n * 4;
    for (size_t w = 0; w < n; ++w) {
      uint32_t bits;
      std::memcpy(&bits, inst + 4 * w, 4);
      bad |= uint32_t((bits & mask[w]) == 0x7f800000u);
    }
  }
  return bad == 0;
}

// Body pair (a, b) of every pair instance of every binary section, as (row, col) both ways.
template <class F>
void for_each_pair_instance(const IslandView& v, F&& f) {
  for (int s = 0; s < v.num_sections(); ++s) {
    const Island_Section& sec = v.sections[s];
    const ForceInfo& info = kForceTable[sec.force_type];
    if (info.offset_body_b < 0) continue;
    const unsigned char* p = v.base + sec.offset;
    for (uint32_t k = 0; k < sec.count - sec.world_count; ++k) {
      const unsigned char* inst = p + size_t{k} * info.instance_size;
      f(read_i32(inst + info.offset_body_a), read_i32(inst + info.offset_body_b));
    }
  }
}
}  // namespace

const char* integrator_name(Integrator i) { return base::name_of(kIntegratorNames, i); }
bool parse_integrator(const std::string& name, Integrator* out) { return base::value_named(kIntegratorNames, name, out); }
std::string integrator_names() { return base::all_names(kIntegratorNames); }

const char* status_name(IslandStatus s) {
  switch (s) {
    case IslandStatus::ok: return "ok";
    case IslandStatus::failed: return "failed";
    case IslandStatus::does_not_fit: return "does_not_fit";
    case IslandStatus::malformed: return "malformed";
  }
  return "?";
}

namespace {

constexpr uint64_t kPrime = 0x100000001B3ull;  // FNV's 64-bit prime, both checksums' multiplier

// The 64-bit sum folded to 32 bits, mixed so every input bit reaches the low half.
uint32_t fold_to_32(uint64_t x) {
  x ^= x >> 29;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 32;
  return static_cast<uint32_t>(x);
}

}  // namespace

uint32_t checksum(const unsigned char* p, size_t n, uint32_t seed) {
  uint64_t h[4] = {0xCBF29CE484222325ull ^ seed, 0x84222325CBF29CE4ull ^ seed, 0x9E3779B97F4A7C15ull ^ seed,
                   0xC2B2AE3D27D4EB4Full ^ seed};
  size_t i = 0;
  for (; i + 32 <= n; i += 32)
    for (int k = 0; k < 4; ++k) {
      uint64_t w;
      std::memcpy(&w, p + i + 8 * k, 8);
      h[k] = (h[k] ^ w) * kPrime;
    }
  for (; i < n; ++i) h[0] = (h[0] ^ p[i]) * kPrime;
  return fold_to_32(h[0] ^ (h[1] * 3) ^ (h[2] * 5) ^ (h[3] * 7));
}

namespace {

constexpr int kImageLanes = 16;

uint64_t image_lane_start(int k, uint32_t seed) { return (0xCBF29CE484222325ull + 0x9E3779B97F4A7C15ull * uint64_t(k)) ^ seed; }

}  // namespace

// The definition (the portable path computes it as written): lane k takes the words k, k + 16,
// ... of the bytes, the last partial word zero-padded; the lanes are multiplied by 3, 5, 7, ...
// and xored onto n times a constant, so the length counts.
uint32_t image_checksum(const unsigned char* p, size_t n, uint32_t seed) {
#if defined(__AVX512F__) && defined(__AVX512DQ__) && !defined(CELLPHYS_SIMD_SCALAR)
  // The lanes stay in two registers, the tail too (a loop that wrote the tail's lanes to memory
  // a word at a time and read them back whole stalled on the store forwarding every call).
  alignas(64) uint64_t start[kImageLanes];
  for (int k = 0; k < kImageLanes; ++k) start[k] = image_lane_start(k, seed);
  __m512i h0 = _mm512_load_si512(start), h1 = _mm512_load_si512(start + 8);
  const __m512i prime = _mm512_set1_epi64(static_cast<long long>(kPrime));
  size_t i = 0;
  for (; i + 8 * kImageLanes <= n; i += 8 * kImageLanes) {
    h0 = _mm512_mullo_epi64(_mm512_xor_si512(h0, _mm512_loadu_si512(p + i)), prime);
    h1 = _mm512_mullo_epi64(_mm512_xor_si512(h1, _mm512_loadu_si512(p + i + 64)), prime);
  }
  if (i < n) {  // fewer than 128 bytes: whole words by masked loads, the partial one set alone
    const size_t r = n - i, whole = r / 8;
    const unsigned words = static_cast<unsigned>((r + 7) / 8);
    const __mmask16 full = static_cast<__mmask16>((1u << whole) - 1);
    __m512i w0 = _mm512_maskz_loadu_epi64(static_cast<__mmask8>(full), p + i);
    __m512i w1 = _mm512_maskz_loadu_epi64(static_cast<__mmask8>(full >> 8), p + i + 64);
    if (r % 8) {
      uint64_t last = 0;
      std::memcpy(&last, p + i + whole * 8, r % 8);
      const __m512i v = _mm512_set1_epi64(static_cast<long long>(last));
      if (whole < 8) w0 = _mm512_mask_mov_epi64(w0, static_cast<__mmask8>(1u << whole), v);
      else w1 = _mm512_mask_mov_epi64(w1, static_cast<__mmask8>(1u << (whole - 8)), v);
    }
    const __mmask16 used = static_cast<__mmask16>((1u << words) - 1);
    h0 = _mm512_mask_mov_epi64(h0, static_cast<__mmask8>(used), _mm512_mullo_epi64(_mm512_xor_si512(h0, w0), prime));
    h1 = _mm512_mask_mov_epi64(h1, static_cast<__mmask8>(used >> 8), _mm512_mullo_epi64(_mm512_xor_si512(h1, w1), prime));
  }
  const __m512i odd0 = _mm512_set_epi64(17, 15, 13, 11, 9, 7, 5, 3), odd1 = _mm512_set_epi64(33, 31, 29, 27, 25, 23, 21, 19);
  const __m512i m = _mm512_xor_si512(_mm512_mullo_epi64(h0, odd0), _mm512_mullo_epi64(h1, odd1));
  // The zero-masked extracts: GCC 12 warns on the unmasked ones' undefined pass-through.
  const __m256i q = _mm256_xor_si256(_mm512_maskz_extracti64x4_epi64(0xF, m, 0), _mm512_maskz_extracti64x4_epi64(0xF, m, 1));
  const __m128i d = _mm_xor_si128(_mm256_castsi256_si128(q), _mm256_extracti128_si256(q, 1));
  const uint64_t lanes = static_cast<uint64_t>(_mm_cvtsi128_si64(d)) ^ static_cast<uint64_t>(_mm_extract_epi64(d, 1));
  return fold_to_32((uint64_t(n) * 0x9E3779B97F4A7C15ull) ^ lanes);
#else
  uint64_t h[kImageLanes];
  for (int k = 0; k < kImageLanes; ++k) h[k] = image_lane_start(k, seed);
  for (size_t i = 0, k = 0; i < n; i += 8, k = (k + 1) % kImageLanes) {
    uint64_t w = 0;
    std::memcpy(&w, p + i, std::min<size_t>(8, n - i));
    h[k] = (h[k] ^ w) * kPrime;
  }
  uint64_t x = uint64_t(n) * 0x9E3779B97F4A7C15ull;
  for (int k = 0; k < kImageLanes; ++k) x ^= h[k] * (2 * uint64_t(k) + 3);
  return fold_to_32(x);
#endif
}

IslandLayout island_layout(uint32_t num_bodies, uint32_t num_sections) {
  IslandLayout l;
  l.sections = align16(sizeof(Island_Header));
  l.params = align16(l.sections + size_t{num_sections} * sizeof(Island_Section));
  l.bodies = l.params + align16(sizeof(Island_Params));
  l.instances = l.bodies + size_t{num_bodies} * sizeof(Rigid_Body);
  l.total = l.instances;
  return l;
}

size_t result_bytes(uint32_t num_bodies) {
  return align16(sizeof(Island_Result)) + size_t{num_bodies} * (sizeof(Rigid_Body_Step) + sizeof(Rigid_Body));
}

IslandView view_island(unsigned char* image) {
  IslandView v;
  v.base = image;
  v.header = reinterpret_cast<Island_Header*>(image);
  const IslandLayout l = island_layout(v.header->num_bodies, v.header->num_sections);
  v.sections = reinterpret_cast<Island_Section*>(image + l.sections);
  v.params = reinterpret_cast<Island_Params*>(image + l.params);
  v.bodies = reinterpret_cast<Rigid_Body*>(image + l.bodies);
  return v;
}

std::string validate_island(const unsigned char* image, size_t bytes, bool sealed) {
  if (bytes < sizeof(Island_Header)) return "shorter than an island header";
  if (reinterpret_cast<uintptr_t>(image) % 16 != 0) return "image is not 16-byte aligned";
  Island_Header h;
  std::memcpy(&h, image, sizeof h);
  if (h.magic != kIslandMagic) return "bad magic (not a packed island)";
  if (h.version != kIslandVersion) return "format version " + std::to_string(h.version) + ", expected " + std::to_string(kIslandVersion);
  if (h.total_bytes != bytes) return "header says " + std::to_string(h.total_bytes) + " bytes, got " + std::to_string(bytes);
  if (h.num_bodies == 0 || h.num_bodies > (1u << 20)) return "body count " + std::to_string(h.num_bodies) + " out of range";
  if (h.num_sections > static_cast<uint32_t>(kNumForceTypes)) return "more sections than force types";
  if (h.integrator >= static_cast<uint32_t>(kNumIntegrators)) return "unknown integrator " + std::to_string(h.integrator);
  if (h.solver >= static_cast<uint32_t>(kNumSolvers)) return "unknown solver " + std::to_string(h.solver);
  if (!(h.step > 0.0f) || !std::isfinite(h.step)) return "step size must be positive and finite";
  if (!(h.tolerance > 0.0f) || !std::isfinite(h.tolerance)) return "tolerance must be positive and finite";
  if (h.max_halvings > kMaxHalvings) return "max_halvings over " + std::to_string(kMaxHalvings);
  const IslandLayout l = island_layout(h.num_bodies, h.num_sections);
  if (l.instances > bytes) return "too short for its bodies";
  if (sealed && image_checksum(image + sizeof(Island_Header), bytes - sizeof(Island_Header)) != h.checksum)
    return "checksum mismatch";
  IslandView v = view_island(const_cast<unsigned char*>(image));
  size_t expect = l.instances;
  bool seen[kNumForceTypes] = {};
  for (uint32_t s = 0; s < h.num_sections; ++s) {
    const Island_Section& sec = v.sections[s];
    if (sec.force_type >= static_cast<uint32_t>(kNumForceTypes)) return "section " + std::to_string(s) + ": unknown force type";
    if (seen[sec.force_type]) return "section " + std::to_string(s) + ": force type repeated";
    seen[sec.force_type] = true;
    const ForceInfo& info = kForceTable[sec.force_type];
    if (sec.offset != expect) return "section " + std::to_string(s) + ": offset " + std::to_string(sec.offset) + ", expected " + std::to_string(expect);
    if (sec.world_count > sec.count) return "section " + std::to_string(s) + ": world_count > count";
    if (info.kind == ForceKind::global && sec.count != 0) return std::string("section ") + std::to_string(s) + ": global force " + info.name + " has instances";
    if (sec.world_count > 0 && !info.world_anchor) return std::string("section ") + std::to_string(s) + ": " + info.name + " cannot be anchored to the world";
    const size_t n = size_t{sec.count} * info.instance_size;
    if (sec.offset + n > bytes) return "section " + std::to_string(s) + ": instances run past the end";
    const bool finite = params_finite(image + sec.offset, sec.count, param_mask(int(sec.force_type)));
    for (uint32_t k = 0; k < sec.count; ++k) {
      const unsigned char* inst = image + sec.offset + size_t{k} * info.instance_size;
      const int32_t a = read_i32(inst + info.offset_body_a);
      if (a < 0 || static_cast<uint32_t>(a) >= h.num_bodies) return std::string(info.name) + " instance " + std::to_string(k) + ": body a out of range";
      if (info.offset_body_b >= 0) {
        const int32_t b = read_i32(inst + info.offset_body_b);
        const bool world = k >= sec.count - sec.world_count;
        if (world ? b != -1 : (b < 0 || static_cast<uint32_t>(b) >= h.num_bodies || b == a))
          return std::string(info.name) + " instance " + std::to_string(k) + ": body b " + std::to_string(b) + " invalid";
      }
      if (finite) continue;
      for (uint32_t p = 0; p < info.num_params; ++p) {  // which one, for the message
        const ParamInfo& pi = info.params[p];
        float vals[3];
        std::memcpy(vals, inst + pi.offset, 4 * pi.lanes);
        if (!finite_floats(vals, pi.lanes)) return std::string(info.name) + " instance " + std::to_string(k) + ": " + pi.name + " is not finite";
      }
    }
    expect = align16(sec.offset + n);
  }
  if (expect != bytes) return "image has " + std::to_string(bytes - expect) + " trailing bytes";
  for (uint32_t i = 0; i < h.num_bodies; ++i) {
    const Rigid_Body& b = v.bodies[i];
    if (!finite_floats(b.position, 3) || !finite_floats(b.orientation, 4) || !finite_floats(b.velocity, 3) ||
        !finite_floats(b.angular_velocity, 3) || !finite_floats(b.inertia_body, 6) || !finite_floats(b.inverse_inertia_body, 6) ||
        !std::isfinite(b.mass) || !std::isfinite(b.inverse_mass))
      return "body " + std::to_string(i) + " has a non-finite field";
    // inverse_mass 0 (with a zero inverse inertia) is a kinematic body: it keeps its velocity
    if (!(b.mass > 0.0f) || !(b.inverse_mass >= 0.0f)) return "body " + std::to_string(i) + " has no positive mass";
  }
  return "";  // num_blocks is checked where the block structure is built (it needs scratch)
}

uint32_t count_offdiagonal_blocks(const IslandView& v) {
  std::vector<uint64_t> keys;
  return count_offdiagonal_blocks(v, keys);
}

uint32_t count_offdiagonal_blocks(const IslandView& v, std::vector<uint64_t>& keys) {
  keys.clear();
  for_each_pair_instance(v, [&](int32_t a, int32_t b) {
    const uint32_t lo = static_cast<uint32_t>(std::min(a, b)), hi = static_cast<uint32_t>(std::max(a, b));
    const uint64_t key = (uint64_t{lo} << 32) | hi;
    if (keys.empty() || keys.back() != key) keys.push_back(key);  // a pair's points come together
  });
  // a pile's 60,000 contact points sorted one by one were 1.3% of its step; its pairs, packed
  // in pair order, are mostly in order already
  if (!std::is_sorted(keys.begin(), keys.end())) std::sort(keys.begin(), keys.end());
  return 2u * static_cast<uint32_t>(std::unique(keys.begin(), keys.end()) - keys.begin());
}

IslandBuilder::IslandBuilder() : buckets_(kNumForceTypes) { reset(); }

void IslandBuilder::reset() {
  header_ = Island_Header{};
  header_.magic = kIslandMagic;
  header_.version = kIslandVersion;
  header_.integrator = static_cast<uint32_t>(Integrator::implicit_split);
  header_.solver = 0;
  header_.step = 1.0f / 60.0f;
  header_.tolerance = 1e-3f;
  header_.max_halvings = 8;
  params_ = default_island_params();
  bodies_.clear();
  for (Bucket& b : buckets_) {
    b.pair.clear(), b.world.clear();
    b.pair_count = b.world_count = 0;
    b.global = false;
  }
}

int IslandBuilder::add_body(const Rigid_Body_Fields& body) {
  Rigid_Body b;
  pack(body, b);
  bodies_.push_back(b);
  return static_cast<int>(bodies_.size()) - 1;
}

void IslandBuilder::add_global(ForceType type) {
  if (kForceTable[static_cast<int>(type)].kind != ForceKind::global)
    throw std::invalid_argument(std::string(kForceTable[static_cast<int>(type)].name) + " is not a global force");
  buckets_[static_cast<int>(type)].global = true;
}

void IslandBuilder::add_force(ForceType type, const void* instance, size_t instance_bytes) {
  const ForceInfo& info = kForceTable[static_cast<int>(type)];
  if (info.kind == ForceKind::global) throw std::invalid_argument(std::string(info.name) + " is global: use add_global");
  if (instance_bytes != info.instance_size) throw std::invalid_argument(std::string("instance size mismatch for ") + info.name);
  bool world = false;
  if (info.offset_body_b >= 0) world = read_i32(static_cast<const unsigned char*>(instance) + info.offset_body_b) < 0;
  Bucket& b = buckets_[static_cast<int>(type)];
  auto& dst = world ? b.world : b.pair;
  dst.insert(dst.end(), static_cast<const unsigned char*>(instance), static_cast<const unsigned char*>(instance) + instance_bytes);
  (world ? b.world_count : b.pair_count) += 1;
}

void IslandBuilder::reserve_like(const IslandBuilder& other) {
  bodies_.reserve(other.bodies_.capacity());
  keys_.reserve(other.keys_.capacity());
  for (size_t t = 0; t < buckets_.size() && t < other.buckets_.size(); ++t) {
    buckets_[t].pair.reserve(other.buckets_[t].pair.capacity());
    buckets_[t].world.reserve(other.buckets_[t].world.capacity());
  }
}

std::vector<unsigned char> IslandBuilder::finish() const {
  std::vector<unsigned char> img;
  finish(img);
  return img;
}

void IslandBuilder::finish(std::vector<unsigned char>& img, bool seal) const {
  uint32_t num_sections = 0;
  for (const Bucket& b : buckets_) num_sections += b.present();
  const IslandLayout l = island_layout(static_cast<uint32_t>(bodies_.size()), num_sections);
  size_t total = l.instances;
  for (const Bucket& b : buckets_)
    if (b.present()) total = align16(total + b.pair.size() + b.world.size());
  img.assign(total, 0);  // std::vector's storage is 16-byte aligned (operator new)
  Island_Header h = header_;
  h.total_bytes = static_cast<uint32_t>(total);
  h.num_bodies = static_cast<uint32_t>(bodies_.size());
  h.num_sections = num_sections;
  std::memcpy(img.data() + l.params, &params_, sizeof params_);
  if (!bodies_.empty()) std::memcpy(img.data() + l.bodies, bodies_.data(), bodies_.size() * sizeof(Rigid_Body));
  size_t off = l.instances;
  uint32_t s = 0;
  for (int t = 0; t < kNumForceTypes; ++t) {
    const Bucket& b = buckets_[t];
    if (!b.present()) continue;
    Island_Section sec{static_cast<uint32_t>(t), b.pair_count + b.world_count, b.world_count, static_cast<uint32_t>(off)};
    std::memcpy(img.data() + l.sections + s * sizeof sec, &sec, sizeof sec);
    if (!b.pair.empty()) std::memcpy(img.data() + off, b.pair.data(), b.pair.size());
    if (!b.world.empty()) std::memcpy(img.data() + off + b.pair.size(), b.world.data(), b.world.size());
    off = align16(off + b.pair.size() + b.world.size());
    ++s;
  }
  std::memcpy(img.data(), &h, sizeof h);
  IslandView v = view_island(img.data());
  v.header->num_blocks = count_offdiagonal_blocks(v, keys_);
  v.header->checksum = seal ? image_checksum(img.data() + sizeof(Island_Header), total - sizeof(Island_Header)) : 0u;
}

}  // namespace cellphys::spu
