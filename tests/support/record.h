// Measured numbers of a test: recorded as a GoogleTest property (in the XML report) and
// printed, so a passing run still shows what it measured.
#pragma once
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace cellphys::test_support {

inline std::string sci(double v, int digits = 4) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

inline void record(const std::string& key, double value, int digits = 4) {
  ::testing::Test::RecordProperty(key, sci(value, digits));
  std::printf("[ measured ] %s = %s\n", key.c_str(), sci(value, digits).c_str());
}

inline void record(const std::string& key, const std::string& value) {
  ::testing::Test::RecordProperty(key, value);
  std::printf("[ measured ] %s = %s\n", key.c_str(), value.c_str());
}

}  // namespace cellphys::test_support
