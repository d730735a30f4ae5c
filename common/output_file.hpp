#pragma once
// Every file a run writes goes through OutputFile, so that a run never destroys an earlier
// result and never leaves a half-written file that looks whole (docs/contract.md):
//  - the content goes to a hidden temporary file beside the target (same file system, so the
//    final rename is atomic); the target is untouched until commit();
//  - every write, flush, fsync and close is checked; a failure throws OutputError naming the
//    target and the reason (a full disk, a closed stdout);
//  - commit() renames the temporary over the target; keep_partial() renames it to
//    TARGET.partial (an interrupted run); destroying an uncommitted file removes the temporary.
// "-" is stdout, and an existing non-regular target (a FIFO, /dev/null, a terminal) is written in
// place: neither can be renamed over, and a reader of a FIFO wants the lines as they come.
#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace dronetrack {

struct OutputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class OutputFile {
 public:
  enum class Mode {
    replace,  // temporary + rename on commit (a run's result)
    append,   // appended in place, every line flushed (a service's live log; never truncated)
  };
  // Creates the temporary (or opens stdout / the special file). Throws OutputError.
  explicit OutputFile(const std::filesystem::path& target, Mode mode = Mode::replace);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // Writes `text` and a newline. Throws OutputError when the system reports a failure (stdio
  // buffers: a full disk may only show at a later write or at commit()).
  void write_line(const char* text, std::size_t length);
  void write(const std::string& text);
  void flush();
  // The descriptor of the open file, for libraries that write by descriptor (libsndfile's
  // sf_open_fd). Write nothing through write()/write_line() then.
  int descriptor() const;

  // Makes the content the target: flush, fsync, close, rename. Throws OutputError.
  void commit();
  // Keeps the content as TARGET.partial (returned); the target is untouched. Never throws:
  // it runs on the way out of an interrupted run. Returns the path the content is in.
  std::filesystem::path keep_partial() noexcept;

  const std::string& name() const { return name_; }  // as given ("-" for stdout)
  bool is_stdout() const { return file_ == stdout; }
  bool in_place() const { return in_place_; }

 private:
  [[noreturn]] void fail(const std::string& what) const;
  void close_checked();

  std::string name_;
  std::filesystem::path target_;
  std::filesystem::path temporary_;
  std::FILE* file_ = nullptr;
  bool in_place_ = false;  // stdout, a special file or append mode: no temporary
  bool line_flush_ = false;
  bool done_ = false;
};

// Call first thing in main(): a standard descriptor that was closed (`cmd >&-`) is reopened on
// /dev/null, so no file the program opens can take its number and receive stray output, and an
// output to "-" after a closed stdout is refused instead of written nowhere.
void guard_standard_streams();

// The path an interrupted run leaves its content in.
std::filesystem::path partial_path(const std::filesystem::path& target);

// A named path a command reads or writes ("--tracks-out", "arrays[0].recording").
struct NamedPath {
  std::string role;
  std::filesystem::path path;
};

// Refuses, before anything is opened, an output that is also an input (after resolving links
// and relative paths), two outputs to the same file (stdout included), an output that is a
// directory, or one whose folder does not exist. Throws OutputError naming both roles.
void check_output_paths(const std::vector<NamedPath>& inputs,
                        const std::vector<NamedPath>& outputs);

}  // namespace dronetrack
