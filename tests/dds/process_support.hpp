#pragma once
// Child processes for the multi-process DDS tests (the real `dronetrack` binary), and the
// waiting they need: poll for a condition with a bounded wait, never sleep a fixed time.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace dronetrack::dds::testing {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// A child process with its stdout and stderr in files; SIGKILLed if still running at the end.
class Process {
 public:
  Process(const std::vector<std::string>& arguments, const fs::path& stdout_path,
          const fs::path& stderr_path) {
    std::vector<char*> argv;
    std::vector<std::string> copies = arguments;
    for (auto& argument : copies) argv.push_back(argument.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    posix_spawn_file_actions_addopen(&actions, 2, stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    const int failed = posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (failed != 0) pid_ = -1;
  }
  ~Process() {
    if (running()) {
      kill(pid_, SIGKILL);
      wait_exit(5s);
    }
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  bool started() const { return pid_ > 0; }
  bool running() const { return pid_ > 0 && !status_; }
  void signal(int number) const {
    if (running()) kill(pid_, number);
  }
  // The exit status, or nullopt if still running after the timeout.
  std::optional<int> wait_exit(std::chrono::nanoseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (running()) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        status_ = status;
        break;
      }
      if (Clock::now() > deadline) return std::nullopt;
      std::this_thread::sleep_for(20ms);
    }
    return status_;
  }

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
};

std::string read_text(const fs::path& path) {
  std::string text;
  if (std::FILE* file = std::fopen(path.c_str(), "rb")) {
    char chunk[4096];
    std::size_t got = 0;
    while ((got = std::fread(chunk, 1, sizeof chunk, file)) > 0) text.append(chunk, got);
    std::fclose(file);
  }
  return text;
}

// Waits for `needle` to appear in the file; returns when it did, or nullopt.
std::optional<Clock::time_point> wait_for_text(const fs::path& path, const std::string& needle,
                                               std::chrono::nanoseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    if (read_text(path).find(needle) != std::string::npos) return Clock::now();
    std::this_thread::sleep_for(10ms);
  }
  return std::nullopt;
}

void sleep_until_wall(double unix_s) {
  const auto target = std::chrono::system_clock::time_point(
      std::chrono::duration_cast<std::chrono::system_clock::duration>(
          std::chrono::duration<double>(unix_s)));
  std::this_thread::sleep_until(target);
}

double unix_now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace dronetrack::dds::testing
