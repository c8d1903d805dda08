// Option values of the cellphys commands, checked as they are read: a bad one is a UsageError
// naming the option, what it takes and what it got.
#pragma once
#include <string>

namespace cellphys::cli {

double parse_positive(const std::string& opt, const std::string& text);
double parse_number(const std::string& opt, const std::string& text, double lo, double hi);
long long parse_count(const std::string& opt, const std::string& text, long long lo, long long hi);

}  // namespace cellphys::cli
