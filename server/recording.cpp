#include "server/recording.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>

#include "runtime/spu/island_image.h"
#include "server/protocol.h"

namespace cellphys::server {

namespace {

constexpr char kMagic[8] = {'C', 'E', 'L', 'L', 'R', 'E', 'C', '1'};

struct RecordHeader {
  uint32_t type, bytes, checksum, reserved;
};
static_assert(sizeof(RecordHeader) == 16);

uint32_t record_checksum(RecordHeader h, const unsigned char* payload, size_t n) {
  h.checksum = 0;
  const uint32_t c = spu::checksum(reinterpret_cast<const unsigned char*>(&h), sizeof h);
  return n ? spu::checksum(payload, n, c) : c;
}

template <class T>
T get(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

}  // namespace

RecordingWriter::RecordingWriter(const std::string& path, bool frames, bool debug)
    : path_(path), frames_(frames), debug_(frames && debug) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) throw RecordingError(path + ": cannot create the recording: " + std::strerror(errno));
  uint32_t head[2] = {kRecordingVersion, (frames_ ? kRecordingFrames : 0u) | (debug_ ? kRecordingDebug : 0u)};
  if (std::fwrite(kMagic, 1, 8, f_) != 8 || std::fwrite(head, 4, 2, f_) != 2) failed_ = true;
}

RecordingWriter::~RecordingWriter() {
  if (f_) std::fclose(f_);
}

void RecordingWriter::record(RecordType type, const unsigned char* a, size_t na, const unsigned char* b, size_t nb) {
  if (!f_) return;
  std::vector<unsigned char> payload(a, a + na);  // one run of bytes, as the reader checks it
  if (nb) payload.insert(payload.end(), b, b + nb);
  RecordHeader h{static_cast<uint32_t>(type), static_cast<uint32_t>(payload.size()), 0, 0};
  h.checksum = record_checksum(h, payload.data(), payload.size());
  if (std::fwrite(&h, sizeof h, 1, f_) != 1 || (!payload.empty() && std::fwrite(payload.data(), 1, payload.size(), f_) != payload.size()))
    failed_ = true;
}

void RecordingWriter::world(const std::string& name, const std::vector<unsigned char>& snapshot) {
  std::vector<unsigned char> head(4 + name.size());
  const uint32_t n = static_cast<uint32_t>(name.size());
  std::memcpy(head.data(), &n, 4);
  std::memcpy(head.data() + 4, name.data(), name.size());
  record(RecordType::world, head.data(), head.size(), snapshot.data(), snapshot.size());
}

void RecordingWriter::command(uint64_t step, const Command& c) {
  record(RecordType::command, reinterpret_cast<const unsigned char*>(&step), 8, c.bytes, c.size);
}

void RecordingWriter::hash(uint64_t step, uint64_t state_hash) {
  const uint64_t v[2] = {step, state_hash};
  record(RecordType::hash, reinterpret_cast<const unsigned char*>(v), sizeof v);
}

void RecordingWriter::frame(uint64_t step, const std::vector<unsigned char>& message) {
  record(RecordType::frame, reinterpret_cast<const unsigned char*>(&step), 8, message.data(), message.size());
}

void RecordingWriter::flush() {
  if (f_ && std::fflush(f_) != 0) failed_ = true;
}

void RecordingWriter::close(uint64_t step, uint64_t state_hash) {
  if (!f_) return;
  const uint64_t v[2] = {step, state_hash};
  record(RecordType::end, reinterpret_cast<const unsigned char*>(v), sizeof v);
  const bool bad = std::fclose(f_) != 0 || failed_;
  f_ = nullptr;
  if (bad) throw RecordingError(path_ + ": writing the recording failed (disk full?); it ends before the failure");
}

