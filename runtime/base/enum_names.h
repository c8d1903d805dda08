// An enumeration's names as one table (the value is the index): the name of a value, the value
// of a name, and every name for messages. Each enumeration keeps its table beside it and these
// three do the rest, so no enumeration spells its names twice.
#pragma once
#include <cstddef>
#include <string>

namespace cellphys::base {

/// The name of value e, or `fallback` when e is not in the table.
template <class E, size_t N>
constexpr const char* name_of(const char* const (&names)[N], E e, const char* fallback = "?") {
  const auto k = static_cast<size_t>(e);
  return k < N ? names[k] : fallback;
}

/// The value named `name` into *out; false (and *out untouched) when no entry has that name.
template <class E, size_t N>
bool value_named(const char* const (&names)[N], const std::string& name, E* out) {
  for (size_t k = 0; k < N; ++k)
    if (name == names[k]) {
      *out = static_cast<E>(k);
      return true;
    }
  return false;
}

/// Every name, comma-separated, in value order.
template <size_t N>
std::string all_names(const char* const (&names)[N]) {
  std::string out;
  for (const char* n : names) out += (out.empty() ? "" : ", ") + std::string(n);
  return out;
}

}  // namespace cellphys::base
