#include "server/replies.h"

#include <algorithm>
#include <cstring>

namespace cellphys::server {

namespace {

using namespace protocol;

template <class T>
std::vector<unsigned char> bytes_of(const T& v, size_t extra) {
  std::vector<unsigned char> out(sizeof(T) + extra);
  std::memcpy(out.data(), &v, sizeof(T));
  return out;
}

size_t padded(size_t n) { return (n + 3) / 4 * 4; }

void finish(std::vector<unsigned char>& out, Type type) {
  Header h{static_cast<uint32_t>(out.size()), static_cast<uint16_t>(type), kVersion};
  std::memcpy(out.data(), &h, sizeof h);
}

}  // namespace

Message encode_ack(const Command& c, uint64_t step, uint32_t result) {
  Ack a{};
  a.seq = c.seq;
  a.command_type = c.type;
  a.step = step;
  a.result = result;
  auto out = bytes_of(a, 0);
  finish(out, Type::ack);
  return std::make_shared<const std::vector<unsigned char>>(std::move(out));
}

Message encode_error(uint32_t seq, uint16_t command_type, const CommandError& e) {
  // A text longer than a u16 says is cut (no reason is that long; a field never).
  const size_t nf = std::min<size_t>(e.field.size(), 4096), nr = std::min<size_t>(e.reason.size(), 4096);
  Error m{};
  m.seq = seq;
  m.command_type = command_type;
  m.code = static_cast<uint16_t>(e.code);
  m.field_bytes = static_cast<uint16_t>(nf);
  m.reason_bytes = static_cast<uint16_t>(nr);
  auto out = bytes_of(m, padded(nf + nr));
  std::memcpy(out.data() + sizeof m, e.field.data(), nf);
  std::memcpy(out.data() + sizeof m + nf, e.reason.data(), nr);
  finish(out, Type::error);
  return std::make_shared<const std::vector<unsigned char>>(std::move(out));
}

Message encode_status(WorldState state, uint64_t step, const std::string& text) {
  Status s{};
  s.state = static_cast<uint32_t>(state);
  s.text_bytes = static_cast<uint32_t>(text.size());
  s.step = step;
  auto out = bytes_of(s, padded(text.size()));
  std::memcpy(out.data() + sizeof s, text.data(), text.size());
  finish(out, Type::status);
  return std::make_shared<const std::vector<unsigned char>>(std::move(out));
}

}  // namespace cellphys::server
