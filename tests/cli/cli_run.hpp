#pragma once
// Runs the dronetrack binary under test (DRONETRACK_BINARY, or $DRONETRACK_UNDER_TEST) as a child
// process with its stdout and stderr captured in files, optionally signalled mid-run: shared by
// the CLI tests (cli_contract_test.cpp, ops_outputs_test.cpp).
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace dronetrack::cli_test {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

struct Outcome {
  int exit_code = -1;  // -1: killed by the test's timeout
  bool timed_out = false;
  std::string err;
  std::string out;
  long max_rss_kB = 0;
};

struct RunOptions {
  std::chrono::milliseconds timeout = 60s;
  int signal = 0;  // sent after signal_after
  std::chrono::milliseconds signal_after = 0ms;
  bool close_stdout = false;
  std::function<void()> while_running;  // called once, signal_after into the run
  std::function<bool()> signal_when;    // if set: the signal goes when this first holds
};

inline std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

inline void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// Runs the dronetrack binary; stdout and stderr go to files in `dir`.
inline Outcome run(const std::vector<std::string>& arguments, const fs::path& dir,
                   const RunOptions& options = {}) {
  const fs::path out_path = dir / "run.out";
  const fs::path err_path = dir / "run.err";
  // DRONETRACK_UNDER_TEST runs the cases against another build (e.g. an older commit's, to see
  // them fail there).
  const char* other = std::getenv("DRONETRACK_UNDER_TEST");
  std::vector<std::string> copies{other ? other : DRONETRACK_BINARY};
  copies.insert(copies.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (auto& argument : copies) argv.push_back(argument.data());
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    const int err_fd = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(err_fd, 2);
    if (options.close_stdout) {
      ::close(1);
    } else {
      const int out_fd = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(out_fd, 1);
    }
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  Outcome outcome;
  const auto started = Clock::now();
  bool signalled = false;
  for (;;) {
    int status = 0;
    rusage usage{};
    const pid_t done = ::wait4(pid, &status, WNOHANG, &usage);
    if (done == pid) {
      outcome.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      outcome.max_rss_kB = usage.ru_maxrss;
      break;
    }
    const auto elapsed = Clock::now() - started;
    if (!signalled && (options.signal != 0 || options.while_running) &&
        elapsed >= options.signal_after && (!options.signal_when || options.signal_when())) {
      signalled = true;
      if (options.while_running) options.while_running();
      if (options.signal != 0) ::kill(pid, options.signal);
    }
    if (elapsed > options.timeout) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      outcome.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(10ms);
  }
  outcome.err = read_text(err_path);
  outcome.out = read_text(out_path);
  return outcome;
}

}  // namespace dronetrack::cli_test
