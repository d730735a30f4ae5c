// OutputFile and check_output_paths on real files in a temporary folder.
#include "common/output_file.hpp"

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace dronetrack::output_file_test {
namespace {

namespace fs = std::filesystem;

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

class OutputFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("output_file_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "target.jsonl") << "earlier\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::size_t files_in_dir() const {
    return static_cast<std::size_t>(
        std::distance(fs::directory_iterator(dir_), fs::directory_iterator()));
  }
  fs::path dir_;
};

TEST_F(OutputFileTest, TargetChangesOnlyOnCommit) {
  OutputFile out(dir_ / "target.jsonl");
  out.write_line("new", 3);
  out.flush();
  EXPECT_EQ(read_text(dir_ / "target.jsonl"), "earlier\n");
  EXPECT_EQ(files_in_dir(), 2u);  // the target and the hidden temporary
  out.commit();
  EXPECT_EQ(read_text(dir_ / "target.jsonl"), "new\n");
  EXPECT_EQ(files_in_dir(), 1u);
}

TEST_F(OutputFileTest, AbandonedFileLeavesTargetAndNoTemporary) {
  {
    OutputFile out(dir_ / "target.jsonl");
    out.write_line("new", 3);
  }
  EXPECT_EQ(read_text(dir_ / "target.jsonl"), "earlier\n");
  EXPECT_EQ(files_in_dir(), 1u);
}

TEST_F(OutputFileTest, PartialKeepsTargetAndNamesTheRest) {
  OutputFile out(dir_ / "target.jsonl");
  out.write_line("half", 4);
  const fs::path kept = out.keep_partial();
  EXPECT_EQ(kept, dir_ / "target.jsonl.partial");
  EXPECT_EQ(read_text(kept), "half\n");
  EXPECT_EQ(read_text(dir_ / "target.jsonl"), "earlier\n");
}

TEST_F(OutputFileTest, CommittedFileKeepsTheModeOfWhatItReplaces) {
  ::chmod((dir_ / "target.jsonl").c_str(), 0640);
  OutputFile out(dir_ / "target.jsonl");
  out.commit();
  struct stat status {};
  ASSERT_EQ(::stat((dir_ / "target.jsonl").c_str(), &status), 0);
  EXPECT_EQ(status.st_mode & 0777, 0640u);
}

TEST_F(OutputFileTest, AppendModeNeverTruncates) {
  {
    OutputFile out(dir_ / "target.jsonl", OutputFile::Mode::append);
    out.write_line("more", 4);
    EXPECT_EQ(read_text(dir_ / "target.jsonl"), "earlier\nmore\n");  // flushed per line
    out.commit();
  }
  EXPECT_EQ(read_text(dir_ / "target.jsonl"), "earlier\nmore\n");
}

TEST_F(OutputFileTest, FullDeviceFailsLoudly) {
  OutputFile out("/dev/full");
  EXPECT_TRUE(out.in_place());
  out.write_line("x", 1);
  EXPECT_THROW(out.commit(), OutputError);
}

TEST_F(OutputFileTest, MissingFolderFailsAtOpen) {
  EXPECT_THROW(OutputFile(dir_ / "no" / "such.jsonl"), OutputError);
}

TEST_F(OutputFileTest, PathCheckFindsAnInputUnderAnotherName) {
  fs::create_symlink(dir_ / "target.jsonl", dir_ / "link.jsonl");
  EXPECT_THROW(check_output_paths({{"the site config", dir_ / "target.jsonl"}},
                                  {{"--doa-out", dir_ / "link.jsonl"}}),
               OutputError);
  EXPECT_THROW(check_output_paths({}, {{"--doa-out", dir_ / "sub/../target.jsonl"},
                                       {"--tracks-out", dir_ / "target.jsonl"}}),
               OutputError);
  EXPECT_THROW(check_output_paths({}, {{"--doa-out", "-"}, {"--tracks-out", "-"}}), OutputError);
  EXPECT_THROW(check_output_paths({}, {{"--doa-out", dir_}}), OutputError);
  EXPECT_NO_THROW(check_output_paths({{"the site config", dir_ / "target.jsonl"}},
                                     {{"--doa-out", dir_ / "new.jsonl"}, {"--tracks-out", "-"}}));
}

}  // namespace
}  // namespace dronetrack::output_file_test
