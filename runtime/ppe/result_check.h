// Whether an island's result bytes can be unpacked: the control side checks every result
// before it touches the world, wherever the island was computed.
#pragma once
#include "runtime/ppe/island_packer.h"
#include "runtime/spu/kernel.h"

namespace cellphys::ppe {

/// A result is sound when its header belongs to the island and its bytes match their
/// checksum (a sealed island's: an unsealed one was stepped where it was packed). A kernel refuses a sound image only when it does not fit (the same anywhere), so
/// a "malformed" refusal means the image was damaged on its way.
bool sound_result(const PackedIsland& p, const spu::IslandReport& r);

}  // namespace cellphys::ppe
