#include "server/stages_encoder.h"

#include <cstring>
#include <iterator>
#include <string>

#include "server/protocol.h"

namespace cellphys::server {

std::vector<unsigned char> encode_stages(uint64_t step, uint32_t epoch, const ppe::StageTimes& times) {
  using namespace protocol;
  std::string names;
  for (const ppe::StageTimeField& f : ppe::kStageTimeFields) names.append(f.name).push_back('\0');
  names.resize((names.size() + 3) / 4 * 4, '\0');
  constexpr size_t n = std::size(ppe::kStageTimeFields);
  Stages m{};
  m.header = Header{static_cast<uint32_t>(sizeof m + 4 * n + names.size()), static_cast<uint16_t>(Type::stages),
                    kVersion};
  m.step = step;
  m.epoch = epoch;
  m.num_stages = static_cast<uint32_t>(n);
  m.names_bytes = static_cast<uint32_t>(names.size());
  std::vector<unsigned char> out(m.header.length);
  std::memcpy(out.data(), &m, sizeof m);
  for (size_t k = 0; k < n; ++k) {
    const float ms = static_cast<float>(times.*(ppe::kStageTimeFields[k].ms));
    std::memcpy(out.data() + sizeof m + 4 * k, &ms, 4);
  }
  std::memcpy(out.data() + sizeof m + 4 * n, names.data(), names.size());
  return out;
}

}  // namespace cellphys::server
