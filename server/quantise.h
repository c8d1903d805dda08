// The quantised body state of protocol::BodyMovedQ: 16-bit steps of a per-tick QuantFrame for
// position and velocities, and the "smallest three" orientation in 32 bits. Encoder and decoder
// side by side, so tests and benchmarks measure the error of exactly what clients receive.
#pragma once
#include <cstdint>

#include "runtime/ppe/body_state.h"
#include "server/protocol.h"

namespace cellphys::server {

/// The frame that covers every state of `states` (n of them): origin at the middle of the
/// positions' box, steps so the largest component maps to 32767.
protocol::QuantFrame quant_frame(const ppe::BodyState* const* states, size_t n);

void quantise(const ppe::BodyState& s, const protocol::QuantFrame& f, protocol::BodyMovedQ& out);
void dequantise(const protocol::BodyMovedQ& q, const protocol::QuantFrame& f, ppe::BodyState& out);

/// A unit quaternion (w x y z) as its three smallest components at 10 bits and the index of the
/// largest (made positive: q and -q are one rotation), and back (renormalised).
uint32_t pack_orientation(const float q[4]);
void unpack_orientation(uint32_t bits, float q[4]);

}  // namespace cellphys::server
