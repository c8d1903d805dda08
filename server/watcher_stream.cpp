#include "server/watcher_stream.h"

#include "server/state_encoder.h"

namespace cellphys::server {

std::shared_ptr<const std::vector<unsigned char>> WatcherStream::next(const Frame& f) {
  std::shared_ptr<const std::vector<unsigned char>> out;
  if (!joined_ || f.epoch != epoch_) {
    auto join = std::make_shared<std::vector<unsigned char>>();
    encode_join(f, Interest{}, false, known_, *join);
    joined_ = true;
    epoch_ = f.epoch;
    out = join;
  } else {
    out = shared_tick(f, false, last_seq_, known_);
  }
  last_seq_ = f.seq;
  return out;
}

}  // namespace cellphys::server