Recording read_recording(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RecordingError(path + ": cannot open the recording: " + std::strerror(errno));
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 16 || std::memcmp(bytes.data(), kMagic, 8) != 0)
    throw RecordingError(path + ": not a cellphys recording (no CELLREC1 header)");
  const uint32_t version = get<uint32_t>(bytes.data() + 8);
  if (version < 1 || version > kRecordingVersion)
    throw RecordingError(path + ": recording version " + std::to_string(version) +
                         " is not one this cellphys reads (1 to " + std::to_string(kRecordingVersion) + ")" +
                         (version > kRecordingVersion ? ": written by a newer cellphys?" : ""));
  Recording r;
  r.version = version;
  r.frames = version >= 2 && (get<uint32_t>(bytes.data() + 12) & kRecordingFrames) != 0;
  r.debug = r.frames && (get<uint32_t>(bytes.data() + 12) & kRecordingDebug) != 0;
  size_t at = 16, count = 0;
  bool have_world = false;
  while (at < bytes.size()) {
    const std::string where = "record " + std::to_string(count) + " (byte " + std::to_string(at) + ")";
    if (bytes.size() - at < sizeof(RecordHeader)) {
      r.damage = where + " is cut short in its header";
      break;
    }
    const RecordHeader h = get<RecordHeader>(bytes.data() + at);
    if (h.bytes > bytes.size() - at - sizeof h) {
      r.damage = where + " is cut short: it says " + std::to_string(h.bytes) + " bytes";
      break;
    }
    const unsigned char* p = bytes.data() + at + sizeof h;
    if (record_checksum(h, p, h.bytes) != h.checksum) {
      r.damage = where + " is damaged (checksum)";
      break;
    }
    const auto type = static_cast<RecordType>(h.type);
    if (!have_world) {
      if (type != RecordType::world || h.bytes < 4 || get<uint32_t>(p) > h.bytes - 4)
        throw RecordingError(path + ": " + where + " is not the world record a recording opens with");
      const uint32_t n = get<uint32_t>(p);
      r.world.assign(reinterpret_cast<const char*>(p + 4), n);
      r.snapshot.assign(p + 4 + n, p + h.bytes);
      have_world = true;
    } else {
      RecordEntry e;
      e.type = type;
      if (h.bytes < 8) {
        r.damage = where + " is too short for its type";
        break;
      }
      e.step = get<uint64_t>(p);
      if (type == RecordType::hash || type == RecordType::end) {
        if (h.bytes != 16) {
          r.damage = where + " is not 16 bytes";
          break;
        }
        e.hash = get<uint64_t>(p + 8);
      } else if (type == RecordType::frame && version >= 2) {
        protocol::Header mh{};
        if (h.bytes >= 8 + sizeof mh) std::memcpy(&mh, p + 8, sizeof mh);
        const auto mt = static_cast<protocol::Type>(mh.type);
        const bool state = mt == protocol::Type::join || mt == protocol::Type::tick || mt == protocol::Type::stages ||
                           (mt == protocol::Type::debug && r.debug);
        if (h.bytes < 8 + sizeof mh || mh.length != h.bytes - 8 || !state) {
          r.damage = where + " is not a frame: its message's header is not a join, tick, stages" +
                     std::string(r.debug ? " or debug" : "") + " of its length";
          break;
        }
        e.message.assign(p + 8, p + h.bytes);
      } else if (type == RecordType::command) {
        CommandError err;
        if (!decode_client_message(p + 8, h.bytes - 8, e.command, err)) {
          r.damage = where + ": " + err.field + ": " + err.reason;
          break;
        }
      } else {
        r.damage = where + " has an unknown type " + std::to_string(h.type);
        break;
      }
      r.entries.push_back(e);
      if (type == RecordType::end) {
        r.ended = true;
        break;
      }
    }
    at += sizeof h + h.bytes;
    ++count;
  }
  if (!have_world) throw RecordingError(path + ": the recording has no sound world record" +
                                        (r.damage.empty() ? "" : " (" + r.damage + ")"));
  return r;
}

}  // namespace cellphys::server
