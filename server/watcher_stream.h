// The state messages of a client that watches every body at full precision and is never behind:
// a join for the first frame and for the first of each epoch (after a reset), then a tick per
// frame. These are the bytes every such client of a room gets (the shared encoding,
// state_encoder.h); a recording keeps them, and `cellphys replay` makes them again to compare.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "server/frame.h"

namespace cellphys::server {

class WatcherStream {
 public:
  /// The message for `f`, which follows the frames given before.
  std::shared_ptr<const std::vector<unsigned char>> next(const Frame& f);

 private:
  bool joined_ = false;
  uint32_t epoch_ = 0;
  uint64_t last_seq_ = 0;
  std::vector<uint32_t> known_;
};

}  // namespace cellphys::server
