// `cellphys serve` started as a process by a test: on a free loopback port (--port 0), its
// address and token read from the two lines it prints; stopped with SIGTERM (or killed).
#pragma once
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace cellphys::test {

class ServeProcess {
 public:
  /// Starts `exe serve args...` with `--port 0 --token <a fixed token>` added; waits for its
  /// listening line (throws if it exits first).
  ServeProcess(const std::string& exe, std::vector<std::string> args, const std::string& scenes_dir) {
    int out[2];
    if (pipe(out) != 0) throw std::runtime_error("pipe");
    std::vector<std::string> argv = {exe, "serve"};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.insert(argv.end(), {"--port", "0", "--token", kToken});
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], 1);
      close(out[0]);
      close(out[1]);
      setenv("CELLPHYS_SCENES", scenes_dir.c_str(), 1);
      std::vector<char*> cargv;
      for (std::string& a : argv) cargv.push_back(a.data());
      cargv.push_back(nullptr);
      execv(exe.c_str(), cargv.data());
      _exit(127);
    }
    close(out[1]);
    out_ = fdopen(out[0], "r");
    char line[512];
    while (std::fgets(line, sizeof line, out_)) {
      const std::string l(line);
      unsigned port = 0;
      if (std::sscanf(line, "listening on http://127.0.0.1:%u/", &port) == 1) port_ = static_cast<unsigned short>(port);
      if (l.rfind("token ", 0) == 0) {
        token_ = l.substr(6, l.find('\n') - 6);
        break;
      }
    }
    if (port_ == 0 || token_.empty()) {
      stop();
      throw std::runtime_error("cellphys serve did not start (exit status " + std::to_string(status_) + ")");
    }
  }
  ~ServeProcess() { stop(); }
  ServeProcess(const ServeProcess&) = delete;
  ServeProcess& operator=(const ServeProcess&) = delete;

  unsigned short port() const { return port_; }
  pid_t pid() const { return pid_; }
  const std::string& token() const { return token_; }

  /// Sends `sig` and waits for the process; returns its exit code (128 + signal if killed).
  int stop(int sig = SIGTERM) {
    if (pid_ > 0) {
      kill(pid_, sig);
      int st = 0;
      waitpid(pid_, &st, 0);
      status_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      pid_ = -1;
    }
    if (out_) {
      std::fclose(out_);
      out_ = nullptr;
    }
    return status_;
  }

  static constexpr const char* kToken = "test-token-0123456789";

 private:
  pid_t pid_ = -1;
  FILE* out_ = nullptr;
  unsigned short port_ = 0;
  std::string token_;
  int status_ = -1;
};

}  // namespace cellphys::test
