// Helpers shared by the rostest nodes: temporary folders, running a node
// executable as a child process, reading the bundled sample data's paths.
#pragma once

#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace massage_cell::test {

namespace fs = std::filesystem;

/// Median of the values (the upper one for an even count); NaN when empty.
inline double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

/// A fresh folder under the system temp dir, removed on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& tag = "massage_cell") {
    std::random_device rd;
    path_ = fs::temp_directory_path() / (tag + "_" + std::to_string(getpid()) + "_" + std::to_string(rd()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
};

struct RunResult {
  int exit_code = -1;  ///< -1 when the process did not exit by itself in time
  std::string output;  ///< stdout and stderr together
};

/// Runs `command` through /bin/sh with a time limit; collects its output.
inline RunResult runCommand(const std::string& command, int timeout_s) {
  RunResult result;
  const std::string wrapped =
      "timeout --signal=INT --kill-after=5 " + std::to_string(timeout_s) + " " + command + " 2>&1";
  FILE* pipe = popen(wrapped.c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer{};
  while (fgets(buffer.data(), buffer.size(), pipe)) result.output += buffer.data();
  const int status = pclose(pipe);
  if (WIFEXITED(status)) {
    result.exit_code = WEXITSTATUS(status);
    if (result.exit_code == 124) result.exit_code = -1;  // timeout's "timed out"
  }
  return result;
}

/// A child process running in the background until stop() or destruction.
class Child {
 public:
  Child(const std::string& command, const std::string& log_path) {
    pid_ = fork();
    if (pid_ == 0) {
      setpgid(0, 0);
      const std::string redirected = "exec " + command + " > " + log_path + " 2>&1";
      execl("/bin/sh", "sh", "-c", redirected.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~Child() { stop(); }
  void stop() {
    if (pid_ <= 0) return;
    kill(-pid_, SIGINT);
    for (int i = 0; i < 50; ++i) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        return;
      }
      usleep(100000);
    }
    kill(-pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  bool running() const { return pid_ > 0 && waitpid(pid_, nullptr, WNOHANG) == 0; }

 private:
  pid_t pid_ = -1;
};

inline std::string readFile(const std::string& path) {
  std::string text;
  if (FILE* f = std::fopen(path.c_str(), "r")) {
    std::array<char, 4096> buffer{};
    std::size_t n;
    while ((n = std::fread(buffer.data(), 1, buffer.size(), f)) > 0) text.append(buffer.data(), n);
    std::fclose(f);
  }
  return text;
}

}  // namespace massage_cell::test
