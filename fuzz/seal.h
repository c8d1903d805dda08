// Seals fuzzed bytes again: a mutated message or snapshot almost never keeps a matching
// checksum, so the fuzz targets recompute every checksum the bytes frame before decoding
// them, and mutations reach the decoders' checks behind the checksums.
#pragma once
#include <vector>

namespace cellphys::fuzz {

/// A snapshot (runtime/ppe/snapshot.cpp): its header's payload size and checksum.
void seal_snapshot(std::vector<unsigned char>& bytes);

/// A jobs batch (runtime/ppe/wire.h): the header's checksum and each job record's, as far as
/// the records frame.
void seal_jobs(std::vector<unsigned char>& msg);

/// A results batch: the header's checksum and each result record's, as far as they frame.
void seal_results(std::vector<unsigned char>& msg);

}  // namespace cellphys::fuzz
