// read_text_file on real files: the text as written, and one error naming the file for a
// directory, a missing file and a file over its bound (held in memory never).
#include "common/input_file.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace dronetrack::input_file_test {
namespace {

namespace fs = std::filesystem;

class InputFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("input_file_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string error_of(const fs::path& file, std::size_t max_bytes) const {
    try {
      read_text_file(file, max_bytes, "users file");
    } catch (const std::runtime_error& error) {
      return error.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(InputFileTest, ReadsTheWholeTextAcrossChunks) {
  // Longer than the 64 kB read chunk, with a NUL and no final newline: bytes as written.
  std::string text(200000, 'x');
  text[70000] = '\0';
  text.back() = 'y';
  std::ofstream(dir_ / "big", std::ios::binary) << text;
  EXPECT_EQ(read_text_file(dir_ / "big", text.size(), "users file"), text);
}

TEST_F(InputFileTest, NamesTheFileAndWhatIsWrong) {
  std::ofstream(dir_ / "users") << std::string(2048, 'a');
  EXPECT_EQ(error_of(dir_ / "users", 1024),
            (dir_ / "users").string() + ": 2048 bytes; a users file may be at most 1 kB");
  EXPECT_EQ(error_of(dir_, 1024), dir_.string() + ": is a directory, not a users file");
  EXPECT_EQ(error_of(dir_ / "absent", 1024),
            (dir_ / "absent").string() + ": cannot open users file");
  EXPECT_EQ(error_of(dir_ / "users", 4u << 20), "");
}

}  // namespace
}  // namespace dronetrack::input_file_test
