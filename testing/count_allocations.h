// Replaces the global operator new and delete with ones that count every allocation, so a
// benchmark or test can show that a warm step allocates nothing. Include it in exactly one
// source file of a binary (the replacements are that binary's, not a library's).
#pragma once
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

namespace cellphys::testing {
/// Allocations made through operator new since the program started, on any thread.
inline std::atomic<uint64_t> g_allocations{0};
inline uint64_t allocation_count() { return g_allocations.load(std::memory_order_relaxed); }
}  // namespace cellphys::testing

void* operator new(std::size_t n) {
  cellphys::testing::g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, std::align_val_t a) {
  cellphys::testing::g_allocations.fetch_add(1, std::memory_order_relaxed);
  const std::size_t al = static_cast<std::size_t>(a);
  if (void* p = std::aligned_alloc(al, (n + al - 1) / al * al)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
