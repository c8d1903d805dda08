#include "tools/atomic_file.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <vector>

namespace cellphys::cli {

namespace fs = std::filesystem;

void AtomicFile::open(const std::string& path) {
  path_ = path;
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::string name = "." + p.filename().string() + ".tmp." + std::to_string(::getpid()) + ".XXXXXX";
  std::string tmpl = (dir / name).string();
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  const int fd = ::mkstemp(buf.data());
  if (fd < 0) throw std::runtime_error(path + ": cannot create a file next to it: " + std::strerror(errno));
  tmp_ = buf.data();
  f_ = ::fdopen(fd, "w");
  if (!f_) {
    ::close(fd);
    discard();
    throw std::runtime_error(path + ": cannot open: " + std::strerror(errno));
  }
  std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
}

void AtomicFile::commit() {
  if (!f_) return;
  const bool write_ok = !std::ferror(f_);
  const bool close_ok = std::fclose(f_) == 0;
  f_ = nullptr;
  if (!write_ok || !close_ok) {
    const std::string why = std::strerror(errno);
    discard();
    throw std::runtime_error(path_ + ": write error: " + why);
  }
  // mkstemp made it 0600; give it the usual permissions
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::chmod(tmp_.c_str(), 0666 & ~mask);
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    discard();
    throw std::runtime_error(path_ + ": cannot rename the finished file into place: " + why);
  }
  tmp_.clear();
}

void AtomicFile::discard() {
  if (f_) std::fclose(f_);
  f_ = nullptr;
  if (!tmp_.empty()) std::remove(tmp_.c_str());
  tmp_.clear();
}

}  // namespace cellphys::cli
