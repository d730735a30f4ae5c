#include "common/output_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <optional>

namespace dronetrack {
namespace {

bool stdout_closed = false;

std::string reason(int error_number) { return std::strerror(error_number); }

// (device, inode) of an existing file, after following links.
std::optional<std::pair<dev_t, ino_t>> identity(const std::filesystem::path& path) {
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) return std::nullopt;
  return std::make_pair(status.st_dev, status.st_ino);
}

std::string resolved(const std::filesystem::path& path) {
  std::error_code error;
  const auto absolute = std::filesystem::absolute(path, error);
  if (error) return path.lexically_normal().string();
  const auto canonical = std::filesystem::weakly_canonical(absolute, error);
  return (error ? absolute.lexically_normal() : canonical).string();
}

bool same_file(const std::filesystem::path& a, const std::filesystem::path& b) {
  const auto identity_a = identity(a);
  const auto identity_b = identity(b);
  if (identity_a && identity_b) return *identity_a == *identity_b;
  return resolved(a) == resolved(b);
}

}  // namespace

void guard_standard_streams() {
  for (int descriptor = 0; descriptor <= 2; ++descriptor) {
    if (::fcntl(descriptor, F_GETFD) >= 0) continue;
    if (descriptor == STDOUT_FILENO) stdout_closed = true;
    // open() takes the lowest free number: this one.
    (void)::open("/dev/null", descriptor == STDIN_FILENO ? O_RDONLY : O_WRONLY);
  }
}

std::filesystem::path partial_path(const std::filesystem::path& target) {
  return std::filesystem::path(target.string() + ".partial");
}

OutputFile::OutputFile(const std::filesystem::path& target, Mode mode)
    : name_(target.string()), target_(target) {
  if (name_ == "-") {
    if (stdout_closed || ::fcntl(STDOUT_FILENO, F_GETFD) < 0) fail("is closed");
    file_ = stdout;
    in_place_ = true;
    return;
  }
  if (name_.empty()) fail("empty output path");
  struct stat status {};
  const bool exists = ::stat(target.c_str(), &status) == 0;
  if (exists && S_ISDIR(status.st_mode)) fail("is a directory");
  if (mode == Mode::append || (exists && !S_ISREG(status.st_mode))) {
    file_ = std::fopen(name_.c_str(), mode == Mode::append ? "a" : "w");
    if (!file_) fail("cannot open for writing (" + reason(errno) + ")");
    in_place_ = true;
    line_flush_ = mode == Mode::append;
    return;
  }
  const std::filesystem::path folder =
      target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  // Built by appending: GCC 12 warns (falsely, -Wrestrict) on "." + std::string.
  std::string hidden_name(".");
  hidden_name += target.filename().string();
  hidden_name += ".tmp-XXXXXX";
  std::string pattern = (folder / hidden_name).string();
  const int descriptor = ::mkstemp(pattern.data());
  if (descriptor < 0)
    fail("cannot create a file in " + folder.string() + " (" + reason(errno) + ")");
  temporary_ = pattern;
  // mkstemp makes the file private (0600); a result keeps the mode of the file it replaces, or
  // gets the usual 0666 less the umask.
  mode_t permissions = status.st_mode & 07777;
  if (!exists) {
    const mode_t mask = ::umask(0);
    ::umask(mask);
    permissions = 0666 & ~mask;
  }
  (void)::fchmod(descriptor, permissions);
  file_ = ::fdopen(descriptor, "w");
  if (!file_) {
    const int error_number = errno;
    ::close(descriptor);
    ::unlink(temporary_.c_str());
    temporary_.clear();
    fail("cannot open (" + reason(error_number) + ")");
  }
}

OutputFile::~OutputFile() {
  if (done_) return;
  if (file_ == stdout) {
    std::fflush(stdout);
    return;
  }
  if (file_) std::fclose(file_);
  if (!temporary_.empty()) ::unlink(temporary_.c_str());
}

void OutputFile::fail(const std::string& what) const {
  throw OutputError((name_ == "-" ? std::string("stdout") : name_) + ": " + what);
}

void OutputFile::write_line(const char* text, std::size_t length) {
  if (std::fwrite(text, 1, length, file_) != length || std::fputc('\n', file_) == EOF)
    fail("write failed (" + reason(errno) + ")");
  if (line_flush_) flush();
}

void OutputFile::write(const std::string& text) {
  if (std::fwrite(text.data(), 1, text.size(), file_) != text.size())
    fail("write failed (" + reason(errno) + ")");
}

void OutputFile::flush() {
  if (std::fflush(file_) != 0) fail("write failed (" + reason(errno) + ")");
}

int OutputFile::descriptor() const { return ::fileno(file_); }

void OutputFile::close_checked() {
  std::FILE* file = file_;
  file_ = nullptr;
  if (std::fclose(file) != 0) fail("write failed on close (" + reason(errno) + ")");
}

void OutputFile::commit() {
  if (done_) return;
  if (std::fflush(file_) != 0 || std::ferror(file_)) fail("write failed (" + reason(errno) + ")");
  if (file_ == stdout) {
    done_ = true;
    return;
  }
  // The rename must not reach the disk before the content does, or a power cut leaves an
  // empty file where the old result was.
  if (!in_place_ && ::fsync(::fileno(file_)) != 0) fail("fsync failed (" + reason(errno) + ")");
  close_checked();
  if (!in_place_) {
    if (std::rename(temporary_.c_str(), target_.c_str()) != 0)
      fail("cannot move the finished file into place (" + reason(errno) + ")");
    temporary_.clear();
    std::error_code ignored;
    std::filesystem::remove(partial_path(target_), ignored);  // an older interrupted run's
  }
  done_ = true;
}

std::filesystem::path OutputFile::keep_partial() noexcept {
  if (done_) return target_;
  done_ = true;
  if (file_ == stdout) {
    std::fflush(stdout);
    return target_;
  }
  if (file_) std::fclose(file_);
  file_ = nullptr;
  if (in_place_) return target_;
  const std::filesystem::path partial = partial_path(target_);
  if (std::rename(temporary_.c_str(), partial.c_str()) != 0) return temporary_;
  temporary_.clear();
  return partial;
}

void check_output_paths(const std::vector<NamedPath>& inputs,
                        const std::vector<NamedPath>& outputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const NamedPath& output = outputs[i];
    const bool to_stdout = output.path == "-";
    for (std::size_t j = 0; j < i; ++j) {
      const bool other_stdout = outputs[j].path == "-";
      if ((to_stdout && other_stdout) ||
          (!to_stdout && !other_stdout && same_file(output.path, outputs[j].path))) {
        throw OutputError(output.role + " " + output.path.string() + ": also given as " +
                          outputs[j].role + "; two outputs in one file would interleave");
      }
    }
    if (to_stdout) continue;
    for (const NamedPath& input : inputs) {
      if (!input.path.empty() && same_file(output.path, input.path)) {
        throw OutputError(output.role + " " + output.path.string() + ": is an input (" +
                          input.role + "); writing it would destroy it");
      }
    }
    std::error_code error;
    if (std::filesystem::is_directory(output.path, error))
      throw OutputError(output.role + " " + output.path.string() + ": is a directory");
    const std::filesystem::path folder =
        output.path.has_parent_path() ? output.path.parent_path() : std::filesystem::path(".");
    if (!std::filesystem::is_directory(folder, error))
      throw OutputError(output.role + " " + output.path.string() + ": folder " + folder.string() +
                        " does not exist");
  }
}

}  // namespace dronetrack
