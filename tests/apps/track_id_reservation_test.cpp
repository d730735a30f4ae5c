// Track ids across fusion restarts (docs/contract.md): each instance starts above every id an
// earlier one reserved, even after a crash, and extends its reservation before using it.
#include "apps/track_id_reservation.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "apps/commands.hpp"

namespace {

namespace fs = std::filesystem;
using dronetrack::apps::TrackIdReservation;

class TrackIdReservationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("dronetrack-track-ids-" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string stored() const {
    std::ifstream in(file());
    std::string text;
    std::getline(in, text);
    return text;
  }
  fs::path file() const { return dir_ / "track-ids"; }
  fs::path dir_;
};

TEST_F(TrackIdReservationTest, WithoutAFileIdsAreTheEngines) {
  TrackIdReservation ids;
  EXPECT_EQ(ids.wire_id(1), 1);
  EXPECT_EQ(ids.wire_id(5000), 5000);
}

TEST_F(TrackIdReservationTest, EachInstanceStartsAboveWhatTheLastReserved) {
  {
    TrackIdReservation first(file());  // no file yet: the site's first fusion
    EXPECT_EQ(first.wire_id(1), 1);
    EXPECT_EQ(stored(), "1025");  // written before any id went out
    EXPECT_EQ(first.wire_id(1024), 1024);
    EXPECT_EQ(stored(), "1025");
    EXPECT_EQ(first.wire_id(1025), 1025);  // past the block: reserved further first
    EXPECT_EQ(stored(), "2049");
  }  // a crash here loses nothing: the file already says 2049
  TrackIdReservation second(file());
  EXPECT_EQ(second.wire_id(1), 2049);
  EXPECT_EQ(second.wire_id(3), 2051);
  EXPECT_EQ(stored(), "3073");
}

TEST_F(TrackIdReservationTest, IdsWrapPastTheIdlRangeToOne) {
  std::ofstream(file()) << "2147483647\n";
  TrackIdReservation ids(file());
  EXPECT_EQ(ids.wire_id(1), 2147483647);
  EXPECT_EQ(ids.wire_id(2), 1);
}

TEST_F(TrackIdReservationTest, AFileWithoutOneIdIsRefused) {
  for (const char* content : {"", "abc", "12 13", "-4", "0", "99999999999999999999"}) {
    std::ofstream(file()) << content;
    EXPECT_THROW(TrackIdReservation{file()}, dronetrack::apps::UserError) << content;
  }
}

}  // namespace
