// A usage error of `cellphys run` or `cellphys scenes` (an unknown or malformed option, a scene
// name that names nothing): the message names what was wrong, and the exit code is 2.
#pragma once
#include <string>

namespace cellphys::cli {

struct UsageError {
  std::string message;
};

}  // namespace cellphys::cli
