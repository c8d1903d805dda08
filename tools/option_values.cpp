#include "tools/option_values.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "tools/usage_error.h"

namespace cellphys::cli {

namespace {

// The whole text as a finite double, or false.
bool to_double(const std::string& text, double& v) {
  char* end = nullptr;
  errno = 0;
  v = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0' && errno != ERANGE && std::isfinite(v);
}

}  // namespace

double parse_positive(const std::string& opt, const std::string& text) {
  double v;
  if (!to_double(text, v) || !(v > 0)) throw UsageError{opt + " needs a positive number, got '" + text + "'"};
  return v;
}

double parse_number(const std::string& opt, const std::string& text, double lo, double hi) {
  double v;
  if (!to_double(text, v) || v < lo || v > hi)
    throw UsageError{opt + " needs a number from " + std::to_string(lo) + " to " + std::to_string(hi) + ", got '" +
                     text + "'"};
  return v;
}

long long parse_count(const std::string& opt, const std::string& text, long long lo, long long hi) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (end == text.c_str() || *end != '\0' || errno == ERANGE || v < lo || v > hi)
    throw UsageError{opt + " needs an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", got '" +
                     text + "'"};
  return v;
}

}  // namespace cellphys::cli
