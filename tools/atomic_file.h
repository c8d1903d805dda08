// An output file written under a temporary name in its own directory and renamed into place by
// commit(): a failed or interrupted run (the destructor discards) never leaves a partial file,
// and an existing file of that name stays as it was until the new one is complete.
#pragma once
#include <cstdio>
#include <string>

namespace cellphys::cli {

class AtomicFile {
 public:
  AtomicFile() = default;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile() { discard(); }

  // Opens a temporary next to `path`; throws std::runtime_error with the reason.
  void open(const std::string& path);
  FILE* get() const { return f_; }
  bool is_open() const { return f_ != nullptr; }

  // Closes and renames the temporary to the path; throws std::runtime_error (and removes the
  // temporary) on a write, close or rename error.
  void commit();
  // Closes and removes the temporary, if any.
  void discard();

 private:
  std::string path_, tmp_;
  FILE* f_ = nullptr;
};

}  // namespace cellphys::cli
